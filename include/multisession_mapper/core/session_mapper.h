// Single-session SLAM in submaps (reference paper, section IV): per scan, odometry and the
// submap builder; per finished submap, an odometry edge, intra-session loop candidates by
// origin distance (registered from the prior, validated by agreement and overlap) and, when a
// loop is accepted, a pose graph optimisation. The offline runner and the nodelets both drive
// this object; it owns no I/O.
#pragma once

#include <map>
#include <memory>
#include <string>
#include <vector>

#include "multisession_mapper/core/frame_anchor.h"
#include "multisession_mapper/core/global_registration.h"
#include "multisession_mapper/core/intra_session_pairs.h"
#include "multisession_mapper/core/loop_record.h"
#include "multisession_mapper/core/odometry.h"
#include "multisession_mapper/core/pose_graph.h"
#include "multisession_mapper/core/status.h"
#include "multisession_mapper/core/submap.h"
#include "multisession_mapper/core/submap_builder.h"
#include "multisession_mapper/core/submap_registration.h"
#include "multisession_mapper/core/vertical_structure.h"

namespace multisession_mapper {
namespace core {

struct IntraLoopConfig {
  bool enabled = true;
  /// Earlier submaps whose origin is within this distance of the new one are candidates [m].
  double search_radius_m = 15.0;
  /// Submaps closer in id than this are neighbours (already linked by odometry), not loops.
  int min_id_gap = 3;
  /// At most this many candidates (nearest first) per new submap.
  int max_candidates = 3;
  SubmapRegistrationConfig registration;
  /// When ICP from the prior fails (the drift around a long loop exceeds its reach), register
  /// the pair again without a prior (GlobalRegistration) and accept the result when it moves
  /// the prior by at most these [m], [rad] (a drifted loop, not an aliased place elsewhere).
  bool global_fallback = true;
  double global_max_correction_m = 15.0;
  double global_max_correction_rad = 0.35;
  GlobalRegistrationConfig global;

  Status Validate() const;
};

struct SessionMapperConfig {
  OdometryConfig odometry;
  SubmapBuilderConfig submaps;
  IntraLoopConfig intra_loops;
  /// Pair detection between neighbouring submaps once the session is optimised
  /// (intra_session_pairs.h).
  IntraSessionPairsConfig intra_pairs;
  PoseGraphConfig pose_graph;
  /// Vertical prior of every finished submap from its walls (vertical_structure.h).
  VerticalStructureConfig vertical_structure;
  /// After the last optimisation, the first scans are registered against the other submaps
  /// (frame_anchor.h); the merger re-anchors the first session of a map with the result.
  FrameAnchorConfig frame_anchor;
  /// Odometry edge noise between consecutive submaps: sigma_t = base + per_m * distance [m],
  /// sigma_r [rad].
  double odometry_sigma_translation_m = 0.05;
  double odometry_sigma_translation_per_m = 0.005;
  double odometry_sigma_rotation_rad = 0.005;

  Status Validate() const;
};

/// Per-stage timing samples, for the timing records of the map (medians are computed there).
struct SessionTimings {
  std::vector<double> odometry_ms;        ///< per scan: filter + de-skew + ICP + map update
  /// Per scan, the odometry's stages (their sum is about odometry_ms).
  std::vector<double> odometry_filter_ms;
  std::vector<double> odometry_deskew_ms;
  std::vector<double> odometry_downsample_ms;  ///< downsampling and the scan's normals
  std::vector<double> odometry_registration_ms;
  std::vector<double> odometry_map_ground_ms;
  std::vector<double> odometry_map_update_ms;
  /// Per scan, the odometry's ICP work: runs, summed iterations, summed correspondence
  /// searches (OdometryResult::registrations and its neighbours).
  std::vector<double> odometry_registrations;
  std::vector<double> odometry_icp_iterations;
  std::vector<double> odometry_icp_searches;
  std::vector<double> submap_building_ms;  ///< per scan
  std::vector<double> intra_loop_s;       ///< per finished submap: candidate registrations
  std::vector<double> optimisation_s;     ///< per pose graph solve
  std::vector<double> descriptor_ms;      ///< per scan, filled by the place recognizer
  std::vector<double> query_ms;           ///< per scan with a history database
  std::vector<double> global_registration_s;  ///< per inter-session candidate pair (merge)
  /// Per inter-session candidate pair registered from a neighbouring loop's pose (merge).
  std::vector<double> guided_registration_s;
  std::vector<double> dynamic_detection_s;    ///< per overlapping submap pair (merge)
  std::vector<double> intra_pair_detection_s;  ///< per neighbouring submap pair (Finish)
};

struct SessionResult {
  std::string session;
  /// Submaps with origins in the session frame (the sensor frame of the first scan),
  /// optimised.
  std::vector<Submap, Eigen::aligned_allocator<Submap>> submaps;
  PoseGraph graph;          ///< node id = submap id
  Trajectory trajectory;    ///< optimised sensor pose of every scan, session frame
  Trajectory odometry;      ///< raw odometry of every scan
  LoopRecords loops;        ///< intra-session candidates and their fate
  FrameAnchorResult anchor;  ///< the first scans' registration (frame_anchor.h)
  IntraSessionPairsStats intra_pairs;  ///< the pair detection between its submaps (if enabled)
  SessionTimings timings;
  std::size_t scans_processed = 0;
  std::size_t scans_skipped = 0;
};

class SessionMapper {
 public:
  static StatusOr<SessionMapper> Create(const SessionMapperConfig& config,
                                        const std::string& session);
  SessionMapper(SessionMapper&&) noexcept;
  SessionMapper& operator=(SessionMapper&&) noexcept;
  ~SessionMapper();

  /// Processes one raw scan. An error means the scan was skipped (the message says why: a
  /// stamp that does not increase, no valid point); the session goes on.
  Status AddScan(const LidarScan& raw_scan);

  /// Last odometry result (pose, de-skewed scan) for publishing; null before the first scan.
  const OdometryResult* last_odometry() const;
  /// Id of the submap the last scan went into.
  std::uint32_t current_submap_id() const;
  /// Submaps finished so far (optimised origins).
  std::size_t num_finished_submaps() const;

  /// Closes the open submaps, runs their loop search and the final optimisation.
  StatusOr<SessionResult> Finish();

  // --- Split path for the nodelets (issue 8): odometry runs elsewhere (ScanMatchingNodelet);
  // --- this object builds the submaps, loops and pose graph from the registered scans.

  /// Processes a scan that an Odometry outside this object has already registered (its
  /// de-skewed scan and pose T_odom_sensor). Equivalent to the part of AddScan after the
  /// odometry: the same submaps, loops and graph result from the same OdometryResults. Fails
  /// (and changes nothing) when the stamp does not increase. Do not mix with AddScan in one
  /// session.
  Status AddRegisteredScan(const OdometryResult& registered);
  /// Counts a scan that the outside odometry refused (its ProcessScan error) as skipped, as
  /// AddScan does for its own odometry.
  void CountSkippedScan();

  /// Applies `config` from the next scan / finished submap on (live tuning). Everything but
  /// `odometry` applies (submap builder, in-session dynamics, intra-session loops, pose graph,
  /// odometry edge sigmas); the odometry of AddScan keeps its creation config (the nodelets
  /// run their own Odometry). The pair detection between neighbouring submaps restarts with
  /// the new settings, and every pair of this session is then detected at Finish, not during
  /// the session (IntraSessionPairsConfig::during_session). Refuses an invalid config
  /// and keeps the old one.
  Status UpdateConfig(const SessionMapperConfig& config);
  const SessionMapperConfig& config() const;

  /// Current (optimised) origin of finished submap `id`, T_session_submap.
  Pose3 SubmapOrigin(std::uint32_t id) const;
  /// Finished submap `id` (points and scan poses in its own frame; its T_map_submap is the
  /// estimate when it finished: use SubmapOrigin for the current one). id < num_finished_submaps().
  const Submap& finished_submap(std::uint32_t id) const;
  /// T_session_odom: moves odometry-frame poses onto the optimised graph (identity before the
  /// first finished submap); the map -> odom transform of REP-105.
  Pose3 SessionFromOdometry() const;
  /// Intra-session loop records so far.
  const LoopRecords& loops() const;
  /// Pose graph solves so far (changes when submap origins moved).
  std::size_t num_optimisations() const;

 private:
  struct State;
  explicit SessionMapper(std::unique_ptr<State> state);
  std::unique_ptr<State> state_;
};

}  // namespace core
}  // namespace multisession_mapper
