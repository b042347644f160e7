#include "multisession_mapper/core/session_mapper.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <future>
#include <utility>

#include "multisession_mapper/core/se3.h"
#include "multisession_mapper/core/stopwatch.h"

namespace multisession_mapper {
namespace core {

Status IntraLoopConfig::Validate() const {
  if (!(search_radius_m > 0.0)) return Status::Error("intra_loops.search_radius_m must be > 0");
  if (min_id_gap < 1) return Status::Error("intra_loops.min_id_gap must be >= 1");
  if (max_candidates < 1) return Status::Error("intra_loops.max_candidates must be >= 1");
  if (!(global_max_correction_m > 0.0) || !(global_max_correction_rad > 0.0)) {
    return Status::Error("intra_loops.global_max_correction_m/_rad must be > 0");
  }
  Status s = global.Validate();
  return s.ok() ? registration.Validate() : s;
}

Status SessionMapperConfig::Validate() const {
  for (const Status& s : {odometry.Validate(), submaps.Validate(), intra_loops.Validate(),
                          pose_graph.Validate(), vertical_structure.Validate(),
                          frame_anchor.Validate(), intra_pairs.Validate()}) {
    if (!s.ok()) return s;
  }
  if (!(odometry_sigma_translation_m > 0.0) || !(odometry_sigma_translation_per_m >= 0.0) ||
      !(odometry_sigma_rotation_rad > 0.0)) {
    return Status::Error("odometry edge sigmas must be > 0");
  }
  return Status::Ok();
}

struct SessionMapper::State {
  SessionMapperConfig config;
  std::string session;
  Odometry odometry;
  SubmapBuilder builder;
  SubmapRegistration registration;
  PoseGraph graph;
  std::vector<Submap, Eigen::aligned_allocator<Submap>> submaps;  // finished, by id
  std::vector<Pose3, Eigen::aligned_allocator<Pose3>> odom_origins;  // by id
  std::map<std::uint32_t, SubmapTarget> targets;  // registration targets, built on demand
  LoopRecords loops;
  SessionTimings timings;
  bool has_last = false;
  OdometryResult last;
  std::size_t processed = 0;
  std::size_t skipped = 0;
  // Split path (AddRegisteredScan): the odometry ran outside; its poses are kept here.
  bool split = false;
  Trajectory split_odometry;
  // The first mapped scan (sensor frame) and its submap, for the frame anchor.
  PointVector first_scan;  // the first frame_anchor.scans scans, in the first one's frame
  Pose3 first_scan_odometry = Pose3::Identity();
  std::uint32_t first_submap = 0;
  // The pair detection between neighbouring submaps, fed as they finish (null: disabled).
  std::unique_ptr<IntraSessionPairDetector> pairs;
  // The vertical evidence of finished submaps (EstimateVerticalEvidence: ~100 ms of kNN
  // normals per `campus` submap), estimated on a thread of its own while the next scans are
  // mapped, because this thread (submap building) is the critical path of a whole run. Each
  // prior reaches the graph before its next solve, which reads the priors whole (a map by
  // submap id): the same solves as with every prior set as its submap finished.
  std::vector<std::pair<std::uint32_t, std::future<VerticalEvidence>>> pending_vertical;

  State(const SessionMapperConfig& c, const std::string& s, Odometry o, SubmapBuilder b,
        SubmapRegistration r)
      : config(c), session(s), odometry(std::move(o)), builder(std::move(b)),
        registration(std::move(r)), graph(c.pose_graph) {}

  // Current estimate of an odometry-frame pose, through the correction of the latest
  // optimised submap (later submaps follow the optimised ones rigidly).
  Pose3 CorrectedOrigin(std::uint32_t id) const {
    if (graph.HasNode(id)) return graph.NodePose(id);
    if (submaps.empty()) return odom_origins[id];
    const std::uint32_t last_id = submaps.back().id;
    const Pose3 correction = graph.NodePose(last_id) * odom_origins[last_id].inverse();
    return correction * odom_origins[id];
  }

  const SubmapTarget* Target(std::uint32_t id) {
    auto it = targets.find(id);
    if (it != targets.end()) return &it->second;
    StatusOr<SubmapTarget> target = SubmapTarget::Create(submaps[id].points, config.intra_loops.registration);
    if (!target.ok()) return nullptr;
    return &targets.emplace(id, std::move(target.value())).first->second;
  }

  void AddFinishedSubmap(Submap submap) {
    ApplyVerticalPriors(false);
    const std::uint32_t id = submap.id;
    odom_origins.push_back(submap.T_map_submap);
    const Pose3 estimate = submaps.empty() ? submap.T_map_submap : CorrectedOrigin(id);
    graph.SetNodePose(id, estimate);
    if (id == 0) graph.SetFixed(0, true);
    if (id > 0) {
      PoseGraphEdge edge;
      edge.from = id - 1;
      edge.to = id;
      edge.T_from_to = se3::Between(odom_origins[id - 1], odom_origins[id]);
      // A submap started at a jump of the odometry (SubmapBuilderConfig::break_on_jump_m) is
      // linked to the previous one across that jump: the link is as uncertain as the jump is
      // large, so that loops on both sides of it can move the two apart or together.
      const double sigma_odometry =
          config.odometry_sigma_translation_m +
          config.odometry_sigma_translation_per_m * submaps.back().length_m;
      const double sigma_t = std::hypot(sigma_odometry, submap.started_at_jump_m);
      edge.information.setZero();
      edge.information.diagonal() << Eigen::Vector3d::Constant(1.0 / (sigma_t * sigma_t)),
          Eigen::Vector3d::Constant(1.0 / (config.odometry_sigma_rotation_rad *
                                           config.odometry_sigma_rotation_rad));
      graph.AddEdge(edge);
    }
    if (pairs) pairs->Add(submap, odom_origins[id]);
    if (config.vertical_structure.enabled) {
      pending_vertical.emplace_back(
          id, std::async(std::launch::async,
                         [points = submap.points, vertical = config.vertical_structure] {
                           return EstimateVerticalEvidence(points, vertical);
                         }));
    }
    submap.T_map_submap = estimate;
    submaps.push_back(std::move(submap));
    SearchIntraLoops(id);
  }

  void SearchIntraLoops(std::uint32_t id) {
    if (!config.intra_loops.enabled) return;
    const auto start = std::chrono::steady_clock::now();
    const Pose3 current = graph.NodePose(id);
    std::vector<std::pair<double, std::uint32_t>> candidates;
    for (const Submap& other : submaps) {
      if (static_cast<int>(id) - static_cast<int>(other.id) < config.intra_loops.min_id_gap) continue;
      const double distance =
          (graph.NodePose(other.id).translation() - current.translation()).norm();
      if (distance < config.intra_loops.search_radius_m) candidates.emplace_back(distance, other.id);
    }
    std::sort(candidates.begin(), candidates.end());
    if (static_cast<int>(candidates.size()) > config.intra_loops.max_candidates) {
      candidates.resize(config.intra_loops.max_candidates);
    }
    bool accepted_any = false;
    for (const auto& [distance, other] : candidates) {
      LoopRecord record;
      record.kind = LoopKind::kIntra;
      record.current_session = session;
      record.current_submap = id;
      record.history_session = session;
      record.history_submap = other;
      const SubmapTarget* target = Target(other);
      if (target == nullptr) {
        record.status = LoopStatus::kRejected;
        record.reason = "history submap has no points";
        loops.push_back(record);
        continue;
      }
      const Pose3 prior = se3::Between(graph.NodePose(other), current);
      const SubmapRegistrationResult result =
          registration.Register(submaps[id].points, *target, prior);
      record.overlap_ratio = result.overlap_ratio;
      record.has_pose = true;
      record.T_history_current = result.T_target_source;
      record.status = result.accepted ? LoopStatus::kAccepted : LoopStatus::kRejected;
      record.reason = result.reason;
      Information6 information = result.information;
      if (!result.accepted && config.intra_loops.global_fallback) {
        RegisterWithoutPrior(id, other, prior, &record, &information);
      }
      loops.push_back(record);
      if (record.status != LoopStatus::kAccepted) continue;
      PoseGraphEdge edge;
      edge.from = other;
      edge.to = id;
      edge.T_from_to = record.T_history_current;
      edge.information = information;
      edge.kind = EdgeKind::kIntraLoop;
      accepted_any = graph.AddEdge(edge).ok() || accepted_any;
    }
    timings.intra_loop_s.push_back(SecondsSince(start));
    if (accepted_any) Optimise();
  }

  // The fallback of a failed loop registration: global registration of the pair, accepted
  // only near the prior (a drifted revisit, not some look-alike place elsewhere).
  void RegisterWithoutPrior(std::uint32_t id, std::uint32_t other, const Pose3& prior,
                            LoopRecord* record, Information6* information) const {
    StatusOr<GlobalRegistration> global = GlobalRegistration::Create(config.intra_loops.global);
    if (!global.ok()) return;
    const GlobalRegistrationResult g =
        global.value().Register(submaps[id].points, submaps[other].points);
    if (!g.accepted) {
      record->reason += "; without prior: " + g.reason;
      return;
    }
    const Pose3 correction = se3::Between(prior, g.T_target_source);
    const double dt = se3::TranslationNorm(correction), dr = se3::RotationAngleRad(correction);
    if (dt > config.intra_loops.global_max_correction_m ||
        dr > config.intra_loops.global_max_correction_rad) {
      record->reason += "; without prior: too far from the prior (" + std::to_string(dt) +
                        " m, " + std::to_string(dr) + " rad)";
      return;
    }
    record->status = LoopStatus::kAccepted;
    record->reason.clear();
    record->overlap_ratio = g.overlap_ratio;
    record->structure_overlap_ratio = g.structure_overlap_ratio;
    record->T_history_current = g.T_target_source;
    *information = g.information;
  }

  // The pending vertical priors that are ready (all of them with `wait`). Applied as they
  // come, so that no finished estimate holds its copy of the submap's points (a future's
  // state keeps its task) until the next solve.
  void ApplyVerticalPriors(bool wait) {
    std::size_t kept = 0;
    for (auto& [id, estimate] : pending_vertical) {
      if (!wait && estimate.wait_for(std::chrono::seconds(0)) != std::future_status::ready) {
        pending_vertical[kept++] = {id, std::move(estimate)};
        continue;
      }
      const VerticalEvidence vertical = estimate.get();
      if (vertical.valid) graph.SetVerticalPrior(id, vertical.information);
    }
    pending_vertical.resize(kept);
  }

  void Optimise() {
    ApplyVerticalPriors(true);
    const auto start = std::chrono::steady_clock::now();
    StatusOr<PoseGraphSummary> summary = graph.Optimize();
    timings.optimisation_s.push_back(SecondsSince(start));
    if (!summary.ok()) return;
    // Loops the graph switched off as outliers are rejected after all.
    for (std::size_t index : summary.value().rejected_edges) {
      const PoseGraphEdge& edge = graph.edges()[index];
      for (LoopRecord& record : loops) {
        if (record.status == LoopStatus::kAccepted && record.kind == LoopKind::kIntra &&
            record.history_submap == edge.from && record.current_submap == edge.to) {
          record.status = LoopStatus::kRejected;
          record.reason = "rejected by the pose graph (inconsistent with the other edges)";
        }
      }
    }
  }

  void DrainBuilder() {
    for (Submap& submap : builder.TakeFinished()) AddFinishedSubmap(std::move(submap));
  }

  // A new pair detector for the intra_pairs settings. Mid-session the submaps finished so far
  // are added again and every pair of the session is left for Finish (no copies of the whole
  // session at once, and the settings of a live change apply to all its pairs).
  Status ResetPairs() {
    if (!config.intra_pairs.enabled) {
      pairs.reset();
      return Status::Ok();
    }
    IntraSessionPairsConfig c = config.intra_pairs;
    if (!submaps.empty()) c.during_session = false;
    StatusOr<std::unique_ptr<IntraSessionPairDetector>> created =
        IntraSessionPairDetector::Create(c);
    if (!created.ok()) return created.status();  // the old detector stays
    pairs = std::move(created.value());
    for (const Submap& submap : submaps) pairs->Add(submap, odom_origins[submap.id]);
    return Status::Ok();
  }

  // Everything after the odometry, shared by AddScan and AddRegisteredScan. A scan whose ICP
  // failed after the first one (a jump of the sensor pose, a long gap, a scan that does not
  // match its surroundings) has only a predicted pose: it is skipped, not put into a submap at
  // a pose that may be wrong.
  Status AddOdometryResult(OdometryResult result) {
    if (has_last && !result.registered) {
      ++skipped;
      return Status::Error("scan-to-map registration failed (" +
                           (result.message.empty() ? std::string("no convergence")
                                                   : result.message) +
                           "); its pose is only predicted, so it is not mapped (a jump of the "
                           "sensor or a long gap?)");
    }
    if (config.frame_anchor.enabled &&
        processed < static_cast<std::size_t>(config.frame_anchor.scans)) {
      // The first scans, in the first scan's frame by their odometry (drift is negligible
      // over a second or two): one denser cloud for the anchor's registration.
      if (processed == 0) first_scan_odometry = result.pose;
      const Pose3 T_first_scan = first_scan_odometry.inverse() * result.pose;
      for (const LidarPoint& p : result.deskewed_scan.points) {
        first_scan.push_back(T_first_scan * p.position_m.cast<double>());
      }
    }
    ++processed;
    timings.odometry_ms.push_back(result.timing.total_ms);
    timings.odometry_filter_ms.push_back(result.timing.filter_ms);
    timings.odometry_deskew_ms.push_back(result.timing.deskew_ms);
    timings.odometry_downsample_ms.push_back(result.timing.downsample_ms);
    timings.odometry_registration_ms.push_back(result.timing.registration_ms);
    timings.odometry_map_ground_ms.push_back(result.timing.map_ground_ms);
    timings.odometry_map_update_ms.push_back(result.timing.map_update_ms);
    timings.odometry_registrations.push_back(result.registrations);
    timings.odometry_icp_iterations.push_back(result.icp_iterations);
    timings.odometry_icp_searches.push_back(result.icp_searches);
    const auto start = std::chrono::steady_clock::now();
    // How far the odometry moved the scan from its prediction (a jump, see break_on_jump_m).
    const double jump_m = result.registered && processed > 1
                              ? se3::TranslationNorm(se3::Between(result.prediction, result.pose))
                              : 0.0;
    builder.AddScan(result.deskewed_scan, result.pose, jump_m);
    if (processed == 1) first_submap = builder.current_submap_id();
    timings.submap_building_ms.push_back(SecondsSince(start) * 1e3);
    last = std::move(result);
    has_last = true;
    DrainBuilder();
    return Status::Ok();
  }
};

SessionMapper::SessionMapper(std::unique_ptr<State> state) : state_(std::move(state)) {}
SessionMapper::SessionMapper(SessionMapper&&) noexcept = default;
SessionMapper& SessionMapper::operator=(SessionMapper&&) noexcept = default;
SessionMapper::~SessionMapper() = default;

StatusOr<SessionMapper> SessionMapper::Create(const SessionMapperConfig& config,
                                              const std::string& session) {
  Status s = config.Validate();
  if (!s.ok()) return s;
  StatusOr<Odometry> odometry = Odometry::Create(config.odometry);
  if (!odometry.ok()) return odometry.status();
  StatusOr<SubmapBuilder> builder = SubmapBuilder::Create(config.submaps, session);
  if (!builder.ok()) return builder.status();
  StatusOr<SubmapRegistration> registration =
      SubmapRegistration::Create(config.intra_loops.registration);
  if (!registration.ok()) return registration.status();
  auto state = std::make_unique<State>(config, session, std::move(odometry.value()),
                                       std::move(builder.value()),
                                       std::move(registration.value()));
  Status pairs = state->ResetPairs();
  if (!pairs.ok()) return pairs;
  return SessionMapper(std::move(state));
}

Status SessionMapper::AddScan(const LidarScan& raw_scan) {
  State& st = *state_;
  StatusOr<OdometryResult> result = st.odometry.ProcessScan(raw_scan);
  if (!result.ok()) {
    ++st.skipped;
    return result.status();
  }
  return st.AddOdometryResult(std::move(result.value()));
}

void SessionMapper::CountSkippedScan() { ++state_->skipped; }

Status SessionMapper::AddRegisteredScan(const OdometryResult& registered) {
  State& st = *state_;
  if (!st.split_odometry.empty() && !(registered.stamp_s > st.split_odometry.back().stamp_s)) {
    ++st.skipped;
    return Status::Error("scan stamp does not increase; scan skipped");
  }
  if (registered.deskewed_scan.points.empty()) {
    ++st.skipped;
    return Status::Error("registered scan has no point; scan skipped");
  }
  st.split = true;
  StampedPose sp;
  sp.stamp_s = registered.stamp_s;
  sp.pose = registered.pose;
  st.split_odometry.push_back(sp);
  return st.AddOdometryResult(registered);
}

Status SessionMapper::UpdateConfig(const SessionMapperConfig& config) {
  State& st = *state_;
  Status s = config.Validate();
  if (!s.ok()) return s;
  StatusOr<SubmapRegistration> registration =
      SubmapRegistration::Create(config.intra_loops.registration);
  if (!registration.ok()) return registration.status();
  const OdometryConfig odometry = st.config.odometry;
  st.config = config;
  st.config.odometry = odometry;  // AddScan's odometry keeps its creation config
  st.builder.set_config(config.submaps);
  st.graph.set_config(config.pose_graph);
  st.registration = std::move(registration.value());
  st.targets.clear();  // built with the old registration config
  // The pairs restart with the new settings (this session's from its end, see ResetPairs).
  return st.ResetPairs();
}

const SessionMapperConfig& SessionMapper::config() const { return state_->config; }

Pose3 SessionMapper::SubmapOrigin(std::uint32_t id) const { return state_->graph.NodePose(id); }

const Submap& SessionMapper::finished_submap(std::uint32_t id) const {
  return state_->submaps[id];
}

Pose3 SessionMapper::SessionFromOdometry() const {
  const State& st = *state_;
  if (st.submaps.empty()) return Pose3::Identity();
  const std::uint32_t last_id = st.submaps.back().id;
  return st.graph.NodePose(last_id) * st.odom_origins[last_id].inverse();
}

const LoopRecords& SessionMapper::loops() const { return state_->loops; }

std::size_t SessionMapper::num_optimisations() const {
  return state_->timings.optimisation_s.size();
}

const OdometryResult* SessionMapper::last_odometry() const {
  return state_->has_last ? &state_->last : nullptr;
}

std::uint32_t SessionMapper::current_submap_id() const {
  return state_->builder.current_submap_id();
}

std::size_t SessionMapper::num_finished_submaps() const { return state_->submaps.size(); }

StatusOr<SessionResult> SessionMapper::Finish() {
  State& st = *state_;
  st.builder.FinishSession();
  st.DrainBuilder();
  if (st.submaps.empty()) {
    return Status::Error("session '" + st.session + "' produced no submap (no usable scan)");
  }
  st.Optimise();
  SessionResult result;
  result.session = st.session;
  for (Submap& submap : st.submaps) submap.T_map_submap = st.graph.NodePose(submap.id);
  if (st.config.frame_anchor.enabled && !st.first_scan.empty()) {
    // Applied by SessionMerger to the first session of a map only.
    result.anchor = EstimateFirstScanPose(st.first_scan, st.submaps, st.first_submap,
                                          st.config.frame_anchor);
  }
  if (st.pairs) {
    StatusOr<IntraSessionPairsStats> pairs = st.pairs->Finish(&st.submaps);
    st.pairs.reset();
    if (!pairs.ok()) return pairs.status();
    st.timings.intra_pair_detection_s = pairs.value().pair_s;
    result.intra_pairs = pairs.value();
  }
  result.trajectory = ScanTrajectory(st.submaps);
  result.submaps = std::move(st.submaps);
  result.graph = st.graph;
  result.odometry = st.split ? st.split_odometry : st.odometry.trajectory();
  result.loops = st.loops;
  result.timings = st.timings;
  result.scans_processed = st.processed;
  result.scans_skipped = st.skipped;
  st.submaps.clear();
  st.targets.clear();
  return result;
}

}  // namespace core
}  // namespace multisession_mapper
