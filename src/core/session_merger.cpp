#include "multisession_mapper/core/session_merger.h"

#include <algorithm>
#include <limits>
#include <chrono>
#include <cmath>
#include <map>
#include <set>
#include <sstream>
#include <utility>

#include <yaml-cpp/yaml.h>

#include "multisession_mapper/core/dependent_loops.h"
#include "multisession_mapper/core/dynamic_propagation.h"
#include "multisession_mapper/core/local_ground.h"
#include "multisession_mapper/core/parallel_for.h"
#include "multisession_mapper/core/point_index.h"
#include "multisession_mapper/core/point_index_pool.h"
#include "multisession_mapper/core/stopwatch.h"
#include "multisession_mapper/core/voxel_occupancy.h"

namespace multisession_mapper {
namespace core {
namespace {

constexpr char kDatabaseFile[] = "database/descriptors.bin";

bool Finite(double v) { return std::isfinite(v); }

Information6 DiagonalInformation(double sigma_t, double sigma_r) {
  Information6 info = Information6::Zero();
  for (int i = 0; i < 3; ++i) {
    info(i, i) = 1.0 / (sigma_t * sigma_t);
    info(i + 3, i + 3) = 1.0 / (sigma_r * sigma_r);
  }
  return info;
}

// Copies a descriptor database (move-only, holds a kd-tree) through its own serialisation.
StatusOr<DescriptorDatabase> CopyDatabase(const DescriptorDatabase& db) {
  std::stringstream bytes;
  Status s = db.Write(bytes);
  if (!s.ok()) return s;
  const std::uint64_t size = bytes.str().size();
  return DescriptorDatabase::Read(bytes, size, "history database", db.config());
}

StatusOr<std::string> DatabaseBytes(const DescriptorDatabase& db) {
  std::ostringstream out;
  Status s = db.Write(out);
  if (!s.ok()) return s;
  return out.str();
}

// One overlapping pair (current submap index, history submap index) of O.
struct Pair {
  std::size_t current = 0;  // index into SessionResult::submaps
  std::size_t history = 0;  // index into MapContents::submaps
};

std::string ChangeLogYaml(const MergeReport& report, const SessionRecord& record,
                          const std::vector<std::uint32_t>& added,
                          const std::vector<std::uint32_t>& fused,
                          const std::vector<std::string>& skipped_pairs) {
  YAML::Emitter out;
  out << YAML::BeginMap;
  out << YAML::Key << "session" << YAML::Value << record.name;
  out << YAML::Key << "merged_at" << YAML::Value << record.merged_at;
  out << YAML::Key << "inter_session_loops" << YAML::Value << report.inter_loops;
  out << YAML::Key << "sequence_loops" << YAML::Value << report.sequence_loops;
  out << YAML::Key << "proximity_loops" << YAML::Value << report.proximity_loops;
  out << YAML::Key << "rejudged_loops" << YAML::Value << report.rejudged_loops;
  out << YAML::Key << "submaps_added" << YAML::Value << YAML::Flow << added;
  out << YAML::Key << "submaps_fused" << YAML::Value << YAML::Flow << fused;
  out << YAML::Key << "points_removed" << YAML::Value << report.points_removed;
  out << YAML::Key << "points_propagated" << YAML::Value << report.points_propagated;
  out << YAML::Key << "points_mended" << YAML::Value << report.points_mended;
  out << YAML::Key << "points_held_back" << YAML::Value << report.points_held_back;
  out << YAML::Key << "objects_held_back" << YAML::Value << report.objects_held_back;
  out << YAML::Key << "history_changes" << YAML::Value << YAML::BeginSeq;
  for (const SubmapChange& c : report.changes) {
    out << YAML::Flow << YAML::BeginMap << YAML::Key << "session" << YAML::Value << c.session
        << YAML::Key << "submap" << YAML::Value << c.submap_id << YAML::Key << "removed"
        << YAML::Value << c.removed_m.size() << YAML::Key << "mended" << YAML::Value
        << c.mended_m.size() << YAML::EndMap;
  }
  out << YAML::EndSeq;
  out << YAML::Key << "skipped_pairs" << YAML::Value << YAML::BeginSeq;
  for (const std::string& s : skipped_pairs) out << s;
  out << YAML::EndSeq;
  out << YAML::EndMap;
  return std::string(out.c_str()) + "\n";
}

}  // namespace

Status ProximityLoopConfig::Validate() const {
  if (!Finite(search_radius_m) || search_radius_m <= 0.0) {
    return Status::Error("proximity.search_radius_m must be > 0");
  }
  if (max_candidates < 1) return Status::Error("proximity.max_candidates must be >= 1");
  return registration.Validate();
}

Status MapFusionConfig::Validate() const {
  if (!Finite(min_overlap_ratio) || min_overlap_ratio < 0.0 || min_overlap_ratio > 1.0) {
    return Status::Error("fusion.min_overlap_ratio must be in [0, 1]");
  }
  if (!Finite(overlap_distance_m) || overlap_distance_m <= 0.0) {
    return Status::Error("fusion.overlap_distance_m must be > 0");
  }
  if (!Finite(voxel_m) || voxel_m <= 0.0) return Status::Error("fusion.voxel_m must be > 0");
  if (!Finite(fine_voxel_m) || (fine_voxel_m != 0.0 && fine_voxel_m < 0.02) ||
      !Finite(fine_below_m) || !Finite(fine_above_m) || fine_below_m < 0.0 ||
      fine_above_m < fine_below_m) {
    return Status::Error(
        "fusion.fine_voxel_m must be 0 (off) or >= 0.02 m, and 0 <= fine_below_m <= "
        "fine_above_m");
  }
  if (!Finite(max_dynamic_fraction) || max_dynamic_fraction <= 0.0 ||
      max_dynamic_fraction > 1.0) {
    return Status::Error("fusion.max_dynamic_fraction must be in (0, 1]");
  }
  if (!Finite(propagate_radius_m) || propagate_radius_m < 0.0) {
    return Status::Error("fusion.propagate_radius_m must be >= 0");
  }
  if (record_sessions < 0) return Status::Error("fusion.record_sessions must be >= 0 (0: all)");
  return hold.Validate();
}

Status SessionMergerConfig::Validate() const {
  Status s = matching.Validate();
  if (s.ok()) s = proximity.Validate();
  if (s.ok()) s = dynamics.Validate();
  if (s.ok()) s = fusion.Validate();
  if (!s.ok()) return s;
  if (!Finite(inter_sigma_translation_m) || inter_sigma_translation_m <= 0.0 ||
      !Finite(inter_sigma_rotation_rad) || inter_sigma_rotation_rad <= 0.0) {
    return Status::Error("merge: inter-session loop sigmas must be > 0");
  }
  if (num_threads < 1) return Status::Error("merge.num_threads must be >= 1");
  return Status::Ok();
}

StatusOr<SessionMerger> SessionMerger::Create(const SessionMergerConfig& config) {
  Status s = config.Validate();
  if (!s.ok()) return s;
  return SessionMerger(config);
}

StatusOr<MergeReport> SessionMerger::Merge(const SessionResult& session,
                                           const SessionRecord& record,
                                           const PlaceRecognizer& recognizer,
                                           const SessionFiles& files, MapContents* map) const {
  const auto start = std::chrono::steady_clock::now();
  MergeReport report;
  report.session = record.name;
  if (session.submaps.empty()) return Status::Error("session '" + record.name + "' has no submaps");
  for (const SessionRecord& s : map->sessions) {
    if (s.name == record.name) {
      return Status::Error("the map already has a session named '" + record.name + "'");
    }
  }

  // ---- First session: it defines the map frame. ----
  if (map->sessions.empty()) {
    StatusOr<DescriptorDatabase> database = recognizer.NewDatabase();
    Status s = database.status();
    if (s.ok()) s = recognizer.AppendTo(&database.value());
    if (!s.ok()) return s;
    StatusOr<std::string> bytes = DatabaseBytes(database.value());
    if (!bytes.ok()) return bytes.status();
    // Its frame is the map frame: re-expressed in its first scans' registered frame when the
    // frame anchor found the graph's tilted (frame_anchor.h).
    const SessionResult* first = &session;
    SessionResult anchored;
    if (session.anchor.accepted) {
      anchored = session;
      Reanchor(session.anchor.T_session_scan, session.anchor.first_submap, &anchored.graph,
               &anchored.submaps);
      anchored.trajectory = ScanTrajectory(anchored.submaps);
      first = &anchored;
    }
    MapContents updated;
    s = AddFirstSession(*first, record, files, &updated);
    if (!s.ok()) return s;
    updated.parameters_yaml = map->parameters_yaml;
    updated.files[kDatabaseFile] = std::move(bytes.value());
    std::vector<std::uint32_t> added;
    for (const Submap& submap : session.submaps) added.push_back(submap.id);
    report.first_session = true;
    report.submaps_added = added.size();
    report.loops = session.loops;
    report.total_s = SecondsSince(start);
    updated.files["changes/" + record.name + ".yaml"] =
        ChangeLogYaml(report, record, added, {}, {});
    *map = std::move(updated);
    return report;
  }

  // ---- Later sessions. Everything is computed first; `map` changes only at the end. ----
  if (!recognizer.history()) {
    return Status::Error("cannot merge '" + record.name +
                         "': the place recognizer had no history database to query");
  }
  InterSessionMatcherConfig matching = config_.matching;
  matching.num_threads = config_.num_threads;
  StatusOr<InterSessionMatcher> matcher = InterSessionMatcher::Create(matching);
  if (!matcher.ok()) return matcher.status();
  const auto match_start = std::chrono::steady_clock::now();
  StatusOr<InterSessionMatchResult> matched = matcher.value().Match(*map, session, recognizer);
  if (!matched.ok()) return matched.status();
  report.matching = std::move(matched.value());
  report.matching_s = SecondsSince(match_start);
  const InterSessionMatchResult& m = report.matching;
  if (!m.aligned) {
    std::size_t candidates = 0;
    for (const LoopRecord& r : m.records) candidates += r.status != LoopStatus::kUndefined;
    return Status::Error("session '" + record.name +
                         "' could not be aligned with the map: " + std::to_string(candidates) +
                         " inter-session candidate pairs, no consistent group of accepted "
                         "loops (does it overlap the mapped area?); the map was not changed");
  }

  // Node ids: history submaps keep theirs; the new session gets the next session index.
  std::map<std::string, std::size_t> session_index;
  for (std::size_t i = 0; i < map->sessions.size(); ++i) session_index[map->sessions[i].name] = i;
  auto history_node = [&](std::size_t h) {
    const Submap& submap = map->submaps[h];
    return SubmapNodeId(session_index.at(submap.session), submap.id);
  };
  const std::size_t new_index = map->sessions.size();
  auto current_node = [&](std::size_t c) {
    return SubmapNodeId(new_index, session.submaps[c].id);
  };
  std::map<std::uint32_t, std::size_t> current_by_id;
  for (std::size_t c = 0; c < session.submaps.size(); ++c) current_by_id[session.submaps[c].id] = c;

  // ---- Joint pose graph. ----
  const auto optimise_start = std::chrono::steady_clock::now();
  PoseGraph graph = map->graph;
  for (std::size_t c = 0; c < session.submaps.size(); ++c) {
    graph.SetNodePose(current_node(c), m.T_map_session * session.submaps[c].T_map_submap);
  }
  const Status session_graph = AddSessionGraph(session.graph, new_index, &graph);
  if (!session_graph.ok()) return session_graph;
  LoopRecords records = m.records;
  std::vector<Pair> pairs;
  std::map<std::size_t, std::size_t> edge_to_record;  // graph edge index -> records index
  auto add_loop_edge = [&](std::size_t c, std::size_t h, const Pose3& T_history_current,
                           const Information6& information, std::size_t record_index) -> Status {
    PoseGraphEdge edge;
    edge.from = history_node(h);
    edge.to = current_node(c);
    edge.T_from_to = T_history_current;
    edge.information = information;
    edge.kind = EdgeKind::kInterLoop;
    StatusOr<std::size_t> index = graph.AddEdge(edge);
    if (!index.ok()) return index.status();
    edge_to_record[index.value()] = record_index;
    return Status::Ok();
  };
  auto find_record = [&](std::uint32_t current_id, const Submap& history) -> std::size_t {
    for (std::size_t i = 0; i < records.size(); ++i) {
      const LoopRecord& r = records[i];
      if (r.status == LoopStatus::kAccepted && r.current_submap == current_id &&
          r.history_session == history.session &&
          r.history_submap == static_cast<std::int64_t>(history.id)) {
        return i;
      }
    }
    return records.size();
  };
  const Information6 inter_information =
      DiagonalInformation(config_.inter_sigma_translation_m, config_.inter_sigma_rotation_rad);
  for (const InterSessionLoop& loop : m.loops) {
    const auto it = current_by_id.find(loop.current_submap);
    if (it == current_by_id.end() || loop.history_index >= map->submaps.size()) {
      return Status::Error("inter-session matcher returned a loop with an unknown submap");
    }
    Status s = add_loop_edge(it->second, loop.history_index, loop.T_history_current,
                             inter_information,
                             find_record(loop.current_submap, map->submaps[loop.history_index]));
    if (!s.ok()) return s;
  }
  auto optimise = [&]() -> Status {
    StatusOr<PoseGraphSummary> summary = graph.Optimize();
    if (!summary.ok()) return summary.status();
    for (std::size_t index : summary.value().rejected_edges) {
      const auto it = edge_to_record.find(index);
      if (it == edge_to_record.end() || it->second >= records.size()) continue;
      records[it->second].status = LoopStatus::kRejected;
      records[it->second].reason = "rejected by the joint pose graph (inconsistent)";
    }
    return Status::Ok();
  };
  Status s = optimise();
  if (!s.ok()) return s;

  // ---- Loops that only disagreed with a reference the joint graph rejected: judged again ----
  // (dependent_loops.h); the accepted ones go into the graph like the others, whose robust
  // kernel can still reject them.
  DependentLoopBounds dependent_bounds;
  dependent_bounds.max_translation_m = config_.matching.consistency.max_translation_m;
  dependent_bounds.max_rotation_rad = config_.matching.consistency.max_rotation_rad;
  const std::vector<std::size_t> rejudged = RejudgeDependentLoops(
      m.dependent,
      [&](const InterSessionLoop& loop, Pose3* T_history_current) {
        const auto it = current_by_id.find(loop.current_submap);
        if (it == current_by_id.end() || loop.history_index >= map->submaps.size()) return false;
        *T_history_current = graph.NodePose(history_node(loop.history_index)).inverse() *
                             graph.NodePose(current_node(it->second));
        return true;
      },
      dependent_bounds, &records);
  for (std::size_t i : rejudged) {
    const DependentLoop& d = m.dependent[i];
    s = add_loop_edge(current_by_id.at(d.loop.current_submap), d.loop.history_index,
                      d.loop.T_history_current, inter_information, d.record);
    if (!s.ok()) return s;
  }
  if (!rejudged.empty()) {
    s = optimise();
    if (!s.ok()) return s;
  }

  // ---- Second loop search by proximity, now that both share the map frame. ----
  StatusOr<SubmapRegistration> registration =
      SubmapRegistration::Create(config_.proximity.registration);
  if (!registration.ok()) return registration.status();
  std::set<std::pair<std::size_t, std::size_t>> linked;  // (current, history)
  for (const auto& [edge_index, record_index] : edge_to_record) {
    (void)record_index;
    const PoseGraphEdge& edge = graph.edges()[edge_index];
    if (!edge.enabled) continue;
    for (std::size_t h = 0; h < map->submaps.size(); ++h) {
      if (history_node(h) != edge.from) continue;
      for (std::size_t c = 0; c < session.submaps.size(); ++c) {
        if (current_node(c) == edge.to) linked.insert({c, h});
      }
    }
  }
  struct ProximityJob {
    std::size_t current, history;
    Pose3 prior;
    SubmapRegistrationResult result;
    EIGEN_MAKE_ALIGNED_OPERATOR_NEW
  };
  std::vector<ProximityJob, Eigen::aligned_allocator<ProximityJob>> jobs;
  if (config_.proximity.enabled) {
    for (std::size_t c = 0; c < session.submaps.size(); ++c) {
      const Pose3 T_map_c = graph.NodePose(current_node(c));
      std::vector<std::pair<double, std::size_t>> near;
      for (std::size_t h = 0; h < map->submaps.size(); ++h) {
        const Submap& hs = map->submaps[h];
        if (hs.state != SubmapState::kActive || hs.points.empty() || linked.count({c, h})) continue;
        const double d =
            (graph.NodePose(history_node(h)).translation() - T_map_c.translation()).norm();
        if (d <= config_.proximity.search_radius_m) near.push_back({d, h});
      }
      std::sort(near.begin(), near.end());
      if (near.size() > static_cast<std::size_t>(config_.proximity.max_candidates)) {
        near.resize(config_.proximity.max_candidates);
      }
      for (const auto& [d, h] : near) {
        (void)d;
        ProximityJob job;
        job.current = c;
        job.history = h;
        job.prior = graph.NodePose(history_node(h)).inverse() * T_map_c;
        jobs.push_back(job);
      }
    }
  }
  // Targets are built once per history submap (kd-tree and normals); those the matching built
  // the same way are taken over.
  std::map<std::size_t, std::shared_ptr<const SubmapTarget>> targets;
  std::vector<std::size_t> target_keys;
  for (const ProximityJob& job : jobs) {
    if (targets.count(job.history)) continue;
    const auto built_before = m.history_targets.find(job.history);
    if (built_before != m.history_targets.end() &&
        built_before->second->BuiltLike(config_.proximity.registration)) {
      targets[job.history] = built_before->second;
    } else {
      targets[job.history] = nullptr;
      target_keys.push_back(job.history);
    }
  }
  std::vector<std::shared_ptr<const SubmapTarget>> built(target_keys.size());
  ParallelFor(target_keys.size(), config_.num_threads, [&](std::size_t i) {
    StatusOr<SubmapTarget> t =
        SubmapTarget::Create(map->submaps[target_keys[i]].points, config_.proximity.registration);
    if (t.ok()) built[i] = std::make_shared<SubmapTarget>(std::move(t.value()));
  });
  for (std::size_t i = 0; i < target_keys.size(); ++i) targets[target_keys[i]] = built[i];
  ParallelFor(jobs.size(), config_.num_threads, [&](std::size_t i) {
    ProximityJob& job = jobs[i];
    const std::shared_ptr<const SubmapTarget>& target = targets.at(job.history);
    if (!target) {
      job.result.reason = "history submap unusable as a registration target";
      return;
    }
    job.result = registration.value().Register(session.submaps[job.current].points, *target,
                                               job.prior);
  });
  // The matching's targets are no longer needed (kd-trees of tens of submaps).
  targets.clear();
  report.matching.history_targets.clear();
  bool any_proximity = false;
  for (const ProximityJob& job : jobs) {
    LoopRecord r;
    r.kind = LoopKind::kInterProximity;
    r.current_session = record.name;
    r.current_submap = session.submaps[job.current].id;
    r.history_session = map->submaps[job.history].session;
    r.history_submap = map->submaps[job.history].id;
    r.overlap_ratio = job.result.overlap_ratio;
    r.has_pose = true;
    r.T_history_current = job.result.accepted ? job.result.T_target_source : job.prior;
    r.status = job.result.accepted ? LoopStatus::kAccepted : LoopStatus::kRejected;
    r.reason = job.result.reason;
    records.push_back(r);
    if (!job.result.accepted) continue;
    s = add_loop_edge(job.current, job.history, job.result.T_target_source,
                      job.result.information, records.size() - 1);
    if (!s.ok()) return s;
    any_proximity = true;
  }
  if (any_proximity) {
    s = optimise();
    if (!s.ok()) return s;
  }
  report.optimisation_s = SecondsSince(optimise_start);

  // O: every accepted inter-session loop edge (first and second search).
  std::set<std::pair<std::size_t, std::size_t>> pair_set;
  for (const auto& [edge_index, record_index] : edge_to_record) {
    (void)record_index;
    const PoseGraphEdge& edge = graph.edges()[edge_index];
    if (!edge.enabled) continue;
    std::size_t h = map->submaps.size(), c = session.submaps.size();
    for (std::size_t i = 0; i < map->submaps.size() && h == map->submaps.size(); ++i) {
      if (history_node(i) == edge.from) h = i;
    }
    for (std::size_t i = 0; i < session.submaps.size() && c == session.submaps.size(); ++i) {
      if (current_node(i) == edge.to) c = i;
    }
    if (h < map->submaps.size() && c < session.submaps.size()) pair_set.insert({c, h});
  }
  for (const LoopRecord& r : records) {
    report.inter_loops += r.kind == LoopKind::kInter && r.status == LoopStatus::kAccepted;
    report.sequence_loops +=
        r.kind == LoopKind::kInterSequence && r.status == LoopStatus::kAccepted;
    report.proximity_loops +=
        r.kind == LoopKind::kInterProximity && r.status == LoopStatus::kAccepted;
  }
  for (std::size_t i : rejudged) {
    report.rejudged_loops += records[m.dependent[i].record].status == LoopStatus::kAccepted;
  }
  for (const auto& [c, h] : pair_set) pairs.push_back({c, h});

  // ---- Low-dynamic detection for every pair of O. ----
  const auto update_start = std::chrono::steady_clock::now();
  StatusOr<DynamicDetector> detector = DynamicDetector::Create(config_.dynamics);
  if (!detector.ok()) return detector.status();
  std::vector<StatusOr<DynamicDetectionResult>> detections(pairs.size(),
                                                           Status::Error("not run"));
  auto pose_of_history = [&](std::size_t h) { return graph.NodePose(history_node(h)); };
  auto pose_of_current = [&](std::size_t c) { return graph.NodePose(current_node(c)); };
  // The pairs of one submap share its neighbour index, built once in the submap's own frame
  // and freed after its last pair (PointIndexPool); each pair is charged its shares.
  std::vector<std::vector<std::size_t>> pairs_of_current(session.submaps.size());
  std::vector<int> uses_of_history(map->submaps.size(), 0);
  std::vector<int> uses_of_current(session.submaps.size(), 0);
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    pairs_of_current[pairs[i].current].push_back(i);
    ++uses_of_history[pairs[i].history];
    ++uses_of_current[pairs[i].current];
  }
  PointIndexPool history_indices(
      std::move(uses_of_history),
      [&](std::size_t h) -> const PointVector& { return map->submaps[h].points; });
  PointIndexPool current_indices(
      std::move(uses_of_current),
      [&](std::size_t c) -> const PointVector& { return session.submaps[c].points; });
  ParallelFor(session.submaps.size(), config_.num_threads, [&](std::size_t c) {
    for (std::size_t i : pairs_of_current[c]) {
      const Pair& p = pairs[i];
      const Pose3 T_current_history =
          pose_of_current(p.current).inverse() * pose_of_history(p.history);
      detections[i] =
          detector.value().Detect(map->submaps[p.history], session.submaps[c], T_current_history,
                                  &history_indices, p.history, &current_indices, c);
    }
  });
  std::map<std::size_t, std::set<std::uint32_t>> removed;  // history index -> point indices
  std::map<std::size_t, std::set<std::uint32_t>> current_dynamic;
  std::map<std::size_t, PointVector> mended;  // history index -> points, map frame
  std::vector<std::string> skipped_pairs;
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    const Pair& p = pairs[i];
    const Submap& hs = map->submaps[p.history];
    const Submap& cs = session.submaps[p.current];
    const std::string name = hs.session + "/" + std::to_string(hs.id) + " <-> " + record.name +
                             "/" + std::to_string(cs.id);
    if (!detections[i].ok()) {
      skipped_pairs.push_back(name + ": " + detections[i].status().message());
      continue;
    }
    const DynamicDetectionResult& d = detections[i].value();
    report.dynamic_pair_s.push_back(d.time_s);
    if (d.MarksMoreThan(config_.fusion.max_dynamic_fraction, hs.points.size(),
                        cs.points.size())) {
      skipped_pairs.push_back(name + ": too many dynamic points (" +
                              std::to_string(d.history_dynamic.size()) + " history, " +
                              std::to_string(d.current_dynamic.size()) +
                              " current); treated as misaligned");
      continue;
    }
    for (std::uint32_t k : d.history_dynamic) {
      if (k < hs.points.size()) removed[p.history].insert(k);
    }
    for (std::uint32_t k : d.current_dynamic) {
      if (k < cs.points.size()) current_dynamic[p.current].insert(k);
    }
    const Pose3 T_map_c = pose_of_current(p.current);
    for (std::uint32_t k : d.current_mending) {
      if (k < cs.points.size()) mended[p.history].push_back(T_map_c * cs.points[k]);
    }
  }

  // Copies of the dynamic points in submaps the pairs did not examine (farther views).
  if (config_.fusion.propagate_radius_m > 0.0) {
    auto marks_of = [](const std::map<std::size_t, std::set<std::uint32_t>>& marks,
                       std::size_t i) -> const std::set<std::uint32_t>* {
      const auto it = marks.find(i);
      return it == marks.end() ? nullptr : &it->second;
    };
    std::vector<MarkedCloud> clouds;
    std::vector<std::pair<bool, std::size_t>> owners;  // (history?, index)
    for (std::size_t h = 0; h < map->submaps.size(); ++h) {
      if (map->submaps[h].state != SubmapState::kActive) continue;
      clouds.push_back({&map->submaps[h].points, pose_of_history(h), marks_of(removed, h)});
      owners.emplace_back(true, h);
    }
    for (std::size_t c = 0; c < session.submaps.size(); ++c) {
      clouds.push_back(
          {&session.submaps[c].points, pose_of_current(c), marks_of(current_dynamic, c)});
      owners.emplace_back(false, c);
    }
    StatusOr<std::vector<std::vector<std::uint32_t>>> propagated =
        FindCopiesOfMarked(config_.fusion.propagate_radius_m, config_.num_threads, clouds);
    if (!propagated.ok()) return propagated.status();
    for (std::size_t i = 0; i < clouds.size(); ++i) {
      const std::vector<std::uint32_t>& found = propagated.value()[i];
      if (found.empty()) continue;
      auto& marks = owners[i].first ? removed : current_dynamic;
      marks[owners[i].second].insert(found.begin(), found.end());
      report.points_propagated += found.size();
    }
  }
  report.update_dynamics_s = SecondsSince(update_start);
  const auto fusion_start = std::chrono::steady_clock::now();
  // ---- Map update: remove, mend, fuse or add. ----
  // History submaps after removal, in the map frame, as voxel occupancy for the fusion tests.
  std::vector<PointVector> history_points(map->submaps.size());
  for (std::size_t h = 0; h < map->submaps.size(); ++h) {
    const Submap& hs = map->submaps[h];
    if (hs.state != SubmapState::kActive) continue;
    const auto rm = removed.find(h);
    for (std::size_t k = 0; k < hs.points.size(); ++k) {
      if (rm != removed.end() && rm->second.count(static_cast<std::uint32_t>(k))) continue;
      history_points[h].push_back(hs.points[k]);
    }
  }
  const MapFusionConfig& fc = config_.fusion;
  const bool use_fine = fc.fine_voxel_m > 0.0 && fc.fine_voxel_m < fc.voxel_m;
  VoxelOccupancy overlap_grid(fc.overlap_distance_m);
  VoxelOccupancy fusion_grid(fc.voxel_m);
  VoxelOccupancy fine_grid(use_fine ? fc.fine_voxel_m : fc.voxel_m);
  // Every point of the map goes into each: one grid per thread, the fine grid (the largest,
  // ~2.3 s of ~3.2 s on the seed-1 s01 merge) first so that the other two share a thread.
  VoxelOccupancy* const grids[] = {&fine_grid, &fusion_grid, &overlap_grid};
  const std::size_t first_grid = use_fine ? 0 : 1;
  ParallelFor(3 - first_grid, config_.num_threads, [&](std::size_t g) {
    VoxelOccupancy& grid = *grids[first_grid + g];
    for (std::size_t h = 0; h < map->submaps.size(); ++h) {
      const Pose3 T = pose_of_history(h);
      for (const Eigen::Vector3d& p : history_points[h]) grid.Add(T * p);
    }
  });
  std::map<std::size_t, PointVector> added_to_history;  // history index -> points, its frame
  auto nearest_history = [&](const Eigen::Vector3d& p_map,
                             const std::vector<std::size_t>& choices) {
    std::size_t best = choices.front();
    double best_d = std::numeric_limits<double>::infinity();
    for (std::size_t h : choices) {
      const double d = (pose_of_history(h).translation() - p_map).squaredNorm();
      if (d < best_d) {
        best_d = d;
        best = h;
      }
    }
    return best;
  };
  // Points join a history submap once per fusion voxel; fused (not mended) points only where
  // the history has nothing within about a voxel, so that re-observing the same surfaces with a
  // different scan pattern does not thicken the map session after session.
  // Fine points (MapFusionConfig::fine_voxel_m) once per fine voxel: every added point, fine
  // or not, occupies both records.
  VoxelOccupancy added_grid(fc.voxel_m);
  VoxelOccupancy added_fine_grid(use_fine ? fc.fine_voxel_m : fc.voxel_m);
  auto add_to_history = [&](std::size_t h, const Eigen::Vector3d& p_map, bool fine) {
    if (fine) {
      if (fine_grid.Occupied(p_map) || added_fine_grid.Occupied(p_map)) return false;
    } else {
      if (fusion_grid.Occupied(p_map) || added_grid.Occupied(p_map)) return false;
    }
    added_grid.Add(p_map);
    if (use_fine) added_fine_grid.Add(p_map);
    added_to_history[h].push_back(pose_of_history(h).inverse() * p_map);
    return true;
  };
  // Per new submap (in parallel, the grids are only read): its overlap with the history, and
  // when that makes it fused, its static points with no history point near (map frame).
  std::vector<std::uint8_t> fused(session.submaps.size(), 0);  // not vector<bool>: threads
  std::vector<std::vector<std::size_t>> partners(session.submaps.size());  // its pairs' history
  for (const Pair& p : pairs) partners[p.current].push_back(p.history);
  std::vector<PointVector> fusion_candidates(session.submaps.size());
  std::vector<std::vector<std::uint8_t>> fusion_fine(session.submaps.size());  // per candidate
  // Of a paired new submap that is kept as a submap: its static points with no history point
  // near (indices), candidates for the new-object hold as well.
  std::vector<std::vector<std::uint32_t>> unfused_new(session.submaps.size());
  ParallelFor(session.submaps.size(), config_.num_threads, [&](std::size_t c) {
    const Submap& cs = session.submaps[c];
    const Pose3 T_map_c = pose_of_current(c);
    const auto dyn = current_dynamic.find(c);
    auto is_dynamic = [&](std::size_t k) {
      return dyn != current_dynamic.end() && dyn->second.count(static_cast<std::uint32_t>(k));
    };
    // The submap's points in the map frame, once for the overlap and fusion tests below.
    PointVector in_map;
    in_map.reserve(cs.points.size());
    for (const Eigen::Vector3d& q : cs.points) in_map.push_back(T_map_c * q);
    std::size_t considered = 0, overlapping = 0;
    for (std::size_t k = 0; k < cs.points.size(); ++k) {
      if (is_dynamic(k)) continue;
      ++considered;
      overlapping += overlap_grid.Near(in_map[k]);
    }
    const double ratio = considered ? static_cast<double>(overlapping) / considered : 0.0;
    if (partners[c].empty()) return;
    if (ratio < config_.fusion.min_overlap_ratio) {
      if (!config_.fusion.hold.enabled) return;
      for (std::size_t k = 0; k < cs.points.size(); ++k) {
        if (!is_dynamic(k) && !fusion_grid.Near(in_map[k])) {
          unfused_new[c].push_back(static_cast<std::uint32_t>(k));
        }
      }
      return;
    }
    fused[c] = 1;
    std::vector<float> height;
    std::vector<std::uint8_t> near_standing;
    if (use_fine) {
      height = HeightsAboveLocalGround(in_map, fc.hold.ground_cell_m);
      near_standing = NearStandingPoints(in_map, height, fc.hold.ground_cell_m,
                                         fc.fine_below_m, fc.fine_above_m);
    }
    for (std::size_t k = 0; k < cs.points.size(); ++k) {
      if (is_dynamic(k)) continue;
      const Eigen::Vector3d& p = in_map[k];
      const bool fine = use_fine && (height[k] >= fc.fine_above_m ||
                                     (height[k] <= fc.fine_below_m && !near_standing[k]));
      if (fine ? !fine_grid.Near(p) : !fusion_grid.Near(p)) {
        fusion_candidates[c].push_back(p);
        fusion_fine[c].push_back(fine);
      }
    }
  });
  // New objects among the points to add (mended, then fused) are held back.
  PointVector candidates, removed_map, held_map;
  for (const auto& [h, points] : mended) {
    candidates.insert(candidates.end(), points.begin(), points.end());
  }
  for (std::size_t c = 0; c < session.submaps.size(); ++c) {
    if (!fused[c]) continue;
    candidates.insert(candidates.end(), fusion_candidates[c].begin(),
                      fusion_candidates[c].end());
  }
  for (std::size_t c = 0; c < session.submaps.size(); ++c) {
    for (std::uint32_t k : unfused_new[c]) {
      candidates.push_back(pose_of_current(c) * session.submaps[c].points[k]);
    }
  }
  std::vector<PlacedPoints> history_placed;
  for (std::size_t h = 0; h < map->submaps.size(); ++h) {
    if (map->submaps[h].state != SubmapState::kActive) continue;
    history_placed.push_back({&history_points[h], pose_of_history(h)});
    const auto rm = removed.find(h);
    if (rm == removed.end()) continue;
    for (std::uint32_t k : rm->second) {
      removed_map.push_back(pose_of_history(h) * map->submaps[h].points[k]);
    }
  }
  StatusOr<NewObjectHoldResult> hold =
      HoldBackNewObjects(config_.fusion.hold, candidates, history_placed, removed_map);
  if (!hold.ok()) return hold.status();
  const std::vector<std::uint8_t>& held = hold.value().held;
  report.objects_held_back = hold.value().groups_held;
  // The points are visited below in the order in which they joined `candidates`.
  std::size_t next_candidate = 0;
  auto not_held = [&]() {
    const std::size_t i = next_candidate++;
    if (!held[i]) return true;
    held_map.push_back(candidates[i]);
    return false;
  };
  std::map<std::size_t, PointVector> mended_added;  // history index -> mended points, map frame
  for (const auto& [h, points] : mended) {
    for (const Eigen::Vector3d& p : points) {
      if (not_held() && add_to_history(h, p, false)) mended_added[h].push_back(p);
    }
  }
  std::vector<std::uint32_t> added_ids, fused_ids;
  std::size_t fusion_points = 0;
  for (std::size_t c = 0; c < session.submaps.size(); ++c) {
    if (!fused[c]) {
      added_ids.push_back(session.submaps[c].id);
      continue;
    }
    fused_ids.push_back(session.submaps[c].id);
    for (std::size_t k = 0; k < fusion_candidates[c].size(); ++k) {
      const Eigen::Vector3d& p = fusion_candidates[c][k];
      if (not_held()) {
        fusion_points += add_to_history(nearest_history(p, partners[c]), p, fusion_fine[c][k]);
      }
    }
  }
  // Held points of the new submaps kept as submaps leave them with their dynamic points.
  for (std::size_t c = 0; c < session.submaps.size(); ++c) {
    for (std::uint32_t k : unfused_new[c]) {
      if (!not_held()) current_dynamic[c].insert(k);
    }
  }
  report.points_held_back = held_map.size();

  report.update_fusion_s = SecondsSince(fusion_start);
  const auto database_start = std::chrono::steady_clock::now();
  // ---- Descriptor database: history plus the scans of the submaps kept as submaps. ----
  StatusOr<DescriptorDatabase> database = CopyDatabase(*recognizer.history());
  if (!database.ok()) return database.status();
  std::set<std::uint32_t> skip(fused_ids.begin(), fused_ids.end());
  s = recognizer.AppendTo(&database.value(), skip);
  if (!s.ok()) return s;
  StatusOr<std::string> database_bytes = DatabaseBytes(database.value());
  if (!database_bytes.ok()) return database_bytes.status();

  report.update_database_s = SecondsSince(database_start);
  // ---- Commit (nothing below can fail). ----
  for (std::size_t h = 0; h < map->submaps.size(); ++h) {
    Submap& hs = map->submaps[h];
    hs.T_map_submap = pose_of_history(h);
    const bool changed = removed.count(h) || added_to_history.count(h);
    if (!changed) continue;
    SubmapChange change;
    change.session = hs.session;
    change.submap_id = hs.id;
    const auto rm = removed.find(h);
    if (rm != removed.end()) {
      for (std::uint32_t k : rm->second) change.removed_m.push_back(hs.T_map_submap * hs.points[k]);
    }
    if (rm != removed.end()) DropSubmapPointsAt(rm->second, &hs);
    history_points[h] = PointVector();
    const auto add = added_to_history.find(h);
    if (add != added_to_history.end()) {
      AppendSubmapPoints(add->second, &hs);
      // The added points in place (blocks of the fusion voxel, the submaps' by default).
      SortSubmapPointsInVoxelBlocks(config_.fusion.voxel_m, &hs);
    }
    const auto md = mended_added.find(h);
    if (md != mended_added.end()) change.mended_m = md->second;
    report.points_removed += change.removed_m.size();
    report.points_mended += change.mended_m.size();
    map->clean_submaps.erase(SubmapKey(hs.session, hs.id));
    report.changes.push_back(std::move(change));
  }
  // History trajectories follow their submaps: each pose moves with the submap whose time span
  // holds its stamp (the joint optimisation may move history submaps slightly).
  {
    for (auto& [name, trajectory] : map->trajectories) {
      std::vector<std::pair<double, Pose3>> deltas;  // first stamp -> correction, by time
      for (std::size_t h = 0; h < map->submaps.size(); ++h) {
        const Submap& hs = map->submaps[h];
        if (hs.session != name || hs.scans.empty()) continue;
        const Pose3 T_old = map->graph.HasNode(history_node(h)) ? map->graph.NodePose(history_node(h))
                                                                : hs.T_map_submap;
        deltas.push_back({hs.first_stamp_s(), hs.T_map_submap * T_old.inverse()});
      }
      std::sort(deltas.begin(), deltas.end(),
                [](const auto& a, const auto& b) { return a.first < b.first; });
      if (deltas.empty()) continue;
      for (StampedPose& sp : trajectory) {
        auto it = std::upper_bound(deltas.begin(), deltas.end(), sp.stamp_s,
                                   [](double t, const auto& d) { return t < d.first; });
        if (it != deltas.begin()) --it;
        sp.pose = it->second * sp.pose;
      }
    }
  }
  Trajectory trajectory;
  for (std::size_t c = 0; c < session.submaps.size(); ++c) {
    Submap submap = session.submaps[c];
    submap.T_map_submap = pose_of_current(c);
    AppendScanPoses(submap, &trajectory);
    if (fused[c]) {
      submap.state = SubmapState::kFused;
      // Its static points now live in the history submaps. Release the buffer, not only the
      // size (clear() keeps the capacity): a long-lived process (the nodelets) keeps the map
      // in memory across sessions, and every fused submap kept its whole point buffer.
      submap.points = PointVector();
      submap.views = std::vector<PointViews>();
    } else {
      const auto dyn = current_dynamic.find(c);
      if (dyn != current_dynamic.end()) DropSubmapPointsAt(dyn->second, &submap);
    }
    map->submaps.push_back(std::move(submap));
  }
  SortTrajectory(&trajectory);
  map->graph = std::move(graph);
  map->sessions.push_back(record);
  map->trajectories[record.name] = std::move(trajectory);
  map->odom_trajectories[record.name] = session.odometry;
  report.submaps_added = added_ids.size();
  report.submaps_fused = fused_ids.size();
  report.loops = session.loops;
  report.loops.insert(report.loops.end(), records.begin(), records.end());
  map->files["loops/" + record.name + ".csv"] = LoopRecordsToCsv(report.loops);
  map->files["timing/" + record.name + ".yaml"] = files.timing_yaml;
  if (!files.place_recognition_csv.empty()) {
    map->files["place_recognition/" + record.name + ".csv"] = files.place_recognition_csv;
  }
  map->files[kDatabaseFile] = std::move(database_bytes.value());
  PointVector all_removed, all_mended;
  for (const SubmapChange& c : report.changes) {
    all_removed.insert(all_removed.end(), c.removed_m.begin(), c.removed_m.end());
    all_mended.insert(all_mended.end(), c.mended_m.begin(), c.mended_m.end());
  }
  map->clouds["dynamics/" + record.name + "_removed.pcd"] = std::move(all_removed);
  map->clouds["dynamics/" + record.name + "_mended.pcd"] = std::move(all_mended);
  report.held_m = held_map;
  map->clouds["dynamics/" + record.name + "_held.pcd"] = std::move(held_map);
  RetireSessionRecords(config_.fusion.record_sessions, map);
  report.update_s = SecondsSince(update_start);
  report.total_s = SecondsSince(start);
  report.points_fused = fusion_points;
  map->files["changes/" + record.name + ".yaml"] =
      ChangeLogYaml(report, record, added_ids, fused_ids, skipped_pairs);
  return report;
}

}  // namespace core
}  // namespace multisession_mapper
