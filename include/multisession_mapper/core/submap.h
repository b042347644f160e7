// A submap: scans of one session accumulated over at most ~20 m / 0.7 rad (reference paper,
// section IV), stored in its own frame with the poses of its scans' sensor origins (needed to
// ray-cast free space when detecting dynamics between sessions).
#pragma once

#include <cstdint>
#include <set>
#include <string>
#include <vector>

#include "multisession_mapper/core/types.h"

namespace multisession_mapper {
namespace core {

struct SubmapScanRecord {
  double stamp_s = 0.0;
  Pose3 T_submap_sensor = Pose3::Identity();  ///< sensor origin of the scan, submap frame

  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

/// Which of a submap's scans measured a point's voxel: the scan of the nearest measurement
/// and the last scan. Indices into Submap::scans; kUnknownScan when not recorded (points a merge
/// added, maps written before the record existed). The pair detection casts a point's rays to
/// these origins: a ray to an origin that did not see the point may pass through holes of a
/// sparsely sampled object in front of it and pass for free space.
struct PointViews {
  static constexpr std::uint32_t kUnknownScan = 0xffffffffu;
  std::uint32_t nearest_scan = kUnknownScan;
  std::uint32_t last_scan = kUnknownScan;
};

enum class SubmapState {
  kActive,  ///< part of the map
  kFused,   ///< replaced by an overlapping submap of a later session; kept for the record
};

struct Submap {
  std::string session;
  std::uint32_t id = 0;
  Pose3 T_map_submap = Pose3::Identity();  ///< origin: sensor pose of the first scan, map frame
  std::vector<SubmapScanRecord, Eigen::aligned_allocator<SubmapScanRecord>> scans;
  PointVector points;  ///< downsampled, dynamic-filtered points in the submap frame [m]
  /// Per point (same order as `points`), or empty when not recorded.
  std::vector<PointViews> views;
  SubmapState state = SubmapState::kActive;
  double length_m = 0.0;  ///< distance driven while the submap was built [m]
  /// The odometry jump [m] at which the submap started (SubmapBuilderConfig::break_on_jump_m),
  /// 0 when it started normally. Only while the session is built: the weak odometry edge to the
  /// previous submap (SessionMapper) is what the map keeps of it.
  double started_at_jump_m = 0.0;

  double first_stamp_s() const { return scans.empty() ? 0.0 : scans.front().stamp_s; }
  double last_stamp_s() const { return scans.empty() ? 0.0 : scans.back().stamp_s; }

  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

const char* SubmapStateName(SubmapState state);

/// Appends the sensor pose of every scan of `submap` (T_map_submap * T_submap_sensor).
void AppendScanPoses(const Submap& submap, Trajectory* out);
/// Sorts by stamp and keeps one pose per stamp (a scan can belong to two overlapping submaps).
void SortTrajectory(Trajectory* trajectory);
/// The scan poses of all `submaps`, sorted by stamp, one per stamp (the two calls above).
Trajectory ScanTrajectory(const std::vector<Submap, Eigen::aligned_allocator<Submap>>& submaps);

/// Removes the points whose `drop` entry is non-zero (drop has one entry per point), and their
/// views when the submap records them.
void DropSubmapPoints(const std::vector<std::uint8_t>& drop, Submap* submap);
/// The same for the points with these indices (indices beyond the points are ignored).
void DropSubmapPointsAt(const std::set<std::uint32_t>& indices, Submap* submap);
/// Appends points (submap frame) of unknown views (e.g. from another session's scans); the
/// submap keeps recording views only if it did.
void AppendSubmapPoints(const PointVector& points, Submap* submap);
/// Puts the points (and their views; views of another size are cleared, as by the functions
/// above) in Z-order (Morton order) of cells of `cell_m` in the submap frame; points of one cell
/// keep their order. Close points then sit close in memory: the kd-tree builds and searches
/// over the submap's points (the pair detection's, the copies' propagation) walk memory in
/// nearly linear order. A map with its points in any order is valid: the registrations and
/// wall normals sample a submap independently of the order (VoxelDownsampleCentred), the pair
/// detection gave the same points in any order (40 benchmark pairs); only the fusion takes the
/// first of a new submap's candidates per voxel. Cells beyond 2^20 of them from the origin
/// (~100 km at 0.1 m) share the outermost cell; a non-finite coordinate counts as the lowest
/// cell. `cell_m` > 0.
void SortSubmapPointsSpatially(double cell_m, Submap* submap);
/// The pipeline sorts a submap by blocks of this many of its voxels (1.6 m at 0.2 m): within a
/// block the points stay in the order first measured, whose views repeat and compress (submap
/// files of seed-2 s00: +2.4 % against +5.1 % for cells of one voxel), at the same speed.
constexpr double kSpatialOrderBlockVoxels = 8.0;
/// SortSubmapPointsSpatially in those blocks, for a submap of voxels of `voxel_m`.
void SortSubmapPointsInVoxelBlocks(double voxel_m, Submap* submap);

}  // namespace core
}  // namespace multisession_mapper
