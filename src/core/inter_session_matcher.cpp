#include "multisession_mapper/core/inter_session_matcher.h"

#include <algorithm>
#include <deque>
#include <iterator>
#include <limits>
#include <cmath>
#include <map>
#include <memory>
#include <set>
#include <utility>

#include "multisession_mapper/core/parallel_for.h"
#include "multisession_mapper/core/se3.h"
#include "multisession_mapper/core/submap.h"
#include "multisession_mapper/core/submap_loop_agreement.h"

namespace multisession_mapper {
namespace core {

namespace {

// A registered candidate pair waiting for the sequence-consistency check.
struct Registered {
  InterSessionLoop loop;
  std::size_t record = 0;      // index into the result's records
  Pose3 T_map_session;         // implied by this loop
  Eigen::Vector3d origin;      // current submap origin, session frame
  double path_m = 0.0;         // distance driven in the session up to the current submap
  std::size_t current = 0;     // index into the session's submaps
  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

// How far apart the map <- session transforms of two loops are, as a fraction of `max_t` [m]
// (where each puts both current submap origins) and of `max_r` [rad]: <= 1 is agreement.
double Discrepancy(const Registered& a, const Registered& b, double max_t, double max_r) {
  double worst = 0.0;
  for (const Eigen::Vector3d& x : {a.origin, b.origin}) {
    worst = std::max(worst, (a.T_map_session * x - b.T_map_session * x).norm() / max_t);
  }
  return std::max(worst,
                  se3::RotationAngleRad(se3::Between(a.T_map_session, b.T_map_session)) / max_r);
}

// Whether the two loops imply the same map <- session transform within `max_t` [m] (where each
// puts both current submap origins) and `max_r` [rad].
bool AgreeWithin(const Registered& a, const Registered& b, double max_t, double max_r) {
  return Discrepancy(a, b, max_t, max_r) <= 1.0;
}

// Discrepancy under bounds `base_t` [m] / `base_r` [rad] that grow with the distance between
// the two current submaps (odometry drift between them) by the per-metre sequence bounds.
double GrowingDiscrepancy(const Registered& a, const Registered& b, double base_t, double base_r,
                          const SequenceConsistencyConfig& config) {
  const double separation_m = (a.origin - b.origin).norm();
  return Discrepancy(a, b, base_t + config.max_translation_per_m * separation_m,
                     base_r + config.max_rotation_per_m * separation_m);
}

// Discrepancy under the sequence-consistency bounds.
double ConsistencyDiscrepancy(const Registered& a, const Registered& b,
                              const SequenceConsistencyConfig& config) {
  return GrowingDiscrepancy(a, b, config.max_translation_m, config.max_rotation_rad, config);
}

bool Agree(const Registered& a, const Registered& b, const SequenceConsistencyConfig& config) {
  return ConsistencyDiscrepancy(a, b, config) <= 1.0;
}

// Drift-tolerant agreement of a loop outside the main group with one inside (see the config).
bool AgreeUpToDrift(const Registered& a, const Registered& b,
                    const SequenceConsistencyConfig& config) {
  const double separation_m = (a.origin - b.origin).norm();
  const double path_m = std::max(std::abs(a.path_m - b.path_m), separation_m);
  return AgreeWithin(a, b,
                     config.max_translation_m + config.max_translation_per_m * separation_m +
                         config.secondary_translation_per_m * path_m,
                     config.max_rotation_rad + config.max_rotation_per_m * separation_m +
                         config.secondary_rotation_per_m * path_m);
}

// Agreement of loops of two neighbouring submaps (see neighbour_path_m): the same-submap
// bounds, growing as the sequence bounds do.
bool AgreeAsNeighbours(const Registered& a, const Registered& b,
                       const SequenceConsistencyConfig& config) {
  return GrowingDiscrepancy(a, b, config.same_submap_translation_m,
                            config.same_submap_rotation_rad, config) <= 1.0;
}

// Single-linkage groups (connected components of Agree) of the loops `members` of `all`.
std::vector<std::vector<std::size_t>> LinkedGroups(
    const std::vector<Registered, Eigen::aligned_allocator<Registered>>& all,
    const std::vector<std::size_t>& members, const SequenceConsistencyConfig& config) {
  std::vector<std::vector<std::size_t>> groups;
  std::vector<bool> assigned(members.size(), false);
  for (std::size_t seed = 0; seed < members.size(); ++seed) {
    if (assigned[seed]) continue;
    assigned[seed] = true;
    std::vector<std::size_t> group{members[seed]};
    for (std::size_t next = 0; next < group.size(); ++next) {  // breadth-first
      for (std::size_t k = 0; k < members.size(); ++k) {
        if (!assigned[k] && Agree(all[group[next]], all[members[k]], config)) {
          assigned[k] = true;
          group.push_back(members[k]);
        }
      }
    }
    groups.push_back(std::move(group));
  }
  return groups;
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
  if (min_secondary_submaps < 0) {
    return Status::Error("sequence_consistency.min_secondary_submaps must be >= 0");
  }
  if (!(secondary_translation_per_m >= 0.0) || !(secondary_rotation_per_m >= 0.0) ||
      !std::isfinite(secondary_translation_per_m) || !std::isfinite(secondary_rotation_per_m)) {
    return Status::Error("sequence_consistency secondary per-metre bounds must be >= 0");
  }
  if (!(same_submap_translation_m >= 0.0) || !(same_submap_rotation_rad >= 0.0) ||
      !std::isfinite(same_submap_translation_m) || !std::isfinite(same_submap_rotation_rad) ||
      ((same_submap_translation_m > 0.0) != (same_submap_rotation_rad > 0.0))) {
    return Status::Error(
        "sequence_consistency same_submap_translation_m / same_submap_rotation_rad must be "
        ">= 0, both 0 (off) or both > 0");
  }
  if (!(neighbour_path_m >= 0.0) || !std::isfinite(neighbour_path_m)) {
    return Status::Error("sequence_consistency.neighbour_path_m must be >= 0 (0: off)");
  }
  return Status::Ok();
}

Status SequenceGuidanceConfig::Validate() const {
  if (max_gap_submaps < 0) {
    return Status::Error("inter_session.sequence_max_gap_submaps must be >= 0");
  }
  if (max_candidates < 1) {
    return Status::Error("inter_session.sequence_max_candidates must be >= 1");
  }
  if (!(search_radius_m > 0.0)) {
    return Status::Error("inter_session.sequence_search_radius_m must be > 0");
  }
  return Status::Ok();
}

Status InterSessionMatcherConfig::Validate() const {
  Status s = voting.Validate();
  if (!s.ok()) return s;
  if (!(neighbour_distance_m > 0.0)) {
    return Status::Error("inter_session.neighbour_distance_m must be > 0");
  }
  if (num_threads < 1) return Status::Error("inter_session.num_threads must be >= 1");
  s = registration.Validate();
  if (!s.ok()) return s;
  s = consistency.Validate();
  if (!s.ok()) return s;
  return sequence.Validate();
}

StatusOr<InterSessionMatcher> InterSessionMatcher::Create(const InterSessionMatcherConfig& config) {
  Status s = config.Validate();
  if (!s.ok()) return s;
  return InterSessionMatcher(config);
}

namespace {

// A candidate pair to register: current submap index, history submap index, record index.
struct Job {
  std::size_t current = 0;
  std::size_t history = 0;
  std::size_t record = 0;
  bool guided = false;                // registered from `prior` (fine stage only)
  Pose3 prior = Pose3::Identity();    // T_history_current when guided
  GlobalRegistrationResult reg;
  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};
using Jobs = std::vector<Job, Eigen::aligned_allocator<Job>>;
using RegisteredLoops = std::vector<Registered, Eigen::aligned_allocator<Registered>>;

// Registers candidate pairs. Features and fine targets are prepared once per submap (a history
// submap is the target of several current submaps) and kept for later batches; the preparation
// time of a submap is charged to the first pair that needed it.
class PairRegistrar {
 public:
  PairRegistrar(const MapContents& history, const SessionResult& current,
                const GlobalRegistration& registration, int num_threads)
      : history_(history), current_(current), registration_(registration),
        num_threads_(num_threads) {
    path_m_.assign(current.submaps.size(), 0.0);
    for (std::size_t c = 1; c < current.submaps.size(); ++c) {
      path_m_[c] = path_m_[c - 1] + current.submaps[c - 1].length_m;
    }
  }

  // Registers `jobs` and fills their records (status kCandidate when registration accepted
  // them, kRejected with the reason otherwise); returns the accepted ones.
  // Times go to the result's registration_s (without initial guess) or guided_registration_s.
  RegisteredLoops Run(Jobs* jobs, InterSessionMatchResult* result) {
    PrepareMissing(*jobs);
    ParallelFor(jobs->size(), num_threads_, [&](std::size_t i) {
      Job& job = (*jobs)[i];
      const auto& source = prepared_.at({false, job.current});  // read-only lookups
      const auto& target = prepared_.at({true, job.history});
      if (!source || !target) return;
      job.reg = job.guided ? registration_.RegisterFrom(*source, *target, job.prior)
                           : registration_.Register(*source, *target);
    });
    RegisteredLoops registered;
    for (const Job& job : *jobs) {
      LoopRecord& record = result->records[job.record];
      const Submap& cur = current_.submaps[job.current];
      const Submap& hist = history_.submaps[job.history];
      const Key keys[] = {{false, job.current}, {true, job.history}};
      const auto* unprepared = std::find_if(std::begin(keys), std::end(keys),
                                            [&](const Key& key) { return !prepared_.at(key); });
      if (unprepared != std::end(keys)) {
        record.reason = errors_.at(*unprepared);
        continue;
      }
      double prepare_s = 0.0;
      for (const Key& key : keys) {
        if (charged_.insert(key).second) {
          prepare_s += GlobalRegistration::PrepareSeconds(*prepared_.at(key));
        }
      }
      const GlobalRegistrationResult& reg = job.reg;
      (job.guided ? result->guided_registration_s : result->registration_s)
          .push_back(reg.time_s + prepare_s);
      record.overlap_ratio = reg.overlap_ratio;
      record.structure_overlap_ratio = reg.structure_overlap_ratio;
      record.has_pose = true;
      record.T_history_current = reg.T_target_source;
      if (!reg.accepted) {
        record.reason = (job.guided ? "registration from the neighbouring loop's pose: "
                                    : "global registration: ") +
                        reg.reason;
        continue;
      }
      Registered r;
      r.loop.current_submap = cur.id;
      r.loop.history_index = job.history;
      r.loop.T_history_current = reg.T_target_source;
      r.loop.information = reg.information;
      r.loop.vote_proportion = record.vote_proportion;
      r.loop.overlap_ratio = reg.overlap_ratio;
      r.record = job.record;
      r.T_map_session = hist.T_map_submap * reg.T_target_source * cur.T_map_submap.inverse();
      r.origin = cur.T_map_submap.translation();
      r.path_m = path_m_[job.current];
      r.current = job.current;
      registered.push_back(r);
      record.status = LoopStatus::kCandidate;  // decided by the caller
    }
    return registered;
  }

  // The fine targets of the history submaps prepared so far.
  std::map<std::size_t, std::shared_ptr<const SubmapTarget>> HistoryTargets() const {
    std::map<std::size_t, std::shared_ptr<const SubmapTarget>> targets;
    for (const auto& [key, prepared] : prepared_) {
      if (!key.first || !prepared) continue;
      std::shared_ptr<const SubmapTarget> target = GlobalRegistration::FineTarget(*prepared);
      if (target) targets[key.second] = std::move(target);
    }
    return targets;
  }

 private:
  using Key = std::pair<bool, std::size_t>;  // (history side, submap index)

  // Prepares the submaps of `jobs` not prepared yet, with FPFH features where a job registers
  // without initial guess (a submap prepared earlier without them is prepared again).
  void PrepareMissing(const Jobs& jobs) {
    std::map<Key, bool> needs_features;
    for (const Job& job : jobs) {
      for (const Key& key : {Key{false, job.current}, Key{true, job.history}}) {
        needs_features[key] = needs_features[key] || !job.guided;
      }
    }
    std::vector<std::pair<Key, bool>> keys;
    for (const auto& [key, features] : needs_features) {
      const auto found = prepared_.find(key);
      const bool enough = found != prepared_.end() &&
                          (!found->second || !features || featured_.count(key) > 0);
      if (!enough) keys.emplace_back(key, features);
    }
    std::vector<StatusOr<std::shared_ptr<const PreparedSubmap>>> built(
        keys.size(), Status::Error("not run"));
    ParallelFor(keys.size(), num_threads_, [&](std::size_t i) {
      const auto& [key, features] = keys[i];
      const auto& [as_target, index] = key;
      const Submap& submap = as_target ? history_.submaps[index] : current_.submaps[index];
      built[i] = registration_.Prepare(submap.points, as_target, features);
    });
    for (std::size_t i = 0; i < keys.size(); ++i) {
      const Key& key = keys[i].first;
      charged_.erase(key);  // a new preparation is charged to the next pair that uses it
      if (built[i].ok()) {
        prepared_[key] = built[i].value();
        if (keys[i].second) featured_.insert(key);
      } else {
        prepared_[key] = nullptr;
        errors_[key] = (key.first ? "history submap: " : "current submap: ") +
                       built[i].status().message();
      }
    }
  }

  const MapContents& history_;
  const SessionResult& current_;
  const GlobalRegistration& registration_;
  const int num_threads_;
  std::vector<double> path_m_;  // distance driven in the session before each submap
  std::map<Key, std::shared_ptr<const PreparedSubmap>> prepared_;
  std::map<Key, std::string> errors_;
  std::set<Key> featured_;  // prepared with FPFH features
  std::set<Key> charged_;
};

// Rejects the accepted loops that place their current submap apart from all its other loops
// while two of those agree (see same_submap_translation_m). Each loop places the submap by its
// history submap's pose in the map. It runs once on the loops of every stage (registration
// without guess, guided, sequence guidance); RegisterAgainstReferences's own check of one
// submap's registrations sees only one stage's and compares them under the wider group bounds.
void RejectOddLoopsOfOneSubmap(const MapContents& history,
                               const SequenceConsistencyConfig& consistency,
                               InterSessionMatchResult* result) {
  if (consistency.same_submap_translation_m <= 0.0) return;
  SubmapPlacements placements;
  for (const InterSessionLoop& loop : result->loops) {
    SubmapPlacement placement;
    placement.current_submap = loop.current_submap;
    placement.T_map_current =
        history.submaps[loop.history_index].T_map_submap * loop.T_history_current;
    placements.push_back(placement);
  }
  const std::vector<std::size_t> odd = OddPlacementsOfOneSubmap(
      placements, consistency.same_submap_translation_m, consistency.same_submap_rotation_rad);
  for (auto it = odd.rbegin(); it != odd.rend(); ++it) {  // erase from the back
    const InterSessionLoop& loop = result->loops[*it];
    const Submap& target = history.submaps[loop.history_index];
    for (LoopRecord& record : result->records) {
      if (record.status == LoopStatus::kAccepted && record.current_submap == loop.current_submap &&
          record.history_session == target.session &&
          record.history_submap == static_cast<std::int64_t>(target.id)) {
        record.status = LoopStatus::kRejected;
        record.reason =
            "places its submap apart from every other loop of it, which agree with each other";
      }
    }
    result->loops.erase(result->loops.begin() + static_cast<std::ptrdiff_t>(*it));
  }
}

// Sequence consistency: which registered loops are accepted (in the result's loops and
// records; the others' records are rejected with the reason) and T_map_session.
std::vector<bool> DecideConsistency(const RegisteredLoops& registered,
                                    const SequenceConsistencyConfig& consistency,
                                    InterSessionMatchResult* result) {
  // The largest group of loops agreeing with one of them.
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
  // Further groups that agree with the main one up to the drift between them.
  std::vector<std::size_t> outside;
  for (std::size_t j = 0; j < registered.size(); ++j) {
    if (!in_group[j]) outside.push_back(j);
  }
  const std::vector<std::size_t> main_group = enough ? best_group : std::vector<std::size_t>{};
  std::size_t secondary_loops = 0;
  if (!main_group.empty() && consistency.min_secondary_submaps > 0) {
    for (const std::vector<std::size_t>& group : LinkedGroups(registered, outside, consistency)) {
      std::set<std::uint32_t> submaps;
      for (std::size_t j : group) submaps.insert(registered[j].loop.current_submap);
      if (static_cast<int>(group.size()) < consistency.min_group_size ||
          static_cast<int>(submaps.size()) < consistency.min_secondary_submaps) {
        continue;
      }
      // Compared with the main group's loop nearest along the session (least drift between).
      std::size_t g_best = group.front(), m_best = main_group.front();
      double nearest_m = std::numeric_limits<double>::infinity();
      for (std::size_t g : group) {
        for (std::size_t m : main_group) {
          const double d = std::abs(registered[g].path_m - registered[m].path_m);
          if (d < nearest_m) {
            nearest_m = d;
            g_best = g;
            m_best = m;
          }
        }
      }
      if (!AgreeUpToDrift(registered[g_best], registered[m_best], consistency)) continue;
      for (std::size_t j : group) in_group[j] = true;
      secondary_loops += group.size();
    }
  }
  // T_map_session comes from the main group's loop with the largest overlap.
  std::size_t anchor = registered.size();
  for (std::size_t j : main_group) {
    if (anchor == registered.size() ||
        registered[j].loop.overlap_ratio > registered[anchor].loop.overlap_ratio) {
      anchor = j;
    }
  }
  for (std::size_t j = 0; j < registered.size(); ++j) {
    LoopRecord& record = result->records[registered[j].record];
    if (in_group[j]) {
      record.status = LoopStatus::kAccepted;
      result->loops.push_back(registered[j].loop);
    } else {
      record.status = LoopStatus::kRejected;
      record.reason =
          enough ? "inconsistent with the " + std::to_string(best_group.size()) +
                       " agreeing loops" +
                       (secondary_loops > 0 ? " (and " + std::to_string(secondary_loops) +
                                                  " in further groups)"
                                            : std::string())
                 : "too few consistent loops (" + std::to_string(best_group.size()) + " < " +
                       std::to_string(consistency.min_group_size) + ")";
    }
  }
  if (anchor < registered.size()) {
    result->T_map_session = registered[anchor].T_map_session;
    result->aligned = true;
  }
  return in_group;
}

// Sensor positions of the submap's scans in the frame `T_frame_map` * (submap's map frame).
std::vector<Eigen::Vector3d> ScanPositions(const Submap& submap, const Pose3& T_frame_map) {
  Trajectory poses;  // map frame
  AppendScanPoses(submap, &poses);
  std::vector<Eigen::Vector3d> positions;
  for (const StampedPose& scan : poses) positions.push_back(T_frame_map * scan.pose.translation());
  if (positions.empty()) positions.push_back(T_frame_map * submap.T_map_submap.translation());
  return positions;
}

// Share of `a` with a point of `b` within `radius_m` (brute force: ~100 scans per submap).
double ShareNear(const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b,
                 double radius_m) {
  const double r2 = radius_m * radius_m;
  std::size_t near = 0;
  for (const Eigen::Vector3d& p : a) {
    near += std::any_of(b.begin(), b.end(),
                        [&](const Eigen::Vector3d& q) { return (p - q).squaredNorm() <= r2; });
  }
  return a.empty() ? 0.0 : static_cast<double>(near) / static_cast<double>(a.size());
}

// Registers `jobs`, each placed by the accepted loop reference_of_record[job.record], and
// accepts those that agree with that loop under the sequence-consistency bounds. Returns the
// accepted ones.
RegisteredLoops RegisterAgainstReferences(
    Jobs* jobs, const std::map<std::size_t, const Registered*>& reference_of_record,
    const InterSessionMatcherConfig& config, const SessionResult& current,
    const std::string& relation, PairRegistrar* registrar, InterSessionMatchResult* result) {
  RegisteredLoops accepted;
  if (jobs->empty()) return accepted;
  const RegisteredLoops registered = registrar->Run(jobs, result);
  // Registrations of one current submap that agree with their references must also agree with
  // each other: where two do not (two history submaps of one place, each within the bounds
  // that grow with the distance to the reference), only those agreeing with the one nearest
  // its reference stay. Campus seed 2, s01/25 placed by its neighbour: s00/42 1.49 deg and
  // s00/43 0.13 deg from the truth, both within the 1.38 deg that 20 m between the two
  // submaps allows. (RejectOddLoopsOfOneSubmap later holds all the accepted loops of a submap
  // to the tighter same-submap bounds where a majority of them agree.)
  std::map<std::size_t, std::size_t> nearest;  // current submap -> index into `registered`
  std::vector<double> discrepancy(registered.size(), 0.0);
  for (std::size_t j = 0; j < registered.size(); ++j) {
    const Registered& r = registered[j];
    const Registered& ref = *reference_of_record.at(r.record);
    discrepancy[j] = ConsistencyDiscrepancy(r, ref, config.consistency);
    if (discrepancy[j] > 1.0) continue;
    const auto found = nearest.find(r.current);
    if (found == nearest.end() || discrepancy[j] < discrepancy[found->second]) {
      nearest[r.current] = j;
    }
  }
  for (std::size_t j = 0; j < registered.size(); ++j) {
    const Registered& r = registered[j];
    LoopRecord& record = result->records[r.record];
    const Registered& ref = *reference_of_record.at(r.record);
    const std::string placing_submap = std::to_string(current.submaps[ref.current].id);
    if (discrepancy[j] > 1.0) {
      record.status = LoopStatus::kRejected;
      record.reason = "disagrees with the loop of submap " + placing_submap + " that " +
                      relation + " it";
      DependentLoop dependent;
      dependent.loop = r.loop;
      dependent.record = r.record;
      dependent.reference_record = ref.record;
      result->dependent.push_back(dependent);
      continue;
    }
    const Registered& best = registered[nearest.at(r.current)];
    if (&best != &r && !Agree(r, best, config.consistency)) {
      record.status = LoopStatus::kRejected;
      record.reason = "disagrees with the " + relation +
                      " loop of the same submap to history submap " +
                      std::to_string(result->records[best.record].history_submap) +
                      ", which is nearer where submap " + placing_submap + " places it";
      continue;
    }
    record.status = LoopStatus::kAccepted;
    record.reason.clear();
    result->loops.push_back(r.loop);
    accepted.push_back(r);
  }
  return accepted;
}

// Per current submap: its accepted loop with the largest overlap (null: none).
std::vector<const Registered*> BestAcceptedLoops(std::size_t num_submaps,
                                                 const RegisteredLoops& registered,
                                                 const std::vector<bool>& accepted) {
  std::vector<const Registered*> best(num_submaps, nullptr);
  for (std::size_t j = 0; j < registered.size(); ++j) {
    if (!accepted[j]) continue;
    const Registered*& b = best[registered[j].current];
    if (!b || registered[j].loop.overlap_ratio > b->loop.overlap_ratio) b = &registered[j];
  }
  return best;
}

// Where `placement` (an accepted loop's T_map_session) puts current submap `c` relative to
// history submap `h`: the prior T_history_current of a guided registration.
Pose3 PriorOf(const Registered& placement, const Submap& history_submap,
              const Submap& current_submap) {
  return history_submap.T_map_submap.inverse() * placement.T_map_session *
         current_submap.T_map_submap;
}

// One pass of sequence guidance: the candidate pairs of every submap without a loop (and not
// placed before) that an accepted loop within `max_gap_submaps` places.
void PlaceBySequence(const InterSessionMatcherConfig& config, const MapContents& history,
                     const SessionResult& current, const std::vector<const Registered*>& reference,
                     std::vector<bool>* placed_before,
                     std::vector<std::vector<Eigen::Vector3d>>* history_positions_cache,
                     Jobs* jobs_out, std::map<std::size_t, const Registered*>* references_out,
                     InterSessionMatchResult* result) {
  const SequenceGuidanceConfig& sequence = config.sequence;
  const long n = static_cast<long>(current.submaps.size());
  Jobs& jobs = *jobs_out;
  std::map<std::size_t, const Registered*>& reference_of_record = *references_out;
  std::vector<std::vector<Eigen::Vector3d>>& history_positions = *history_positions_cache;
  for (long c = 0; c < n; ++c) {
    if (reference[c] || (*placed_before)[c]) continue;
    // The nearest submap along the session with an accepted loop (ties: larger overlap).
    const Registered* ref = nullptr;
    for (int gap = 1; gap <= sequence.max_gap_submaps && !ref; ++gap) {
      for (const long k : {c - gap, c + gap}) {
        if (k < 0 || k >= n || !reference[k]) continue;
        if (!ref || reference[k]->loop.overlap_ratio > ref->loop.overlap_ratio) {
          ref = reference[k];
        }
      }
    }
    if (!ref) continue;
    (*placed_before)[c] = true;
    const Submap& cur = current.submaps[c];
    const std::vector<Eigen::Vector3d> placed = ScanPositions(cur, ref->T_map_session);
    // (share of the placed scans with a history scan near, history index), best first.
    std::vector<std::pair<double, std::size_t>> nearest;
    for (std::size_t h = 0; h < history.submaps.size(); ++h) {
      if (history.submaps[h].state != SubmapState::kActive) continue;
      if (history_positions[h].empty()) {
        history_positions[h] = ScanPositions(history.submaps[h], Pose3::Identity());
      }
      const double share = ShareNear(placed, history_positions[h], sequence.search_radius_m);
      if (share > 0.0) nearest.emplace_back(-share, h);
    }
    std::sort(nearest.begin(), nearest.end());
    nearest.resize(std::min<std::size_t>(nearest.size(), sequence.max_candidates));
    for (const auto& [share, h] : nearest) {
      (void)share;
      LoopRecord record;
      record.kind = LoopKind::kInterSequence;
      record.current_session = current.session;
      record.current_submap = cur.id;
      record.history_session = history.submaps[h].session;
      record.history_submap = history.submaps[h].id;
      record.status = LoopStatus::kRejected;  // reason and fate: set after registration
      Job job;
      job.current = static_cast<std::size_t>(c);
      job.history = h;
      job.record = result->records.size();
      job.guided = config.guided_candidates;
      job.prior = PriorOf(*ref, history.submaps[h], cur);
      jobs.push_back(job);
      reference_of_record[job.record] = ref;
      result->records.push_back(record);
    }
  }
}

// Sequence guidance (see SequenceGuidanceConfig): loops for the submaps the votes left without
// one, placed by an accepted loop of a neighbour along the session.
void MatchBySequence(const InterSessionMatcherConfig& config, const MapContents& history,
                     const SessionResult& current, const RegisteredLoops& registered,
                     const std::vector<bool>& accepted, PairRegistrar* registrar,
                     InterSessionMatchResult* result) {
  const SequenceGuidanceConfig& sequence = config.sequence;
  std::vector<const Registered*> reference =
      BestAcceptedLoops(current.submaps.size(), registered, accepted);
  std::vector<std::vector<Eigen::Vector3d>> history_positions(history.submaps.size());
  std::vector<bool> placed_before(current.submaps.size(), false);
  // The loops that sequence guidance accepted, references of the next pass (a deque: the
  // references point into it while it grows).
  std::deque<Registered, Eigen::aligned_allocator<Registered>> by_sequence;
  for (;;) {
    Jobs jobs;
    std::map<std::size_t, const Registered*> reference_of_record;
    PlaceBySequence(config, history, current, reference, &placed_before, &history_positions,
                    &jobs, &reference_of_record, result);
    if (jobs.empty()) break;
    const RegisteredLoops accepted_now = RegisterAgainstReferences(
        &jobs, reference_of_record, config, current, "placed", registrar, result);
    if (!sequence.chain || accepted_now.empty()) break;
    for (const Registered& r : accepted_now) {
      by_sequence.push_back(r);
      const Registered*& best = reference[r.current];
      if (!best || r.loop.overlap_ratio > best->loop.overlap_ratio) best = &by_sequence.back();
    }
  }
}

// The current submaps (index -> why) none of whose accepted loops agrees with any loop of its
// neighbours along the session, while loops of two of those neighbours agree with each other
// (see neighbour_path_m). `accepted`: the accepted loops so far (of the submaps not withdrawn
// already). It runs once, before sequence guidance, whose loops follow their neighbours' anyway.
std::map<std::size_t, std::string> SubmapsApartFromNeighbours(
    const std::vector<const Registered*>& accepted, const SequenceConsistencyConfig& consistency,
    const SessionResult& current) {
  std::map<std::size_t, std::string> apart;
  if (consistency.neighbour_path_m <= 0.0 || consistency.same_submap_translation_m <= 0.0) {
    return apart;
  }
  std::map<std::size_t, std::vector<const Registered*>> by_submap;
  for (const Registered* r : accepted) by_submap[r->current].push_back(r);
  const auto any_agree = [&](const std::vector<const Registered*>& a,
                             const std::vector<const Registered*>& b) {
    for (const Registered* x : a) {
      for (const Registered* y : b) {
        if (AgreeAsNeighbours(*x, *y, consistency)) return true;
      }
    }
    return false;
  };
  for (const auto& [c, loops] : by_submap) {
    std::vector<const std::vector<const Registered*>*> neighbours;
    std::string ids;
    bool agrees = false;  // with a loop of a neighbour: not apart
    for (const auto& [other, other_loops] : by_submap) {
      if (agrees || other == c ||
          std::abs(other_loops.front()->path_m - loops.front()->path_m) >
              consistency.neighbour_path_m) {
        continue;
      }
      agrees = any_agree(loops, other_loops);
      neighbours.push_back(&other_loops);
      ids += (ids.empty() ? "" : ", ") + std::to_string(current.submaps[other].id);
    }
    if (agrees) continue;
    bool majority = false;
    for (std::size_t i = 0; i < neighbours.size() && !majority; ++i) {
      for (std::size_t j = i + 1; j < neighbours.size() && !majority; ++j) {
        majority = any_agree(*neighbours[i], *neighbours[j]);
      }
    }
    if (!majority) continue;
    apart[c] = "withdrawn: the loops of submap " + std::to_string(current.submaps[c].id) +
               " place it apart from every loop of its neighbours (submaps " + ids +
               "), which agree with each other; its neighbours' loops place it";
  }
  return apart;
}

// A submap whose guided registration disagreed with its own accepted loop holds two
// registrations that cannot both be right, and nothing says which: every loop of it is
// withdrawn and the groups are decided again without them; sequence guidance then places the
// submap by its neighbours' loops, which arbitrate. (Campus seed 2, s01/25: its first loop,
// to s00/42, was 1.5 deg off in tilt and passed the consistency bounds; the guided one to
// s00/43, 0.017 m / 0.13 deg from the truth, was the one rejected.) So are the submaps whose
// loops all place them apart from their neighbours' (SubmapsApartFromNeighbours). The guided
// loops of the other submaps stay when their reference is still accepted.
void WithdrawSuspectSubmaps(const SequenceConsistencyConfig& consistency,
                            const SessionResult& current, std::size_t dependent_before,
                            const RegisteredLoops& guided_accepted,
                            const std::map<std::size_t, const Registered*>& reference_of_record,
                            RegisteredLoops* registered, std::vector<bool>* in_group,
                            InterSessionMatchResult* result) {
  // current submap -> why its loops are withdrawn. First the submaps whose guided
  // registrations disagreed with their reference (the submap's own loop).
  std::map<std::size_t, std::string> suspect;
  for (std::size_t d = dependent_before; d < result->dependent.size(); ++d) {
    const std::size_t record = result->dependent[d].record;
    const std::size_t c = reference_of_record.at(record)->current;
    suspect.emplace(c, "withdrawn: the registrations of submap " +
                           std::to_string(current.submaps[c].id) + " disagree (history submap " +
                           std::to_string(result->records[record].history_submap) +
                           "); its neighbours' loops place it");
  }
  // Then the submaps apart from their neighbours, judged by the accepted loops of the others.
  std::vector<const Registered*> accepted;
  for (std::size_t j = 0; j < registered->size(); ++j) {
    if ((*in_group)[j] && !suspect.count((*registered)[j].current)) {
      accepted.push_back(&(*registered)[j]);
    }
  }
  for (const Registered& r : guided_accepted) {
    if (!suspect.count(r.current)) accepted.push_back(&r);
  }
  for (auto& [c, why] : SubmapsApartFromNeighbours(accepted, consistency, current)) {
    suspect.emplace(c, std::move(why));
  }
  if (suspect.empty()) return;
  RegisteredLoops kept;
  for (const Registered& r : *registered) {
    if (suspect.count(r.current)) {
      LoopRecord& record = result->records[r.record];
      record.status = LoopStatus::kRejected;
      record.reason = suspect.at(r.current);
    } else {
      kept.push_back(r);
    }
  }
  // The references of the guided loops, by record, before `registered` is replaced.
  std::map<std::size_t, std::size_t> reference_record_of;
  for (const auto& [record, ref] : reference_of_record) reference_record_of[record] = ref->record;
  registered->swap(kept);
  result->loops.clear();
  result->T_map_session = Pose3::Identity();
  result->aligned = false;
  *in_group = DecideConsistency(*registered, consistency, result);
  std::set<std::size_t> accepted_records;
  for (std::size_t j = 0; j < registered->size(); ++j) {
    if ((*in_group)[j]) accepted_records.insert((*registered)[j].record);
  }
  for (const Registered& r : guided_accepted) {
    LoopRecord& record = result->records[r.record];
    if (suspect.count(r.current)) {
      record.status = LoopStatus::kRejected;
      record.reason = suspect.at(r.current);
    } else if (accepted_records.count(reference_record_of.at(r.record))) {
      result->loops.push_back(r.loop);
    } else {
      record.status = LoopStatus::kRejected;
      record.reason = "the loop that guided it fell out of the groups";
    }
  }
}

}  // namespace

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
  // 1. Votes and the candidate pairs to register, in submap order (records keep that order),
  // per current submap in vote order.
  std::vector<Jobs> candidates(current.submaps.size());
  for (std::size_t c = 0; c < current.submaps.size(); ++c) {
    const Submap& cur = current.submaps[c];
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
      } else if (history.submaps[found->second].state != SubmapState::kActive) {
        record.reason = "history submap fused into a later session's";
      } else {
        Job job;
        job.current = c;
        job.history = found->second;
        job.record = result.records.size();
        candidates[c].push_back(job);
      }
      result.records.push_back(record);
    }
  }

  // 2. Registration of the candidate pairs, on config_.num_threads threads, and 3. sequence
  // consistency.
  PairRegistrar registrar(history, current, registration.value(), config_.num_threads);
  RegisteredLoops registered;
  std::vector<bool> in_group;
  if (!config_.guided_candidates) {
    // Every candidate pair without initial guess.
    Jobs jobs;
    for (const Jobs& of_submap : candidates) jobs.insert(jobs.end(), of_submap.begin(), of_submap.end());
    registered = registrar.Run(&jobs, &result);
    in_group = DecideConsistency(registered, config_.consistency, &result);
  } else {
    // Rounds without initial guess: each submap's next candidate in vote order, until the
    // registration accepts one of them or none is left.
    std::vector<std::size_t> next(current.submaps.size(), 0);
    std::vector<bool> has_loop(current.submaps.size(), false);
    auto register_globally = [&](Jobs* jobs) {
      for (const Registered& r : registrar.Run(jobs, &result)) {
        has_loop[r.current] = true;
        registered.push_back(r);
      }
    };
    for (;;) {
      Jobs round;
      for (std::size_t c = 0; c < candidates.size(); ++c) {
        if (!has_loop[c] && next[c] < candidates[c].size()) round.push_back(candidates[c][next[c]++]);
      }
      if (round.empty()) break;
      register_globally(&round);
    }
    in_group = DecideConsistency(registered, config_.consistency, &result);
    // A submap whose loops all fell out of the groups: its other candidates without initial
    // guess too, and the groups are decided again with them.
    std::vector<const Registered*> reference =
        BestAcceptedLoops(current.submaps.size(), registered, in_group);
    Jobs rest;
    for (std::size_t c = 0; c < candidates.size(); ++c) {
      while (!reference[c] && next[c] < candidates[c].size()) rest.push_back(candidates[c][next[c]++]);
    }
    if (!rest.empty()) {
      register_globally(&rest);
      result.loops.clear();
      result.T_map_session = Pose3::Identity();
      result.aligned = false;
      in_group = DecideConsistency(registered, config_.consistency, &result);
      reference = BestAcceptedLoops(current.submaps.size(), registered, in_group);
    }
    // The remaining candidates of a submap with an accepted loop: from where that loop places
    // the submap (fine stage only), kept when they agree with it.
    Jobs guided;
    std::map<std::size_t, const Registered*> reference_of_record;
    for (std::size_t c = 0; c < candidates.size(); ++c) {
      for (; reference[c] && next[c] < candidates[c].size(); ++next[c]) {
        Job job = candidates[c][next[c]];
        job.guided = true;
        job.prior = PriorOf(*reference[c], history.submaps[job.history], current.submaps[c]);
        guided.push_back(job);
        reference_of_record[job.record] = reference[c];
      }
    }
    const std::size_t dependent_before = result.dependent.size();
    const RegisteredLoops guided_accepted = RegisterAgainstReferences(
        &guided, reference_of_record, config_, current, "guided", &registrar, &result);
    WithdrawSuspectSubmaps(config_.consistency, current, dependent_before, guided_accepted,
                           reference_of_record, &registered, &in_group, &result);
  }

  // 4. Sequence guidance for the submaps still without a loop.
  if (result.aligned && config_.sequence.max_gap_submaps > 0) {
    MatchBySequence(config_, history, current, registered, in_group, &registrar, &result);
  }
  RejectOddLoopsOfOneSubmap(history, config_.consistency, &result);
  result.history_targets = registrar.HistoryTargets();
  return result;
}

}  // namespace core
}  // namespace multisession_mapper
