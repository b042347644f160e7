// Low-dynamic detection between two overlapping submaps of different sessions (reference
// paper, section VI-B; issue 7): objects present in one session and absent in the other
// (parked cars that left, bins, construction fences), found in sparse LiDAR submaps.
//
//  1. The history submap is moved into the current submap's frame.
//  2. Seeds: point pairs closer than d_beta (kd-tree); region growing from the seeds in each
//     submap (point distance and normal difference) gives the common parts; the rest of each
//     submap is its difference set.
//  3. A voxel map of each difference set; ray casting from each submap's sensor origins (the
//     scan poses recorded in the submap) keeps only occupied voxels in front of the rays; the
//     remaining occupied voxels of one set are ray-cast through the other session's free space
//     to find coarse dynamic points (something stood where the other session saw through).
//  4. Region growing turns the coarse dynamic points into the final dynamic points; a height
//     guard (points higher than `height_guard_m` above the local ground are never coarse
//     dynamic points, and dynamic only as part of an object grown from below them, at most
//     `guard_object_height_m` high) can be switched off. A detected object also takes the
//     points below it that the ground tolerance left out (wheels, lower body) when the other
//     session has no partner for them (`bottom_extension_radius_m`).
//  5. Changed objects (an addition to the paper): another object in the same place, e.g. a
//     parking slot taken by a different car each day. Neither session sees through the other's
//     car, and their shared surfaces (sides within d_beta, roofs) make most of both common, so
//     steps 2-4 find little. Instead the above-ground points of each submap are segmented into
//     objects; an object of movable size (footprint, height, mostly planar surfaces: no
//     hedge or canopy) whose points lie off the other session's surfaces where the other
//     session has a surface close by (point-to-plane distance over `changed_surface_distance_m`)
//     or saw through them, for at least `changed_min_fraction` of the points where the other
//     session has a surface or saw through, is dynamic as a whole: the
//     place does not hold the same object in both sessions, so neither version is static.
//     For the same reason an examined object touching an object changed on the other side
//     is changed too when it disagrees a little itself (`changed_partner_min_fraction`), and
//     an object one of whose ends lies off the other session's surface facing the same way
//     is changed (`changed_end_min_compared`: another car whose long sides coincide).
//  6. Low residue (an addition to the paper): small blobs 0.08-0.25 m above the ground where
//     the other session measured bare ground and nothing at their level (feet, the bottom of
//     a wheel; `low_residue_min_ground_points`), which no ray can see through.
//  7. Mending: points of the current difference set that are not dynamic and were hidden in
//     the history session (behind what was removed) are returned for adding to the history.
//
// How the sparse submaps are handled (the submaps keep one point per 0.2 m voxel, the sensor
// origins of their scans and, since session 43, each point's nearest and last measuring scan):
//  - A ray goes from each point to its `rays_per_point` nearest sensor origins (origins thinned
//    to one per `origin_spacing_m`), or with `rays_from_viewing_scans` to the origins of the
//    scans that measured it (when its submap recorded them). A ray that meets an occupied
//    voxel of its own session before its end did not see its end point from there and is
//    dropped ("only occupied voxels in front of the rays"). Free space ends `end_margin_m`
//    before the end point (longer for rays that graze the ground) so that surface samples do
//    not clear their neighbours.
//  - Porous things (tree canopies, hedges, mesh fences) return different points every session:
//    one session's rays pass where the other hit a leaf. A point only counts as a coarse
//    dynamic point when the evidence is consistent: at least `min_passing_rays` rays of the
//    other session pass through its voxel AND the other session has no point above the ground
//    within `support_radius_m` of it (a removed car leaves empty air; a canopy does not). A
//    detection must be a cluster of at least `min_cluster_points` points with at least
//    `min_cluster_coarse_points` coarse points, and it must stand on the ground (its lowest
//    point at most `max_object_bottom_m` above it): a crown that floats above its trunk is no
//    movable object. So canopies stay static with the height guard off; the guard is kept as
//    the paper's default.
//  - Free columns: a parked car seen from 15-25 m by the other session is crossed mostly low,
//    by rays to the ground behind it, which pass through the car's place under its roof, not
//    through the voxels of its surface points. So the passing rays that count for a point are
//    those through its voxel and through the empty column below it (the inside of the object
//    for its own session: no own occupied voxel), down to `column_clearance_m` above the ground
//    and at most `free_column_depth_m` deep.
//  - Local ground: the lowest point per `ground_cell_m` cell, minimum over the 3x3 cell
//    neighbourhood, of each submap for its own points (of both submaps where its own is more
//    than `own_ground_max_gap_m` higher: its view of the ground was blocked). Points within
//    `ground_tolerance_m` of it are ground: never dynamic by the free-space detection (the
//    ground under a removed car is seen by both sessions' rays at grazing angles; only the
//    bottom extension and the low residue, step 6, take points from that layer above
//    `bottom_min_height_m`) and no support.
#pragma once

#include <array>
#include <cstdint>
#include <utility>
#include <vector>

#include "multisession_mapper/core/point_index.h"
#include "multisession_mapper/core/point_index_pool.h"
#include "multisession_mapper/core/status.h"
#include "multisession_mapper/core/submap.h"
#include "multisession_mapper/core/types.h"

namespace multisession_mapper {
namespace core {

struct DynamicDetectionConfig {
  /// Seed distance d_beta: a point with a point of the other submap this close is common [m].
  double seed_distance_m = 0.15;
  /// Region growing: neighbour radius [m] and largest normal difference [rad].
  double grow_radius_m = 0.3;
  double grow_max_normal_angle_rad = 0.35;
  /// Normals for the region growing: one per cubic voxel of this edge, from the covariance of
  /// the submap's points in it (planar voxels only) [m].
  double normal_voxel_m = 0.6;
  /// Voxel size of the difference-set voxel maps used for ray casting [m]. 0.2 m, the
  /// submaps' own sampling: the paper's 0.04 m grid on 0.2 m-sampled surfaces is mostly holes
  /// through which rays leak, and costs 5x the traversal steps. Not yet swept on simulated data.
  double voxel_size_m = 0.2;
  /// Ray casting: sensor origins are thinned to one per this distance [m]; each point is
  /// ray-cast from its this many nearest thinned origins within `max_ray_length_m` [m].
  double origin_spacing_m = 2.0;
  int rays_per_point = 2;
  double max_ray_length_m = 40.0;
  /// A point whose submap recorded which scans measured it (Submap::views) is ray-cast from
  /// those scans' origins (nearest and last measurement, within max_ray_length_m) instead of
  /// its nearest thinned origins, which need not have seen it.
  bool rays_from_viewing_scans = false;
  /// A ray counts as passing a queried voxel only when it meets the plane of the point that
  /// put the voxel in question (its normal, normal_voxel_m) at least at this angle [rad]:
  /// a ray that runs nearly parallel to a surface may pass beside it through the 0.2 m voxel
  /// that holds it (the far side of a parked car that one submap saw and the other did not).
  /// Points without a normal and the free column below them take every ray. 0: off.
  double min_pass_incidence_rad = 0.0;
  /// Only points within this distance of the other session's sensor origins are examined
  /// (can be dynamic or mended) [m]: farther points are sparse, and their alignment error
  /// grows with range (0.5 deg of rotation error is 0.2 m at 25 m).
  double max_range_m = 25.0;
  /// Far band: points between max_range_m and far_range_m of the other session's sensor
  /// origins are examined too, but a detection holding any of them is kept only when it has
  /// the shape of a movable object (the changed-object step's test: extent, top, bottom and
  /// planar fraction), and they are never mended [m]. Half of the `campus` low-dynamic points
  /// lie 20-60 m from the path of the session that saw their place empty; there the ground
  /// is rarely measured (a VLP-16 at 1.8 m reaches flat ground only up to ~35 m) and the local
  /// ground is the lowest point around: the lower part of a porous crown would pass for an
  /// object standing on the crown's own lowest points. The test therefore first grows the
  /// detection over every above-ground point of its submap (a crown is then too tall or too
  /// wide). `dynamic_detection_benchmark`
  /// (`campus` s00-s01, submaps at their true origins, scored within 60 m, guard on), 0 / 40 /
  /// 50 m (with max_ray_length_m 50): seed 1 low-dynamic DA 30.9 / 35.6 / 38.6 %, static SA
  /// 99.758 / 99.757 / 99.711 %; seed 2 (not tuned on) 36.6 / 40.9 / 43.0 %, 99.827 / 99.804
  /// / 99.745 %. 0 (or <= max_range_m): off.
  double far_range_m = 40.0;
  /// Far band, ground around: an object holding far-band points (a detection, or an object
  /// the changed-object step examines when changed_compare_range_m exceeds max_range_m) must
  /// also stand on the ground of its surroundings: its lowest point out of ground_tolerance_m
  /// of its local ground at most far_max_bottom_m [m] above the lowest point of both submaps
  /// in the 3 x 3 cells of edge far_ground_cell_m [m] around it (0: off; else at least
  /// ground_cell_m). Under a tree crown seen from afar, whose trunk and ground nobody
  /// measured, the local ground (ground_cell_m) is the crown's own lowest points, and a
  /// fragment of the lower crown passed for a car-sized object standing on the ground, which
  /// the crowns' day-to-day scatter made dynamic or changed. Session 71, 3-session `campus` pipeline (map fit), seeds 1 / 2 / 3,
  /// off -> on: static points lost 115,279 -> 112,003 / 109,264 -> 106,020 / 128,864 ->
  /// 124,449 (canopy SA 99.625 -> 99.658 / 99.572 -> 99.601 / 99.552 -> 99.593 %), low-dynamic
  /// points removed -247 / +62 / -12; with far_max_bottom_m 1.2: -715 / -9 / -612 for about
  /// the same gain (docs/status_details.md).
  double far_ground_cell_m = 2.0;
  double far_max_bottom_m = 1.6;
  /// Free space ends this far before a ray's end point [m]; for end points on the ground it is
  /// end_margin_m / sin(ray elevation), at most max_end_margin_m [m].
  double end_margin_m = 0.3;
  double max_end_margin_m = 2.0;
  /// Consistent free-space evidence for a coarse dynamic point: this many passing rays of the
  /// other session through its voxel, and at most `max_support_points` points of the other
  /// session above the ground within `support_radius_m` [m].
  int min_passing_rays = 2;
  /// Passing rays also count in the free column below a point (see above): at most this deep
  /// [m] (0: the point's voxel only, the paper's test), down to this height above the local
  /// ground [m] (cars' ground clearance is ~0.3 m: rays under a car that stays say nothing).
  /// Measured with `dynamic_detection_benchmark` (submaps at their true poses, height guard on):
  /// `small` s00-s01 low-dynamic DA 41.1 -> 46.8 %, static SA 99.01 -> 98.96 %; `campus`
  /// s00-s01 44.9 -> 46.7 %, SA 99.61 -> 99.57 %, canopy SA 99.97 -> 99.96 %.
  double free_column_depth_m = 2.4;
  double column_clearance_m = 0.35;
  double support_radius_m = 0.4;
  int max_support_points = 0;
  /// Growing the coarse dynamic points into objects: neighbour radius [m]; a detection needs
  /// this many points, of which this many coarse.
  double dynamic_grow_radius_m = 0.45;
  int min_cluster_points = 10;
  int min_cluster_coarse_points = 3;
  /// ... and at least this fraction of its points coarse [0, 1]: an object that the other
  /// session's rays really passed through is seen through over much of it, while a few
  /// grazing or column passes make a handful of coarse points in a surface the other session
  /// saw from the other side. 0: off.
  double min_cluster_coarse_fraction = 0.0;
  /// A detection must stand on the ground: its lowest point at most this high above the local
  /// ground [m]. Movable things rest on the ground (a car seen over another one shows only its
  /// top, from about 1.2 m); a porous tree crown or the upper part of a facade that the other
  /// session saw through floats. campus s00-s01 pair, height guard off
  /// (dynamic_detection_benchmark): canopy SA 95.66 % without the rule, 99.53 % at 1.5 m,
  /// 99.90 % at 1.0 m; low-dynamic DA 53.9 / 53.3 / 50.2 %. 0: off.
  double max_object_bottom_m = 1.5;
  /// A detected object also takes the points below it down to `bottom_min_height_m` above
  /// the ground (wheels and lower body, which ground_tolerance_m leaves to the ground): a point
  /// without a close partner in the other session, lower than one of the object's points,
  /// within this horizontal distance of it and at most `bottom_max_drop_m` below it [m]
  /// (0: off). Pair benchmark (`campus` s00-s01, true origins, guard on), off -> 0.2 m:
  /// seed 1 low-dynamic DA 53.20 -> 54.96 %, static SA 99.533 -> 99.474 %; seed 2 (not tuned
  /// on) 52.94 -> 54.46 %, 99.675 -> 99.644 %.
  double bottom_extension_radius_m = 0.2;
  double bottom_min_height_m = 0.08;
  double bottom_max_drop_m = 0.5;
  /// Local ground: cell edge [m]; points this close above the ground are ground [m]. Each
  /// submap's points are measured against its own ground, unless that is more than
  /// own_ground_max_gap_m above the ground of both submaps together [m]. Measured with
  /// `dynamic_detection_benchmark` (small seed 1, submaps at their true poses; pairs s00-s01 /
  /// s00-s02 / s01-s02): with the joint ground and 1 m cells, 16.7 / 20.9 / 20.3 thousand
  /// ground points were removed as dynamic (static SA 97.7 / 97.9 / 97.1 %); with the own
  /// ground and 0.5 m cells 3.9 / 2.6 / 3.5 thousand (SA 99.2 / 99.5 / 99.1 %), low-dynamic DA
  /// 42.9 -> 42.2, 54.5 -> 52.2, 50.3 -> 47.5 %.
  double ground_cell_m = 0.5;
  double ground_tolerance_m = 0.25;
  double own_ground_max_gap_m = 1.0;
  /// Height guard: points higher than height_guard_m above the local ground are never coarse
  /// dynamic points (free-space evidence up there is mostly canopy); they are dynamic only as
  /// part of an object grown from below, and only up to guard_object_height_m (trucks, vans)
  /// [m] (below height_guard_m: the plain guard). Measured with `dynamic_detection_benchmark`
  /// (true poses, guard on): growing above
  /// the guard up to 3.5 m gave `small` s00-s01 low-dynamic DA 46.8 -> 55.4 %, static SA
  /// 98.96 -> 98.92 %, canopy SA 99.71 -> 99.63 % (up to any height: SA 98.77 %, canopy 99.18 %
  /// with more building points); `campus` s00-s01 46.7 -> 47.3 %, SA 99.57 -> 99.55 %,
  /// canopy SA 99.96 -> 99.92 %.
  bool height_guard_enabled = true;
  double height_guard_m = 2.0;
  double guard_object_height_m = 3.5;
  /// Changed objects (step 5): off with changed_objects_enabled = false. Objects are the
  /// above-ground points within changed_compare_range_m of both sessions' scan origins,
  /// grown with changed_grow_radius_m [m]; an object is examined when it has at least
  /// changed_min_points points, a horizontal extent (bounding-box diagonal) of at most
  /// changed_max_extent_m [m], its top at most guard_object_height_m above the ground (also
  /// with the guard off: taller things are buildings, trees and posts), its bottom at most
  /// changed_max_bottom_m above the ground [m] (it stands on the ground), and at least
  /// changed_min_planar_fraction of its points on planar surfaces (hedges and canopies are
  /// not). A point is compared when the other session has an above-ground point within
  /// changed_neighbour_radius_m [m] or, with no such point, min_passing_rays of its rays
  /// passed through the point's voxel. It contradicts the other session when it was seen
  /// through, or when no such neighbour is within changed_surface_distance_m of it, measured
  /// along the neighbour's normal where the neighbour has one (Euclidean otherwise) [m], and
  /// at least one of them has a normal (off a blurred or sparse surface, a gap between samples
  /// says nothing: the point is then not compared). At least changed_min_compared points must
  /// be compared, and at least changed_min_fraction [0, 1] of them contradict.
  /// Measured with `dynamic_detection_benchmark` (`campus` seed 1, s00-s01, submaps at their
  /// true origins, guard on): low-dynamic DA 47.3 -> 53.8 % (places taken by another object
  /// 20.5 -> 32.7 %), static SA 99.55 -> 99.52 %, canopy SA unchanged (99.92 %); with
  /// changed_min_fraction 0.3: 55.4 % and 99.46 %. Requiring a planar neighbour cut the same
  /// cars flagged as changed from 28 % to 9 % of the examined ones; moving the object first by
  /// the local alignment error (of the object itself, or of its surroundings) was tried and
  /// not kept: it flagged more of the same cars, or missed most of the other cars.
  /// The shape test is made on the whole object (grown over every above-ground point of its
  /// submap, as the far band's), not on its cut by the compare range, which made a wall or
  /// hedge leaving the range pass for a car-sized object. Session 28, pair benchmark (`campus`
  /// s00-s01, true origins, guard on, scored within 25 m), seed 1 / seed 2: the whole-object
  /// test at 15 m keeps low-dynamic DA the same (55.03 / 55.20 %) and raises static SA 99.548
  /// -> 99.558 / 99.635 -> 99.655 % (wall points removed 761 -> 235 / 2011 -> 941); the
  /// compare range 15 -> 20 m without it: DA 58.53 / 59.78 %, SA 99.457 / 99.544 % (walls,
  /// hedges and canopy cut by the range), with it: DA **58.39 / 59.78 %** (places taken by
  /// another object 32.5 -> 38.8 / 37.3 -> 44.6 %), SA **99.525 / 99.618 %**, canopy SA 99.949
  /// -> 99.927 / 99.905 % (unchanged); the rest of the SA cost is parked cars that stayed
  /// (15860 -> 17278 / 13406 -> 14797 points). 25 m (seed 1, without the whole-object test):
  /// DA 61.45 %, SA 99.367 %, canopy 99.711 %; with changed_min_fraction 0.5: 58.00 / 99.441 %
  /// (at 15 m: 53.86 / 99.559 %).
  bool changed_objects_enabled = true;
  double changed_compare_range_m = 20.0;
  double changed_grow_radius_m = 0.45;
  int changed_min_points = 20;
  double changed_max_extent_m = 9.0;
  double changed_max_bottom_m = 0.8;
  double changed_min_planar_fraction = 0.3;
  double changed_neighbour_radius_m = 0.5;
  double changed_surface_distance_m = 0.12;
  int changed_min_compared = 15;
  double changed_min_fraction = 0.4;
  /// Partners: an examined object that its own comparison leaves unchanged becomes changed
  /// when it touches an object changed on the other side (a point of that object is among
  /// the 4 nearest other-side points within changed_neighbour_radius_m of one of its points)
  /// and at least this fraction [0, 1] of its compared points contradict: two
  /// different objects in one place are both absent from the other session. A value of
  /// changed_min_fraction or more turns the rule off. Session 29, pair benchmark (`campus`
  /// s00-s01, true origins, guard on, scored within 25 m), seed 1 / seed 2, off -> 0.3:
  /// low-dynamic DA 58.39 -> 59.90 / 59.78 -> 60.17 % (places taken by another object 38.80
  /// -> 41.64 / 44.56 -> 45.18 %), static SA 99.525 -> 99.524 / 99.618 -> 99.610 %; 0.2:
  /// 60.09 / 60.61 %, SA 99.513 / 99.603 %; 0.1 (seed 1): 60.18 %, SA 99.499 %.
  double changed_partner_min_fraction = 0.3;
  /// An object is changed also when one of its ends has at least changed_end_min_compared
  /// compared points of which changed_end_min_fraction contradict the other session (0: off).
  /// Its ends are its points whose own normal lies within acos(changed_end_min_cos) of its
  /// longest horizontal axis (2-D principal axis of its points), one on each side of its
  /// centroid. An end point is judged only by the other session's surfaces that face the same
  /// way (neighbours within changed_neighbour_radius_m whose normal is within
  /// acos(changed_end_min_cos) of the point's own): it contradicts when none of them is within
  /// changed_surface_distance_m along the normal, and with none it is not compared. Why: the
  /// simulator's car in a changing slot is 4.0-4.9 m long (a van 4.9-5.4 m) and parked up to
  /// 0.3 m along the slot from the last, so another car in the slot often has its long sides
  /// where the first car's were and its ends elsewhere; the ends hold too few of the compared
  /// points for changed_min_fraction. Session 67, 3-session `campus` pipeline (map fit),
  /// seeds 1 / 2 / 3, without -> with 10 / 0.8 / 0.85: low-dynamic DA 51.20 -> 53.13 /
  /// 57.84 -> 59.49 / 50.18 -> 51.53 %, static SA 99.4176 -> 99.4167 / 99.4552 -> 99.4551 /
  /// 99.3469 -> 99.3469 % (static parked-car points lost 34,998 -> 34,850 / 24,379 -> 24,381 /
  /// 42,777 -> 42,777), high-dynamic DA, canopy SA and ATE unchanged. Judging the ends by any
  /// contradiction (seen through, or off the other car's side beside a corner) instead flagged
  /// cars that stayed: with 15 / 0.9, DA +0.96 / +1.81 / +1.27 points but static SA -0.03 /
  /// -0.04 / -0.03 points, more wrong points on every seed.
  int changed_end_min_compared = 10;
  double changed_end_min_fraction = 0.8;
  double changed_end_min_cos = 0.85;
  /// The same object in both sessions keeps its points: an examined object that is not
  /// changed, with at least changed_min_compared compared points of which at most this
  /// fraction [0, changed_min_fraction) contradict the other session, loses none of its points
  /// (those the changed-object step examined: above the ground, within its compare range) to
  /// the free-space detection (steps 3-4) of this pair. Why: the free-space detection takes
  /// parts of cars that stayed (rays of the other session through the voxels of their far side
  /// or edges, grown over the car), while their surfaces agree with the other session's; on
  /// `campus` seed 2 s00-s01 (12 pairs) the pairs removed 3,335 static parked-car points, 2,556
  /// of them by the free-space detection on 17 such cars (0.3: 1,593 lost instead of 3,335,
  /// low-dynamic DA 55.67 -> 54.44 %). Session 68, 3-session `campus` pipeline (map fit),
  /// seeds 1 / 2 / 3, off -> 0.3: static SA 99.417 -> 99.452 / 99.455 -> 99.484 / 99.347 ->
  /// 99.374 % (static parked-car points lost 34,850 -> 27,782 / 24,381 -> 17,861 / 42,777 ->
  /// 37,295), low-dynamic DA 53.13 -> 52.34 / 59.49 -> 59.08 / 51.53 -> 51.31 %: fewer wrong
  /// points in all, but the DA is the target not met, so it is off. 0: off.
  double changed_same_max_fraction = 0.0;
  /// Low residue (an addition to the paper): the returns of feet and wheels just above the
  /// ground (bottom_min_height_m to ground_tolerance_m above it: the layer) that the
  /// in-session filter kept, since a beam through them lands on the ground right behind. Rays
  /// cannot see through that layer, but the other session measured the ground there. A point
  /// of the layer is dynamic when
  ///  - the other session has at least `low_residue_min_ground_points` ground points (below
  ///    bottom_min_height_m above its ground, so with bottom_min_height_m 0 the rule finds
  ///    no ground and takes nothing) within `low_residue_radius_m` horizontally, lower than
  ///    the point by more than 0.05 m;
  ///  - it has no point within `low_residue_partner_distance_m` horizontally that stands above
  ///    its ground or at the point's own level, up to 0.5 m above the point (a curb, a low
  ///    wall, the foot of a trunk: in both sessions, though sampled at other places);
  ///  - it lies within `low_residue_range_m` (at most max_range_m) of the other session's
  ///    scan origins as thinned by origin_spacing_m (its beams reached the layer there: the
  ///    rule's losses on curbs grow with the range);
  ///  - at most `low_residue_max_own_neighbours` points of its own session's layer lie within
  ///    `low_residue_blob_radius_m` (a small blob, not a long curb that the other session saw
  ///    elsewhere or not at all; 0: no limit).
  /// Measured with `dynamic_detection_benchmark` (campus, s00-s01, 12 pairs, seeds 1 / 2 / 3,
  /// off -> on): low-dynamic DA 46.37 -> 46.80 / 55.67 -> 56.01 / 79.26 -> 79.90 %, moving-object
  /// leftovers removed 51 -> 86 of 681 / 27 -> 35 of 662 / 61 -> 79 of 784, static points lost
  /// +28 / +23 / +35 (curbs and parked cars; SA -0.002 to -0.003 points), the same time per pair.
  /// With range 10 m or 10 own neighbours twice the static losses for ~10 % more. In the
  /// merge, the propagation to copies (map_update.propagate_radius_m, 0.2 m) also takes the
  /// other submaps' copies of what this rule marks: with no propagation from its points
  /// (tried, session 70), the 3-session pipeline (seeds 1 / 2) removed 709 / 648 more
  /// dynamic points than without the rule at +58 / -11 static points, with it 1,877 / 2,086
  /// at +559 / +297 (terrain right under the marked points): kept, for the DA, the target not
  /// met. The in-session pair pass (off by default) runs this step too, unmeasured. 0 ground
  /// points: off.
  int low_residue_min_ground_points = 3;
  double low_residue_radius_m = 0.2;
  double low_residue_partner_distance_m = 0.2;
  double low_residue_range_m = 7.0;
  int low_residue_max_own_neighbours = 7;
  double low_residue_blob_radius_m = 0.5;
  /// Mending: a current point with no history point this close, not dynamic and not seen
  /// through by `min_passing_rays` history rays, is missing from the history [m].
  double mending_distance_m = 0.3;

  Status Validate() const;
};

struct DynamicDetectionResult {
  std::vector<std::uint32_t> history_dynamic;  ///< indices into history.points
  std::vector<std::uint32_t> current_dynamic;  ///< indices into current.points
  /// Whether the detection marks more than `fraction` of either submap (sizes of their point
  /// sets): a pair that disagrees on that much is misaligned or not really overlapping, and
  /// removing it would damage the map.
  bool MarksMoreThan(double fraction, std::size_t history_points,
                     std::size_t current_points) const;
  /// Indices into current.points of static points hidden in the history session, to be added
  /// to the history submap (in the current frame; move them with T_history_current).
  /// Criterion: no history point within mending_distance_m, not current_dynamic, within
  /// max_range_m of a history sensor origin, and history's rays did not see through the
  /// place (hidden behind removed objects or otherwise out of the history's view).
  std::vector<std::uint32_t> current_mending;
  /// Every object examined by the changed-object step (step 5), for diagnosis and benchmarks.
  struct ExaminedObject {
    int side = 0;  ///< 0: history, 1: current
    std::vector<std::uint32_t> points;  ///< indices into that submap's points
    int compared = 0;  ///< points where the other session has a surface close by or saw through
    int off_surface = 0;  ///< of those, points off that surface or seen through
    int seen_through = 0;  ///< of those, points seen through (no surface close by)
    /// Points on each end of the object (own normal along its longest horizontal axis; [0]
    /// the end towards +axis) compared with the other session's surfaces facing the same
    /// way, and of those the ones that contradict (see changed_end_min_compared).
    std::array<int, 2> end_compared{};
    std::array<int, 2> end_off{};
    bool changed = false;
    bool by_partner = false;  ///< changed as the partner of an object changed on the other side
  };
  std::vector<ExaminedObject> examined_objects;
  /// Points of each submap ([0] history, [1] current) that the region growing of step 2 added
  /// to the common parts (seeds not counted), for diagnosis.
  std::array<std::size_t, 2> common_grown{};
  double time_s = 0.0;  ///< wall time of the whole detection [s]
  /// Wall time of each step [s] (their sum is time_s up to bookkeeping), for benchmarks:
  /// neighbour indices built here, ground grid, common parts (seeds and region growing),
  /// voxel maps and ray casting, coarse dynamic points grown into objects and the low residue
  /// (steps 4 and 6, in `dynamic_s`), changed objects (step 5), mending (step 7).
  struct StageTimes {
    double index_s = 0.0;
    double ground_s = 0.0;
    double common_s = 0.0;
    double rays_s = 0.0;
    double dynamic_s = 0.0;
    double changed_s = 0.0;
    double mending_s = 0.0;
    static constexpr int kCount = 7;
    /// The steps in their order, with their names (index, ground, common, rays, dynamic,
    /// changed, mending).
    std::array<std::pair<const char*, double>, kCount> Named() const {
      return {{{"index", index_s},
               {"ground", ground_s},
               {"common", common_s},
               {"rays", rays_s},
               {"dynamic", dynamic_s},
               {"changed", changed_s},
               {"mending", mending_s}}};
    }
    /// Adds `other`'s times step by step (sums over pairs).
    void Add(const StageTimes& other);
  };
  StageTimes stage;
};

/// Whether some point of `origins` (e.g. a submap's scan origins) lies within sqrt(range_sq)
/// of `p` [m^2]: the range test of the steps above (and of dynamic_detection_benchmark).
bool NearAny(const PointVector& origins, const Eigen::Vector3d& p, double range_sq);

class DynamicDetector {
 public:
  static StatusOr<DynamicDetector> Create(const DynamicDetectionConfig& config);

  /// `T_current_history` moves history-submap coordinates into the current submap frame.
  /// Both submaps carry their scans' sensor origins (Submap::scans). An empty submap gives an
  /// empty result; a non-empty submap without scan origins is an error (no free space known).
  StatusOr<DynamicDetectionResult> Detect(const Submap& history, const Submap& current,
                                          const Pose3& T_current_history) const;
  /// The same with a prebuilt index over `current.points` (in the current frame), which every
  /// pair of the same current submap can share; an index of another size is an error.
  /// `time_s` then leaves out the index's construction.
  StatusOr<DynamicDetectionResult> Detect(const Submap& history, const Submap& current,
                                          const Pose3& T_current_history,
                                          const PointIndex& current_index) const;
  /// The same with prebuilt indices over both submaps, each over its submap's points in the
  /// submap's own frame (`history_index` over history.points untransformed), so that every
  /// pair of either submap can share its index; an index of another size is an error.
  /// `time_s` then leaves out the construction of both.
  StatusOr<DynamicDetectionResult> Detect(const Submap& history, const Submap& current,
                                          const Pose3& T_current_history,
                                          const PointIndex& history_index,
                                          const PointIndex& current_index) const;
  /// The same with the indices of history item `h` and current item `k` of two pools (one
  /// use of each); `time_s` and `stage.index_s` include this pair's shares of their
  /// construction (how the merge and the benchmark charge shared indices).
  StatusOr<DynamicDetectionResult> Detect(const Submap& history, const Submap& current,
                                          const Pose3& T_current_history,
                                          PointIndexPool* history_indices, std::size_t h,
                                          PointIndexPool* current_indices, std::size_t k) const;

  const DynamicDetectionConfig& config() const { return config_; }

 private:
  explicit DynamicDetector(const DynamicDetectionConfig& config) : config_(config) {}
  DynamicDetectionConfig config_;
};

}  // namespace core
}  // namespace multisession_mapper
