// Merges a mapped session into the stored map (reference paper, section VI; issue 7). The
// first session defines the map frame (AddFirstSession). Every later session:
//  1. inter-session loops without initial guess (InterSessionMatcher);
//  2. joint pose graph: history submaps and the new session's submaps, intra-session edges,
//     the inter-session loops (robust kernel); only the map's first submap is fixed. Loops the
//     matcher rejected only for disagreeing with the neighbour's loop that placed them
//     (DependentLoop) are judged again when the graph rejected that loop: accepted when they
//     agree with the optimised graph within the sequence-consistency bounds, then optimised
//     again (dependent_loops.h);
//  3. a second, proximity-based loop search of every new submap against the history now that
//     both share a frame, then a second optimisation;
//  4. low-dynamic detection for every overlapping pair (DynamicDetector);
//  5. map update: dynamic points leave the history submaps, hidden static points of the new
//     session mend them, new submaps that overlap a history submap are fused into it (the map
//     of a place visited every day keeps its size), new submaps in unvisited places are added;
//     the descriptor database and the change log follow.
// A session that cannot be aligned (no consistent inter-session loop) is not merged: Merge()
// returns an error and the map is left unchanged.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "multisession_mapper/core/dynamic_detection.h"
#include "multisession_mapper/core/inter_session_matcher.h"
#include "multisession_mapper/core/map_store.h"
#include "multisession_mapper/core/map_update.h"
#include "multisession_mapper/core/new_object_hold.h"
#include "multisession_mapper/core/place_recognizer.h"
#include "multisession_mapper/core/pose_graph.h"
#include "multisession_mapper/core/session_mapper.h"
#include "multisession_mapper/core/status.h"
#include "multisession_mapper/core/submap_registration.h"

namespace multisession_mapper {
namespace core {

struct ProximityLoopConfig {
  bool enabled = true;
  /// History submaps whose origins are within this distance of a new submap (after the first
  /// joint optimisation) are registered against it [m].
  double search_radius_m = 12.0;
  /// At most this many history candidates (nearest first) per new submap.
  int max_candidates = 3;
  SubmapRegistrationConfig registration;

  Status Validate() const;
};

struct MapFusionConfig {
  /// A new submap is fused into history submaps (not kept as a submap of its own) when at least
  /// this fraction of its points lie within `overlap_distance_m` of the history map.
  double min_overlap_ratio = 0.6;
  double overlap_distance_m = 0.3;
  /// Voxel of the fused submaps [m]: a point of a fused submap joins the history only where
  /// the history has no point in its voxel or the 26 around it (new structure, not a re-sample
  /// of known surfaces), and at most one point per voxel is added (also for mended points).
  double voxel_m = 0.2;
  /// A finer voxel [m] for the fused points no movable object can be part of: at least
  /// fine_above_m above the local ground, or at most fine_below_m above it with nothing
  /// standing (a point between the two heights) in its ground cell or the 8 around
  /// (HeightsAboveLocalGround and NearStandingPoints of the new submap's points, cells of
  /// hold.ground_cell_m; the standing test because a car's tyres reach down to the ground).
  /// Far from the sensor, terrain and canopies are sampled sparsely, and the next session's
  /// samples fall between the history's; with the 0.2 m voxel the gaps stayed open (up to
  /// 0.4 m) and their surfaces lost points. Parked cars keep voxel_m: a finer voxel would
  /// also densify the cars the map still keeps. Session 48, 3-session seeds 1 / 3: static SA
  /// 98.43 -> 98.77 / 98.91 -> 99.24 %, low-dynamic DA 52.83 -> 51.07 / 50.16 -> 49.09 %
  /// (without the standing test: 98.82 / 99.31 % and 50.07 / 47.97 %).
  /// 0 (or >= voxel_m): voxel_m everywhere; else at least 0.02 m.
  double fine_voxel_m = 0.1;
  double fine_below_m = 0.25;  ///< [m] above the local ground
  double fine_above_m = 3.5;   ///< [m] above the local ground, >= fine_below_m
  /// A pair whose detection marks more than this fraction of either submap as dynamic is
  /// treated as misaligned and left unchanged (removing that much would damage the map).
  double max_dynamic_fraction = 0.25;
  /// Copies of the dynamic points elsewhere in the map [m] (0: off): the pairs examine only
  /// points near the other session's scan origins, while a parked car is also held, sparsely,
  /// by the submaps that saw it from farther away (up to 60 m) and by submaps the loops did
  /// not pair. After the detections, every point of an active history submap or of a new
  /// submap within this distance of a dynamic point (in the map frame) is dynamic as well.
  double propagate_radius_m = 0.2;
  /// Records kept per session: the point records of a merge (dynamics/<session>_removed.pcd
  /// and _mended.pcd, about 1 MB per `small` session) and its place-recognition log
  /// (place_recognition/<session>.csv) are kept for the last this many merged sessions and
  /// dropped from the map directory after that, so that a map merged every day keeps a
  /// bounded size; every session keeps its change log (changes/<session>.yaml, with the
  /// counts), loops and trajectories (0: keep every record).
  int record_sessions = 3;
  /// New objects of the new session (above-ground groups of movable shape, alone, where the
  /// history saw the ground or removed an object) are not added to the history, and leave the
  /// paired new submaps that are kept as submaps (new_object_hold.h).
  NewObjectHoldConfig hold;

  Status Validate() const;
};

struct SessionMergerConfig {
  InterSessionMatcherConfig matching;
  ProximityLoopConfig proximity;
  DynamicDetectionConfig dynamics;
  MapFusionConfig fusion;
  /// Inter-session loop edge noise [m], [rad].
  double inter_sigma_translation_m = 0.1;
  double inter_sigma_rotation_rad = 0.01;
  /// Threads for the independent registrations and detections of a merge.
  int num_threads = 2;

  Status Validate() const;
};

/// Dynamic points removed from one history submap, and points added to it by mending.
struct SubmapChange {
  std::string session;  ///< history submap's session
  std::uint32_t submap_id = 0;
  PointVector removed_m;  ///< map frame [m]
  PointVector mended_m;   ///< map frame [m]
};

struct MergeReport {
  std::string session;
  bool first_session = false;
  std::size_t inter_loops = 0;      ///< accepted by place recognition + global registration
  std::size_t sequence_loops = 0;   ///< accepted by sequence guidance
  std::size_t proximity_loops = 0;  ///< accepted by the second search
  /// Of inter_loops and sequence_loops: accepted only when judged again against the joint
  /// graph, after it rejected the loop they had disagreed with (DependentLoop).
  std::size_t rejudged_loops = 0;
  std::size_t submaps_added = 0;    ///< new submaps kept as submaps
  std::size_t submaps_fused = 0;    ///< new submaps fused into history submaps
  std::size_t points_removed = 0;
  /// Of the removed and left-out points, those found as copies of dynamic points in other
  /// submaps (MapFusionConfig::propagate_radius_m).
  std::size_t points_propagated = 0;
  std::size_t points_mended = 0;
  std::size_t points_fused = 0;     ///< static points of fused submaps new to the history
  /// Points of new objects not added to the history (MapFusionConfig::hold), and their groups.
  std::size_t points_held_back = 0;
  std::size_t objects_held_back = 0;
  PointVector held_m;  ///< those points, map frame [m]
  std::vector<SubmapChange> changes;
  LoopRecords loops;                 ///< inter and proximity records (loops/<session>.csv)
  InterSessionMatchResult matching;  ///< votes and candidates
  std::vector<double> dynamic_pair_s;  ///< time per detected pair [s]
  double matching_s = 0.0;
  double optimisation_s = 0.0;
  double update_s = 0.0;
  /// Parts of update_s [s]: dynamic detection of all pairs (wall time, in parallel), removal
  /// / mending / fusion, descriptor database, and the rest (change records, trajectories).
  double update_dynamics_s = 0.0;
  double update_fusion_s = 0.0;
  double update_database_s = 0.0;
  double total_s = 0.0;
};

class SessionMerger {
 public:
  static StatusOr<SessionMerger> Create(const SessionMergerConfig& config);

  /// Adds `session` to `map` (first session, or merge as above). On error `map` is unchanged.
  StatusOr<MergeReport> Merge(const SessionResult& session, const SessionRecord& record,
                              const PlaceRecognizer& recognizer, const SessionFiles& files,
                              MapContents* map) const;

  const SessionMergerConfig& config() const { return config_; }

 private:
  explicit SessionMerger(const SessionMergerConfig& config) : config_(config) {}
  SessionMergerConfig config_;
};

}  // namespace core
}  // namespace multisession_mapper
