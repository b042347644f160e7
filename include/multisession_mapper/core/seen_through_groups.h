// Seen-through groups: the in-session visibility evidence judged per connected group of voxels
// above the ground rather than per voxel. An object seen only from 20-60 m (a car on a road beside
// the route, a pedestrian far ahead) leaves a trail of voxels, each measured by one or two rings a
// few times. Each voxel gets a few checks, split between "seen through" (a later or earlier beam
// passed where it was) and "consistent" (a beam landed within the margin, 0.3 m + 2 % of the range:
// 1.3 m at 50 m), so the per-voxel majority rule keeps most of them. Over the whole trail the share
// of seen-through checks is large, while a static object's voxels are seen through only now and
// then (a beam slipping past an edge): the groups show what single voxels cannot. Session 52, seed
// 1 s00 alone (submaps at their true origins), a diagnostic build's counters of the 8.45 million
// voxels the per-voxel rules kept: the 13,024 moving-object points the map keeps are kept (by the
// evaluator's label transfer) through 6,210 map points, 2,877 of which were measured only from
// beyond 40 m. None of the rules on a voxel's own counters that were tried separated them from
// static voxels (a tie rule, seen through at least as often as consistent, dropped 16 static voxels
// for each moving one). Groups did: with the true terrain as their ground, the rule below took
// 1,024 moving-object voxels and 389 static ones; with the submap's own fine ground 191 and 376
// (objects seen from afar have no ground of their own), hence the coarse ground as well (574 and
// 765) and a ground plane per submap. In the pipeline (defaults, s00 alone, true origins), seeds 1
// / 3 / 2 (3 and 2 not tuned on): removed 96.42 / 96.75 / 97.35 % -> 96.71 / 96.82 / 97.44 % (fine
// and coarse ground) -> 96.81 / 96.92 / 97.55 % (and the plane), static SA 99.723 / 99.811 / 99.791
// % -> 99.705 / 99.802 / 99.779 %; whole seed-1 s00 2.6 % more CPU, 5 % more wall time (Finalize
// waits for it).
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "multisession_mapper/core/status.h"
#include "multisession_mapper/core/types.h"
#include "multisession_mapper/core/voxel_key.h"

namespace multisession_mapper {
namespace core {

struct SeenThroughGroupsConfig {
  /// A group is dropped when seen_through / (seen_through + consistent), summed over its
  /// voxels, is at least this [0, 1). 0 disables the groups.
  double min_seen_through_ratio = 0.3;
  /// ... and at least this fraction [0, 1] of its voxels was seen through at least once (the
  /// evidence is spread over the object, not one voxel's).
  double min_seen_voxel_fraction = 0.2;
  /// ... and it has at least this many voxels.
  int min_voxels = 3;
  /// Only voxels higher than this above their local ground form groups (the ground is seen
  /// at grazing angles, where beams pass above it within the margin) [m].
  double min_height_m = 0.25;
  /// Local ground: the lowest voxel per horizontal cell of this edge, the minimum over the
  /// 3 x 3 cells around (see local_ground.h) [m].
  double ground_cell_m = 0.5;
  /// Objects seen only from afar have no ground of their own in the submap (a VLP-16 1.8 m
  /// up measures flat ground to ~34 m), so their lowest voxels are their local ground and the
  /// rest of them sits only a ring's spacing above it. A voxel also forms groups when it lies
  /// higher than coarse_min_height_m above the ground of coarse cells (same 3 x 3 minimum)
  /// [m, m]. Seed 1, s00 alone, true origins, from the evidence of the kept voxels: the fine
  /// ground alone gave 191 moving-object voxels and 376 static ones; with 4 m cells and
  /// 0.5 m, 574 and 765; 4 m cells and 0.25 m for every voxel, 736 and 4,047 (terrain on far
  /// slopes); the true terrain as the ground, 1,024 and 389 (voxels from 20 m on).
  double coarse_ground_cell_m = 4.0;
  double coarse_min_height_m = 0.5;
  /// Only voxels never measured closer than this form groups [m]: nearer objects get enough
  /// checks per voxel (seed 1, true terrain as the ground: 1,024 moving-object and 389 static
  /// voxels from 20 m on, 1,032 and 381 from 0 m), and the groups' look-ups cost CPU.
  double min_nearest_range_m = 20.0;
  /// The ground as one plane per call (a submap), fitted by least squares, trimmed three
  /// times, to the voxels at most 0.05 m above their fine ground and measured from at most
  /// plane_fit_max_range_m (the ground near the route, where the rings reach it), from at
  /// least 50 of them spread over at least 1 m (standard deviation) in every horizontal
  /// direction: a voxel also forms groups when it lies higher than
  /// plane_min_height_m above it. It reaches the objects seen only from afar, beyond the
  /// coarse cells of any measured ground. 0: no plane [m, m].
  double plane_min_height_m = 0.5;
  double plane_fit_max_range_m = 30.0;

  Status Validate() const;
};

/// One voxel that the per-voxel rules kept, with its evidence.
struct GroupVoxel {
  VoxelKey key;               ///< its voxel (groups connect 26-neighbours)
  Eigen::Vector3d point_up;   ///< its point in a frame with z up (for the local ground) [m]
  std::uint32_t seen_through = 0;
  std::uint32_t consistent = 0;
  float nearest_range_m = 0.0f;  ///< the smallest range it was measured from [m]
};

/// Indices into `voxels` of the voxels of the groups to drop, ascending. Empty when disabled.
/// The points must be finite.
std::vector<std::uint32_t> SeenThroughGroups(const SeenThroughGroupsConfig& config,
                                             const std::vector<GroupVoxel>& voxels);

}  // namespace core
}  // namespace multisession_mapper
