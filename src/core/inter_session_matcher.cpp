#include "multisession_mapper/core/inter_session_matcher.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <utility>

#include "multisession_mapper/core/se3.h"

namespace multisession_mapper {
namespace core {

namespace {

// A registered candidate pair waiting for the sequence-consistency check.
struct Registered {
  InterSessionLoop loop;
  std::size_t record = 0;      // index into the result's records
  Pose3 T_map_session;         // implied by this loop
  Eigen::Vector3d origin;      // current submap origin, session frame
  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

bool Agree(const Registered& a, const Registered& b, const SequenceConsistencyConfig& config) {
  const double separation_m = (a.origin - b.origin).norm();
  const double max_t = config.max_translation_m + config.max_translation_per_m * separation_m;
  const double max_r = config.max_rotation_rad + config.max_rotation_per_m * separation_m;
  // Where each loop puts the other's current submap origin in the map.
  for (const Eigen::Vector3d& x : {a.origin, b.origin}) {
    if ((a.T_map_session * x - b.T_map_session * x).norm() > max_t) return false;
  }
  return se3::RotationAngleRad(se3::Between(a.T_map_session, b.T_map_session)) <= max_r;
}

double ProportionOf(const SubmapVoteResult& vote, const HistorySubmapId& id) {
  for (const VoteProportion& p : vote.proportions) {
    if (p.history == id) return p.proportion;
  }
  return 0.0;
}

}  // namespace

Status SequenceConsistencyConfig::Validate() const {
  if (!(max_translation_m > 0.0) || !(max_rotation_rad > 0.0)) {
    return Status::Error("sequence_consistency max_translation_m / max_rotation_rad must be > 0");
  }
  if (!(max_translation_per_m >= 0.0) || !(max_rotation_per_m >= 0.0)) {
    return Status::Error("sequence_consistency per-metre bounds must be >= 0");
  }
  if (min_group_size < 1) return Status::Error("sequence_consistency.min_group_size must be >= 1");
  return Status::Ok();
}

Status InterSessionMatcherConfig::Validate() const {
  Status s = voting.Validate();
  if (!s.ok()) return s;
  if (!(neighbour_distance_m > 0.0)) {
    return Status::Error("inter_session.neighbour_distance_m must be > 0");
  }
  s = registration.Validate();
  if (!s.ok()) return s;
  return consistency.Validate();
}

StatusOr<InterSessionMatcher> InterSessionMatcher::Create(const InterSessionMatcherConfig& config) {
  Status s = config.Validate();
  if (!s.ok()) return s;
  return InterSessionMatcher(config);
}

StatusOr<InterSessionMatchResult> InterSessionMatcher::Match(
    const MapContents& history, const SessionResult& current,
    const PlaceRecognizer& recognizer) const {
  StatusOr<SubmapVoting> voting = SubmapVoting::Create(config_.voting);
  if (!voting.ok()) return voting.status();
  StatusOr<GlobalRegistration> registration = GlobalRegistration::Create(config_.registration);
  if (!registration.ok()) return registration.status();

  std::map<HistorySubmapId, std::size_t> index_of;
  std::map<HistorySubmapId, Eigen::Vector3d> active_origins;
  for (std::size_t i = 0; i < history.submaps.size(); ++i) {
    const Submap& s = history.submaps[i];
    const HistorySubmapId id{s.session, static_cast<int>(s.id)};
    index_of[id] = i;
    if (s.state == SubmapState::kActive) active_origins[id] = s.T_map_submap.translation();
  }
  const SubmapVoting::NeighbourRelation neighbours =
      SubmapVoting::OriginsWithin(active_origins, config_.neighbour_distance_m);

  InterSessionMatchResult result;
  std::vector<Registered, Eigen::aligned_allocator<Registered>> registered;
  // Prepared submaps (features, fine target) are built on first use and reused: a history
  // submap is the target of several current submaps. The preparation time is charged to the
  // pair that needed it.
  std::map<std::size_t, std::shared_ptr<const PreparedSubmap>> prepared_history;
  for (const Submap& cur : current.submaps) {
    std::shared_ptr<const PreparedSubmap> prepared_current;
    const SubmapVoteResult vote = voting.value().Vote(recognizer.VotesOf(cur.id), neighbours);
    result.votes.push_back(vote);
    LoopRecord base;
    base.kind = LoopKind::kInter;
    base.current_session = current.session;
    base.current_submap = cur.id;
    if (vote.outcome == SubmapVoteResult::Outcome::kUndefined) {
      LoopRecord record = base;
      record.status = LoopStatus::kUndefined;
      record.vote_proportion = vote.proportions.empty() ? 0.0 : vote.proportions.front().proportion;
      record.reason = vote.reason;
      result.records.push_back(record);
      continue;
    }
    for (const HistorySubmapId& candidate : vote.candidates) {
      LoopRecord record = base;
      record.history_session = candidate.session;
      record.history_submap = candidate.submap_id;
      record.vote_proportion = ProportionOf(vote, candidate);
      record.status = LoopStatus::kRejected;
      const auto found = index_of.find(candidate);
      if (found == index_of.end()) {
        record.reason = "history submap not in the map";
        result.records.push_back(record);
        continue;
      }
      const Submap& hist = history.submaps[found->second];
      if (hist.state != SubmapState::kActive) {
        record.reason = "history submap fused into a later session's";
        result.records.push_back(record);
        continue;
      }
      double prepare_s = 0.0;
      if (!prepared_current) {
        StatusOr<std::shared_ptr<const PreparedSubmap>> p =
            registration.value().Prepare(cur.points, false);
        if (!p.ok()) {
          record.reason = "current submap: " + p.status().message();
          result.records.push_back(record);
          continue;
        }
        prepared_current = p.value();
        prepare_s += GlobalRegistration::PrepareSeconds(*prepared_current);
      }
      std::shared_ptr<const PreparedSubmap>& prepared_hist = prepared_history[found->second];
      if (!prepared_hist) {
        StatusOr<std::shared_ptr<const PreparedSubmap>> p =
            registration.value().Prepare(hist.points, true);
        if (!p.ok()) {
          record.reason = "history submap: " + p.status().message();
          result.records.push_back(record);
          continue;
        }
        prepared_hist = p.value();
        prepare_s += GlobalRegistration::PrepareSeconds(*prepared_hist);
      }
      const GlobalRegistrationResult reg =
          registration.value().Register(*prepared_current, *prepared_hist);
      result.registration_s.push_back(reg.time_s + prepare_s);
      record.overlap_ratio = reg.overlap_ratio;
      record.has_pose = true;
      record.T_history_current = reg.T_target_source;
      if (!reg.accepted) {
        record.reason = "global registration: " + reg.reason;
        result.records.push_back(record);
        continue;
      }
      Registered r;
      r.loop.current_submap = cur.id;
      r.loop.history_index = found->second;
      r.loop.T_history_current = reg.T_target_source;
      r.loop.information = reg.information;
      r.loop.vote_proportion = record.vote_proportion;
      r.loop.overlap_ratio = reg.overlap_ratio;
      r.record = result.records.size();
      r.T_map_session = hist.T_map_submap * reg.T_target_source * cur.T_map_submap.inverse();
      r.origin = cur.T_map_submap.translation();
      registered.push_back(r);
      record.status = LoopStatus::kCandidate;  // decided below
      result.records.push_back(record);
    }
  }

  // Sequence consistency: the largest group of loops agreeing with one of them.
  const SequenceConsistencyConfig& consistency = config_.consistency;
  std::vector<std::size_t> best_group;
  double best_overlap_sum = -1.0;
  for (std::size_t i = 0; i < registered.size(); ++i) {
    std::vector<std::size_t> group;
    double overlap_sum = 0.0;
    for (std::size_t j = 0; j < registered.size(); ++j) {
      if (i == j || Agree(registered[i], registered[j], consistency)) {
        group.push_back(j);
        overlap_sum += registered[j].loop.overlap_ratio;
      }
    }
    if (group.size() > best_group.size() ||
        (group.size() == best_group.size() && overlap_sum > best_overlap_sum)) {
      best_group = std::move(group);
      best_overlap_sum = overlap_sum;
    }
  }
  const bool enough = static_cast<int>(best_group.size()) >= consistency.min_group_size;
  std::vector<bool> in_group(registered.size(), false);
  if (enough) {
    for (std::size_t j : best_group) in_group[j] = true;
  }
  std::size_t anchor = registered.size();
  for (std::size_t j = 0; j < registered.size(); ++j) {
    LoopRecord& record = result.records[registered[j].record];
    if (in_group[j]) {
      record.status = LoopStatus::kAccepted;
      result.loops.push_back(registered[j].loop);
      if (anchor == registered.size() ||
          registered[j].loop.overlap_ratio > registered[anchor].loop.overlap_ratio) {
        anchor = j;
      }
    } else {
      record.status = LoopStatus::kRejected;
      record.reason =
          enough ? "inconsistent with the " + std::to_string(best_group.size()) +
                       " agreeing loops"
                 : "too few consistent loops (" + std::to_string(best_group.size()) + " < " +
                       std::to_string(consistency.min_group_size) + ")";
    }
  }
  if (anchor < registered.size()) {
    result.T_map_session = registered[anchor].T_map_session;
    result.aligned = true;
  }
  return result;
}

}  // namespace core
}  // namespace multisession_mapper
