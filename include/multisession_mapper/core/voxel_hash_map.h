// Local map of the odometry: points in a sparse hash of cubic voxels around the robot, at most
// `max_points_per_voxel` per voxel, voxels far from the robot dropped. Nearest-neighbour
// queries look at the query's voxel and its 26 neighbours only, so a match is found whenever
// it is closer than one voxel edge. Design after KISS-ICP's VoxelHashMap (Vizzo et al. 2023),
// written here; additions: a minimum spacing between the points of a voxel (so a voxel is not
// filled by one scan), box-distance pruning of neighbour voxels in the search, and cached
// surface normals from the local covariance for point-to-plane ICP.
//
// Not thread-safe: FindMatch() fills the normal and neighbourhood caches, FindMatches() also
// each query's memory of its last search (one ICP thread per
// map).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "multisession_mapper/core/local_plane.h"
#include "multisession_mapper/core/registration_target.h"
#include "multisession_mapper/core/status.h"
#include "multisession_mapper/core/types.h"
#include "multisession_mapper/core/voxel_index_table.h"

namespace multisession_mapper {
namespace core {

struct VoxelHashMapConfig {
  /// Edge of a voxel [m]. Also the reach of nearest-neighbour queries. KISS-ICP uses
  /// max_range / 100, i.e. 1.0 m for a VLP-16.
  double voxel_size_m = 1.0;
  /// Points kept per voxel; later points are ignored once a voxel is full.
  int max_points_per_voxel = 20;
  /// A point closer than this to a point already in its voxel is not added [m]. 0 disables.
  /// Default ~ voxel_size / sqrt(max_points): spreads the points of a voxel over its area.
  double min_point_spacing_m = 0.2;
  /// Voxels whose first point is farther than this from the robot are removed [m].
  double max_distance_m = 100.0;
  /// Update() removes far voxels only once the robot has moved this far since the last
  /// removal [m] (0: at every update). The removal sweeps the whole map; at 1 m it runs every
  /// ~5 scans at 2 m/s and 10 Hz, and voxels stay at most 1 m beyond max_distance_m.
  double removal_step_m = 1.0;
  /// Neighbours within this radius of a map point give its normal [m] (<= 3 voxel_size_m;
  /// searched over ceil(radius / voxel) voxels around it, computed once and cached).
  double normal_radius_m = 1.0;
  LocalPlaneCriteria plane;

  Status Validate() const;
};

class VoxelHashMap : public RegistrationTarget {
 public:
  static StatusOr<VoxelHashMap> Create(const VoxelHashMapConfig& config);

  /// Adds `points_in_map` (map frame) and removes voxels farther than max_distance_m from
  /// `robot_position_m` (see removal_step_m): what the odometry does after each registered
  /// scan.
  void Update(const PointVector& points_in_map, const Eigen::Vector3d& robot_position_m);
  /// Adds points (map frame), respecting max_points_per_voxel and min_point_spacing_m.
  void AddPoints(const PointVector& points_in_map);
  /// Removes voxels whose first point is farther than max_distance_m from `position_m`.
  void RemoveFarVoxels(const Eigen::Vector3d& position_m);
  void Clear();

  bool FindMatch(const Eigen::Vector3d& query, double max_distance_m,
                 TargetMatch* match) const override;
  /// With normals disabled and a pool of 2+ threads: the neighbourhoods of all queries are
  /// looked up (and cached) on the calling thread, then the nearest points are searched on
  /// the pool's threads. `warm_start` presumes that the previous call had the same queries
  /// (moved) and that no point was removed since; with it, a query whose previous match is
  /// still within max_distance_m searches only for points closer than that match (most
  /// neighbour voxels are then skipped by their boxes). A query searched again in an unchanged map is mostly
  /// answered from its memory of the last search (see QueryMemory). Same results as FindMatch
  /// per query in every case.
  void FindMatches(const PointVector& queries, double max_distance_m, bool warm_start,
                   WorkerPool* pool, std::vector<std::uint8_t>* found,
                   std::vector<TargetMatch>* matches) const override;
  /// false: FindMatch returns no normals (has_normal false) and computes none, e.g. when the
  /// ICP takes its normals from the source scan (the normals are most of a match's cost).
  void SetNormalsEnabled(bool enabled) { normals_enabled_ = enabled; }
  /// The normal of the map's surface at `p` (map frame): the covariance of the map points
  /// within normal_radius_m of p, with the planarity test of `config().plane` (a single ring
  /// line is no plane). False where it fails. Not cached; independent of SetNormalsEnabled.
  /// Reads the search's neighbour cache: not concurrently with FindMatch / FindMatches.
  bool PlaneNormalAt(const Eigen::Vector3d& p, Eigen::Vector3d* normal) const;
  bool empty() const override { return voxels_.empty(); }
  /// FindMatches answers given from a query's memory without a search since the map was
  /// created (see QueryMemory; including "none within the bound"), for tests and profiling.
  std::uint64_t recalled_matches() const { return recalled_; }

  /// Every point of the map (map frame), e.g. for visualisation.
  PointVector Points() const;
  std::size_t NumVoxels() const { return voxels_.size(); }
  std::size_t NumPoints() const;
  const VoxelHashMapConfig& config() const { return config_; }

 private:
  using VoxelIndex = Eigen::Vector3i;
  enum class NormalState : std::uint8_t { kUnknown, kPlanar, kNotPlanar };
  struct Voxel {
    VoxelIndex index = VoxelIndex::Zero();
    // Cache filled by FindMatch; reset when this voxel or a neighbour gains points.
    mutable std::vector<Eigen::Vector3d> normals;
    mutable std::vector<NormalState> normal_states;
    std::uint32_t last_insert_epoch = 0;  // AddPoints call that last inserted here
  };

  /// What the nearest-neighbour search reads of a voxel first: the bounding box of its points
  /// and their number, one cache line per voxel in a compact array. The search (bound by cache
  /// misses) skips most neighbour voxels on the box alone, without touching their points.
  struct alignas(64) SearchBox {
    Eigen::Vector3d low = Eigen::Vector3d::Zero();   ///< corner of the points' box [m]
    Eigen::Vector3d high = Eigen::Vector3d::Zero();  ///< opposite corner [m]
    std::uint32_t count = 0;  ///< points stored, in points_ at [id * stride_, + count)
  };

  explicit VoxelHashMap(const VoxelHashMapConfig& config);
  VoxelIndex IndexOf(const Eigen::Vector3d& p) const;
  /// Index into voxels_ or -1.
  int Find(const VoxelIndex& index) const;
  /// Index into voxels_, creating an empty voxel when absent.
  int FindOrInsert(const VoxelIndex& index);
  /// Re-indexes voxels_ after their ids changed.
  void RebuildTable();
  void InvalidateNormalsAround(const VoxelIndex& index);
  /// Ids of the 27 voxels around `center` (itself first, then the 6 face, 12 edge and 8
  /// corner neighbours; -1 where empty), cached until voxels are removed (ids move): an ICP
  /// queries the same voxels at every iteration, and the next scans mostly the same ones.
  /// Measured (session 36, first 1500 `campus` seed-1 s00 scans): clearing the cache at
  /// every new voxel, i.e. at every scan, made its rebuilding (27 table look-ups per center)
  /// about 10 % of the odometry thread's CPU.
  const std::int32_t* NeighbourIds(const VoxelIndex& center) const {
    const std::uint32_t offset = NeighbourOffset(center);  // may grow neighbour_ids_: first
    return neighbour_ids_.data() + offset;
  }
  /// Offset of those 27 ids in neighbour_ids_ (stable until the cache is cleared; pointers
  /// are not, the vector grows).
  std::uint32_t NeighbourOffset(const VoxelIndex& center) const;
  /// NeighbourOffset of query i's `center`, reusing the last FindMatches' offset when query i
  /// had the same center then (same result, no look-up).
  std::uint32_t QueryNeighbourOffset(std::size_t i, const VoxelIndex& center) const;
  /// FindMatches' search for query i: recalls its last match when that is provably still the
  /// nearest point (see QueryMemory, `recall`: the map is unchanged since), otherwise
  /// searches with MatchAround and remembers what it found.
  bool SearchOrRecall(std::size_t i, const Eigen::Vector3d& query, const VoxelIndex& center,
                      const std::int32_t* ids, double bound_sq, bool recall,
                      TargetMatch* match, bool* recalled) const;
  /// FindMatch's search among the voxels `ids` around `center`, the voxel of `query`, for the
  /// nearest point closer than sqrt(bound_sq). Reads only, unless normals are enabled (they
  /// are computed and cached on demand).
  /// With `clear_sq`: a lower bound on the squared distance from `query` to every point of
  /// those voxels other than the match (infinite when there is none).
  bool MatchAround(const Eigen::Vector3d& query, const VoxelIndex& center,
                   const std::int32_t* ids, double bound_sq, TargetMatch* match,
                   double* clear_sq = nullptr) const;
  void ClearNeighbourCache();
  /// Enters the new voxel `id` at `index` into the cached neighbourhoods that contain it.
  void AddToCachedNeighbourhoods(const VoxelIndex& index, std::uint32_t id);
  const Eigen::Vector3d* PointsOf(std::size_t id) const { return points_.data() + id * stride_; }
  Eigen::Vector3d* PointsOf(std::size_t id) { return points_.data() + id * stride_; }
  NormalState ComputeNormal(const Eigen::Vector3d& p, const VoxelIndex& index,
                            Eigen::Vector3d* normal) const;

  VoxelHashMapConfig config_;
  double inv_voxel_size_ = 1.0;
  std::uint32_t epoch_ = 0;
  bool normals_enabled_ = true;
  /// Some normal was computed since the last Clear(): only then do insertions have cached
  /// normals to invalidate (the odometry with scan normals never asks for one).
  mutable bool normals_cached_ = false;
  bool removed_once_ = false;
  /// Center voxel -> offset of its 27 ids in neighbour_ids_ (open addressing, as table_).
  mutable VoxelIndexTable neighbour_cache_;
  mutable std::vector<std::int32_t> neighbour_ids_;  ///< 27 per cached center
  /// What the last search of query i (FindMatches' i-th query) found, for its next search.
  /// An ICP searches the same source points at every iteration and they move by millimetres:
  /// - the neighbour-cache offset is reused while the query stays in its voxel (no look-up);
  /// - the nearest point is recalled without a search while the map is unchanged and
  ///   |match - query now| + |query now - query then| < clear: every other point of the
  ///   neighbourhood is then still farther from the query than the match (roughly: the query
  ///   moved by less than half the margin by which the match was the nearest), so a search
  ///   would find it again, with the same distance bits (one SquaredDistance expression; no
  ///   -march flags, so no FMA contraction differs between the two). The margin of the test
  ///   grows with the coordinates' size, which bounds the rounding of the voxel-face tests.
  struct QueryMemory {
    Eigen::Vector3d query = Eigen::Vector3d::Zero();  ///< where it was last searched [m]
    Eigen::Vector3d match = Eigen::Vector3d::Zero();  ///< the nearest point found there
    /// Every other point of the 27 voxels around `center` is at least this far from `query`
    /// (squared [m^2]; a lower bound from the points, boxes and voxel faces the search saw).
    double clear_sq = 0.0;
    VoxelIndex center = VoxelIndex::Zero();
    std::uint32_t offset = VoxelIndexTable::kEmpty;  ///< in neighbour_ids_; kEmpty: look up
    bool has_match = false;  ///< `match` is valid (found within that search's bound)
  };
  /// Per query of the last FindMatches (emptied with the neighbour cache).
  mutable std::vector<QueryMemory> memory_;
  /// content_version_ at the last FindMatches: the matches in memory_ hold while it is equal.
  mutable std::uint64_t memory_version_ = 0;
  /// Changes whenever a point is added or removed.
  std::uint64_t content_version_ = 1;
  mutable std::uint64_t recalled_ = 0;  ///< see recalled_matches()
  Eigen::Vector3d last_removal_position_m_ = Eigen::Vector3d::Zero();
  // Voxel index -> id in voxels_ (open addressing: ~3x faster lookups than
  // std::unordered_map here, which dominate the ICP's run time).
  VoxelIndexTable table_;
  std::vector<Voxel> voxels_;
  std::vector<SearchBox> boxes_;  ///< per voxel, same ids as voxels_
  // Voxel i owns points_[i * stride_, (i + 1) * stride_), stride_ = max_points_per_voxel. One
  // flat array instead of a vector per voxel saves the search a cache miss per visited voxel.
  std::size_t stride_ = 1;
  std::vector<Eigen::Vector3d> points_;
};

}  // namespace core
}  // namespace multisession_mapper
