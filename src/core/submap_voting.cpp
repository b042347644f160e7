#include "multisession_mapper/core/submap_voting.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <map>
#include <sstream>

namespace multisession_mapper {
namespace core {
namespace {

// Which of the nodes are connected to the first one under `are_neighbours` (through any of
// the nodes). `nodes` is not empty.
std::vector<bool> ReachableFromFirst(const std::vector<HistorySubmapId>& nodes,
                                     const SubmapVoting::NeighbourRelation& are_neighbours) {
  std::vector<bool> reached(nodes.size(), false);
  std::vector<std::size_t> stack = {0};
  reached[0] = true;
  while (!stack.empty()) {
    const std::size_t a = stack.back();
    stack.pop_back();
    for (std::size_t b = 0; b < nodes.size(); ++b) {
      if (!reached[b] && are_neighbours(nodes[a], nodes[b])) {
        reached[b] = true;
        stack.push_back(b);
      }
    }
  }
  return reached;
}

// True when the nodes form one connected component under `are_neighbours`.
bool Connected(const std::vector<HistorySubmapId>& nodes,
               const SubmapVoting::NeighbourRelation& are_neighbours) {
  if (nodes.size() < 2) return true;
  const std::vector<bool> reached = ReachableFromFirst(nodes, are_neighbours);
  return std::all_of(reached.begin(), reached.end(), [](bool r) { return r; });
}

std::string Describe(const HistorySubmapId& id) {
  return id.session + ":" + std::to_string(id.submap_id);
}

}  // namespace

Status SubmapVotingConfig::Validate() const {
  if (!std::isfinite(gamma) || gamma <= 0.0 || gamma >= 1.0) {
    return Status::Error("submap_voting.gamma must be in (0, 1), got " + std::to_string(gamma));
  }
  if (top_n < 1 || top_n > 100) {
    return Status::Error("submap_voting.top_n must be in [1, 100], got " + std::to_string(top_n));
  }
  if (min_matched_scans < 1) {
    return Status::Error("submap_voting.min_matched_scans must be >= 1, got " +
                         std::to_string(min_matched_scans));
  }
  return Status::Ok();
}

const char* VoteOutcomeName(SubmapVoteResult::Outcome outcome) {
  switch (outcome) {
    case SubmapVoteResult::Outcome::kSingle:
      return "single";
    case SubmapVoteResult::Outcome::kNeighbours:
      return "neighbours";
    case SubmapVoteResult::Outcome::kUndefined:
      return "undefined";
  }
  return "unknown";
}

StatusOr<SubmapVoting> SubmapVoting::Create(const SubmapVotingConfig& config) {
  Status status = config.Validate();
  if (!status.ok()) return status;
  return SubmapVoting(config);
}

SubmapVoteResult SubmapVoting::Vote(const std::vector<ScanVote>& scans,
                                    const NeighbourRelation& are_neighbours) const {
  SubmapVoteResult result;
  result.scans_total = static_cast<int>(scans.size());
  std::map<HistorySubmapId, int> votes;
  for (const ScanVote& scan : scans) {
    if (!scan.matched) continue;
    ++votes[scan.history];
    ++result.scans_matched;
  }
  result.denominator = config_.denominator == SubmapVotingConfig::Denominator::kMatchedScans
                           ? result.scans_matched
                           : result.scans_total;
  for (const auto& [id, count] : votes) {
    result.proportions.push_back(
        {id, count, result.denominator > 0 ? double(count) / result.denominator : 0.0});
  }
  std::stable_sort(result.proportions.begin(), result.proportions.end(),
                   [](const VoteProportion& a, const VoteProportion& b) {
                     return a.votes > b.votes;  // map order breaks ties deterministically
                   });

  if (result.scans_matched < config_.min_matched_scans) {
    result.reason = "only " + std::to_string(result.scans_matched) + " matched scans (< " +
                    std::to_string(config_.min_matched_scans) + ")";
    return result;
  }
  const VoteProportion& top = result.proportions.front();
  if (top.proportion > config_.gamma) {
    result.outcome = SubmapVoteResult::Outcome::kSingle;
    result.candidates = {top.history};
    std::ostringstream reason;
    reason << "p(" << Describe(top.history) << ") = " << top.proportion << " > gamma";
    result.reason = reason.str();
    return result;
  }
  // Step 3: the top submap's neighbour group (the voted submaps connected to it), in vote
  // order, up to top_n of them.
  std::vector<const VoteProportion*> group = {&top};
  if (are_neighbours) {
    std::vector<HistorySubmapId> voted;
    for (const VoteProportion& p : result.proportions) voted.push_back(p.history);
    const std::vector<bool> in_group = ReachableFromFirst(voted, are_neighbours);
    for (std::size_t i = 1; i < result.proportions.size(); ++i) {
      if (in_group[i]) group.push_back(&result.proportions[i]);
    }
  }
  const int max_group = std::min<int>(config_.top_n, static_cast<int>(group.size()));
  double sum = top.proportion;
  for (int m = 2; m <= max_group; ++m) {
    sum += group[static_cast<std::size_t>(m - 1)]->proportion;
    if (sum <= config_.gamma) continue;
    std::vector<HistorySubmapId> candidates;
    for (int i = 0; i < m; ++i) candidates.push_back(group[static_cast<std::size_t>(i)]->history);
    // The first m of the group need not be connected among themselves (a chain through a
    // submap with fewer votes); then a larger m may be.
    if (!Connected(candidates, are_neighbours)) continue;
    std::ostringstream reason;
    reason << "neighbours of " << Describe(top.history) << ": top " << m << " sum " << sum
           << " > gamma";
    result.outcome = SubmapVoteResult::Outcome::kNeighbours;
    result.candidates = std::move(candidates);
    result.reason = reason.str();
    return result;
  }
  // Undefined. Say whether the votes were concentrated but on places that are not neighbours.
  double top_sum = 0.0;
  const int top_m = std::min<int>(config_.top_n, static_cast<int>(result.proportions.size()));
  for (int i = 0; i < top_m; ++i) top_sum += result.proportions[static_cast<std::size_t>(i)].proportion;
  std::ostringstream reason;
  reason << "largest p = " << top.proportion << ", neighbour group of " << Describe(top.history)
         << " (" << max_group << " of " << group.size() << ") sum " << sum << " <= gamma";
  if (top_sum > config_.gamma) reason << "; top " << top_m << " sum " << top_sum << " but not neighbours";
  result.reason = reason.str();
  return result;
}

SubmapVoting::NeighbourRelation SubmapVoting::ConsecutiveIds(int max_id_gap) {
  return [max_id_gap](const HistorySubmapId& a, const HistorySubmapId& b) {
    return a.session == b.session && std::abs(a.submap_id - b.submap_id) <= max_id_gap;
  };
}

SubmapVoting::NeighbourRelation SubmapVoting::OriginsWithin(
    std::map<HistorySubmapId, Eigen::Vector3d> origins_m, double max_distance_m) {
  return [origins = std::move(origins_m), max_distance_m](const HistorySubmapId& a,
                                                          const HistorySubmapId& b) {
    const auto ia = origins.find(a);
    const auto ib = origins.find(b);
    if (ia == origins.end() || ib == origins.end()) return false;
    return (ia->second - ib->second).norm() <= max_distance_m;
  };
}

SubmapVoting::NeighbourRelation SubmapVoting::Linked(
    std::vector<std::pair<HistorySubmapId, HistorySubmapId>> links) {
  for (auto& link : links) {
    if (link.second < link.first) std::swap(link.first, link.second);
  }
  std::sort(links.begin(), links.end());
  return [links = std::move(links)](const HistorySubmapId& a, const HistorySubmapId& b) {
    const auto key = b < a ? std::make_pair(b, a) : std::make_pair(a, b);
    return std::binary_search(links.begin(), links.end(), key);
  };
}

}  // namespace core
}  // namespace multisession_mapper
