// The map directory on disk (docs/map_format.md): manifest.yaml, submap PCDs, the pose graph in
// g2o, TUM trajectories, and further files owned by other modules (loop and place-recognition
// logs, timing, the descriptor database, the change log) carried as opaque contents.
//
// Saving is atomic: everything is written to `<dir>.new`, fsynced, then swapped in with two
// renames (`<dir>` -> `<dir>.old`, `<dir>.new` -> `<dir>`); a crash at any point leaves either
// the old or the new map, and Load() finishes an interrupted swap. Unchanged files of the old
// map are hard-linked, not rewritten, so saving after a session costs what the session changed.
// The manifest lists every file with its size and FNV-1a 64 checksum; Load() verifies them and
// names the missing, truncated or corrupt file instead of crashing.
#pragma once

#include <cstdint>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "multisession_mapper/core/pose_graph.h"
#include "multisession_mapper/core/status.h"
#include "multisession_mapper/core/submap.h"
#include "multisession_mapper/core/types.h"

namespace multisession_mapper {
namespace core {

constexpr int kMapFormatVersion = 1;

struct SessionRecord {
  std::string name;        ///< unique; by default the bag's file name without extension
  std::string bag;         ///< as given to the runner (informative)
  std::uint32_t scans = 0;
  double duration_s = 0.0;
  std::string merged_at;   ///< ISO 8601 UTC
};

struct MapContents {
  std::vector<SessionRecord> sessions;
  std::vector<Submap, Eigen::aligned_allocator<Submap>> submaps;
  PoseGraph graph;
  std::map<std::string, Trajectory> trajectories;       ///< session -> optimised, map frame
  std::map<std::string, Trajectory> odom_trajectories;  ///< session -> raw odometry
  std::string parameters_yaml;  ///< configuration the map was built with (a YAML mapping)
  /// Further files by relative path (e.g. "loops/s01.csv") with their full new content.
  std::map<std::string, std::string> files;
  /// Further point clouds by relative path (e.g. "dynamics/s01_removed.pcd"), written as PCD
  /// like the submaps; not read back by Load() (they are records, carried over on save).
  std::map<std::string, PointVector> clouds;
  /// Submaps ("session/id") whose points are unchanged since they were loaded: their PCD is
  /// hard-linked from the old map instead of being written again.
  std::set<std::string> clean_submaps;
  /// Files of the current map ("place_recognition/s01.csv") that the next save does not carry
  /// over: records past their retention (RetireSessionRecords).
  std::set<std::string> retired_files;
};

struct MapStoreConfig {
  /// Test hook for crash safety: when >= 0, Save() stops (as a crash would: no clean-up) after
  /// writing this many files (hard-linked submaps first, then the written ones; with
  /// write_threads > 1 the other threads finish the files they had begun). Never set outside
  /// tests.
  int test_abort_after_files = -1;
  /// Verify every file's checksum on load (costs one read of the map).
  bool verify_checksums = true;
  /// Threads that write the changed submaps' PCD files in Save (LZF compression, fsync and
  /// the read-back for the manifest's checksums), >= 1. Whole campus seed-1 s00: 57 submaps,
  /// 121 MB, ~2 s in one thread.
  int write_threads = 2;

  Status Validate() const {
    if (write_threads < 1) return Status::Error("map store: write_threads must be >= 1");
    return Status::Ok();
  }
};

/// Key of a submap in file names and `clean_submaps`: "<session>/<id>".
std::string SubmapKey(const std::string& session, std::uint32_t id);

class MapStore {
 public:
  explicit MapStore(const MapStoreConfig& config = MapStoreConfig()) : config_(config) {}

  /// Atomically replaces the map at `dir` (creating it if absent) by `contents`.
  Status Save(const MapContents& contents, const std::string& dir) const;

  /// Loads and verifies the map at `dir`, completing an interrupted save first.
  StatusOr<MapContents> Load(const std::string& dir) const;

  /// True when `dir` holds a map (after recovery of an interrupted save).
  static bool Exists(const std::string& dir);

  /// Finishes or rolls back a save that was interrupted (see the header comment).
  static Status Recover(const std::string& dir);

 private:
  MapStoreConfig config_;
};

}  // namespace core
}  // namespace multisession_mapper
