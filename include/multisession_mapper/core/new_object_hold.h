// Holding back new objects at a merge. The map update adds to the history the points of the
// new session that the history lacks (mending behind removed objects, fused submaps' new
// structure), and keeps the new submaps that overlap the history too little to be fused. A
// car parked where the history saw the ground, or where it saw another car that this merge
// removed, is such a point set too: present in the new session only, so by the map's own
// definition not static (an object is static when every session that saw its place saw it).
// The update therefore holds back each connected above-ground group of candidate points
// (those with no history point near: the points to add, and those of the kept new submaps
// that were paired with history submaps) that has the shape of a movable object, stands alone
// (few history points above the ground next to it: not a new face of an object the history
// keeps) and lies where the history measured something (its ground, or the object this merge
// removed). What the history never saw is still added: the map stays complete where it could
// not know better.
#pragma once

#include <cstdint>
#include <vector>

#include "multisession_mapper/core/status.h"
#include "multisession_mapper/core/types.h"

namespace multisession_mapper {
namespace core {

struct NewObjectHoldConfig {
  bool enabled = true;
  /// Local ground: the lowest point of the history, the removed points and the candidates in
  /// cells of this edge, the minimum over the 3 x 3 cells around [m]; a candidate more than
  /// ground_tolerance_m above it is above the ground [m] (the detection's values).
  double ground_cell_m = 0.5;
  double ground_tolerance_m = 0.25;
  /// Above-ground candidates closer than this are one group [m]. The candidates are sparse
  /// (only where the history has no point within a 0.2 m voxel), so the radius is wider than
  /// the detection's 0.45 m.
  double grow_radius_m = 0.6;
  int min_points = 5;
  /// Movable shape (the detection's changed-object test without normals): horizontal extent
  /// (bounding-box diagonal) [m], top and bottom above the local ground [m]. The extent may be
  /// longer than the detection's 9 m: the candidates of a row of fence panels or of cars
  /// parked close together grow into one group (a row of three 3.5 m construction fence
  /// panels is 10.7 m long), and a group is held back only where the history saw the ground
  /// or removed an object. Session 72, 3-session `campus`, map fit, 9 -> 12 m, seeds 1 / 2 /
  /// 3: low-dynamic DA 52.81 -> 53.98 / 60.18 -> 60.18 / 51.14 -> 51.14 % (+6,040 / -22 / +0
  /// points removed; seed 1: a three-panel fence row that the session without it had
  /// removed came back with the third session), static SA 99.455 -> 99.454 / 99.524 ->
  /// 99.521 / 99.404 -> 99.404 % (+104 / +489 / +17 static points lost, seed 2's a wall);
  /// 15 m on seed 1 (against 9 m): +6,162 low-dynamic, +1,333 static points.
  double max_extent_m = 12.0;
  double max_top_m = 3.5;
  double max_bottom_m = 0.8;
  /// Alone: at most this fraction [0, 1] of the group's points has a history point above the
  /// ground (after this merge's removals) within attach_radius_m [m]. 3-session `campus`, map
  /// fit, hold off / 0.2 / 0.4 / 0.6 (session 47): low-dynamic DA seed 1 42.93 / 51.23 / 52.83
  /// / 53.98 %, static SA 98.46 / 98.45 / 98.43 / 98.40 % (parked cars that stayed lose 36.5k /
  /// 38.4k / 42.5k / 47.6k points); seed 3 40.23 / 47.88 / 50.16 %, SA 98.94 / 98.92 / 98.91 %;
  /// seed 2 (not tuned on) 45.74 / 56.27 / 57.96 %, SA 99.11 / 99.10 / 99.08 %.
  double attach_radius_m = 0.5;
  double max_attached_fraction = 0.4;
  /// Seen: at least this many history points on the ground, or removed by this merge, lie
  /// within the group's horizontal bounding box grown by seen_margin_m [m] (counted per ground
  /// cell: cells that overlap the box count whole).
  double seen_margin_m = 0.3;
  int min_seen_points = 5;

  Status Validate() const;
};

/// A point cloud and its pose in the map frame.
struct PlacedPoints {
  const PointVector* points = nullptr;
  Pose3 T_map_points = Pose3::Identity();

  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

struct NewObjectHoldResult {
  std::vector<std::uint8_t> held;  ///< per candidate: 1 to hold back
  std::size_t groups_held = 0;
};

/// Decides, per candidate point (map frame), whether the update holds it back. `history`: the
/// history submaps after this merge's removals; `removed_m`: the points this merge removed
/// (map frame). Disabled: nothing is held. An error only for non-finite points.
StatusOr<NewObjectHoldResult> HoldBackNewObjects(const NewObjectHoldConfig& config,
                                                 const PointVector& candidates_m,
                                                 const std::vector<PlacedPoints>& history,
                                                 const PointVector& removed_m);

}  // namespace core
}  // namespace multisession_mapper
