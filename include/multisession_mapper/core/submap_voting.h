// Per-submap voting of the reference paper (section V): turns the per-scan database matches
// of one current submap into inter-session loop closure candidates.
//
// Each scan of the current submap m_i^c that matched votes for the history submap m_j^h of its
// nearest database scan; p_j = (scans voting for m_j^h) / denominator. Then, in this order:
//  1. fewer than `min_matched_scans` matched scans -> undefined (too little evidence);
//  2. max_j p_j > gamma -> that one pair is a candidate (kSingle);
//  3. the top submap's neighbour group: the voted history submaps connected to it under the
//     caller's neighbour relation (e.g. origins within ~30 m, or linked in the pose graph), in
//     vote order; for the smallest m in [2, top_n] whose first m hold > gamma of the votes and
//     are connected among themselves, those m are candidates (kNeighbours);
//  4. otherwise undefined (the reason says when the top-n votes held > gamma but were not on
//     neighbours).
// Step 3 reads the paper's "top n submaps are neighbours" as "the n submaps around the top one":
// with the plain top n by votes, a tiny vote for a far place that ties with (or beats) a
// neighbour's vetoes a group that already holds > gamma (campus s01 submap 19: 31 + 28 + 3 of
// 65 votes on one place, 3 on a place 200 m away ranked third). Votes outside the group are then
// < 1 - gamma by construction, as in the paper's rule.
//
// Denominator (config): the paper's formula divides by the scans in the submap, while the
// paper's text and issue 6 leave scans with "no match" (and failed queries) out of the vote.
// kMatchedScans (default, the behaviour) divides by the matched scans only: a submap
// whose scans partly see new or changed surroundings (dynamics, the paper's failure cases) can
// still become a candidate when every matched scan agrees. kAllScans divides by every scan of
// the submap: stricter, a submap is a candidate only when > gamma of ALL its scans agree.
// Either way, min_matched_scans guards against a decision from a handful of votes.
//
// Neighbour relation: consecutive ids miss the neighbours that loops create (a route that ends
// where it started, or passes a place twice); OriginsWithin (history submap origins within
// ~30 m) is the better default when the map is known. A history route that passes a place
// twice splits the vote between the passes (two passes, two submaps each: four), so such a
// current submap needs a group larger than the paper's n = 3. Default n = 5, measured on the
// simulator's `campus` profile (s01 merged into s00, s02 into both): s01 correct submaps
// 33 -> 37 of 39 overlapping, s02 30 of 34 either way, 0 wrong either way; s01's matching took
// 64 -> 88 s (more candidate pairs to register).
#pragma once

#include <functional>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "multisession_mapper/core/status.h"

namespace multisession_mapper {
namespace core {

/// A history submap: its session and its id within the session.
struct HistorySubmapId {
  std::string session;
  int submap_id = -1;

  bool operator==(const HistorySubmapId& o) const {
    return submap_id == o.submap_id && session == o.session;
  }
  bool operator!=(const HistorySubmapId& o) const { return !(*this == o); }
  bool operator<(const HistorySubmapId& o) const {
    return session != o.session ? session < o.session : submap_id < o.submap_id;
  }
};

/// The database result of one scan of the current submap.
struct ScanVote {
  bool matched = false;     ///< false: "no match" (nearest farther than d_alpha) or failed query
  HistorySubmapId history;  ///< submap of the nearest database scan; ignored when !matched
};

struct SubmapVotingConfig {
  enum class Denominator { kMatchedScans, kAllScans };

  /// Proportion a single submap (or a neighbour group) must exceed (the paper's gamma).
  double gamma = 0.95;
  /// Largest neighbour group considered (the paper's n; 3 in the paper, see the header).
  int top_n = 5;
  /// Fewer matched scans in the current submap -> undefined.
  int min_matched_scans = 5;
  /// See the header comment; kMatchedScans follows issue 6.
  Denominator denominator = Denominator::kMatchedScans;

  /// OK when every field is finite and consistent; otherwise names the bad field.
  Status Validate() const;
};

/// One history submap's share of the vote.
struct VoteProportion {
  HistorySubmapId history;
  int votes = 0;
  double proportion = 0.0;  ///< votes / denominator
};

struct SubmapVoteResult {
  enum class Outcome { kSingle, kNeighbours, kUndefined };

  Outcome outcome = Outcome::kUndefined;
  /// History submaps paired with the current submap (empty when undefined).
  std::vector<HistorySubmapId> candidates;
  /// Every voted history submap, largest proportion first (ties: HistorySubmapId order).
  std::vector<VoteProportion> proportions;
  int scans_total = 0;    ///< scans of the current submap
  int scans_matched = 0;  ///< scans that took part in the vote
  int denominator = 0;    ///< what the proportions were divided by
  std::string reason;     ///< one line for logs and loops/<session>.csv
};

/// "single" / "neighbours" / "undefined".
const char* VoteOutcomeName(SubmapVoteResult::Outcome outcome);

class SubmapVoting {
 public:
  using NeighbourRelation = std::function<bool(const HistorySubmapId&, const HistorySubmapId&)>;

  /// `config` must be valid (see SubmapVotingConfig::Validate); Create() checks it.
  static StatusOr<SubmapVoting> Create(const SubmapVotingConfig& config);

  /// Votes over the scans of one current submap. `are_neighbours` must be symmetric; it is
  /// only called for the top-n step.
  SubmapVoteResult Vote(const std::vector<ScanVote>& scans,
                        const NeighbourRelation& are_neighbours) const;

  /// Neighbour relation "same session and submap ids differ by at most max_id_gap" (consecutive
  /// submaps of a session overlap by construction). Misses the neighbours a loop creates (the
  /// end of a route back at its start): prefer OriginsWithin or Linked when the map is known.
  static NeighbourRelation ConsecutiveIds(int max_id_gap = 1);
  /// Neighbour relation "both origins are known and at most max_distance_m apart" (map frame
  /// positions of the history submap origins, e.g. from the map manifest; ~1.5 x the submap
  /// length, 30 m for 20 m submaps). Submaps of different sessions can be neighbours.
  static NeighbourRelation OriginsWithin(std::map<HistorySubmapId, Eigen::Vector3d> origins_m,
                                         double max_distance_m);
  /// Neighbour relation "linked by one of `links`" (e.g. the odometry and loop edges of the
  /// pose graph), in either direction.
  static NeighbourRelation Linked(
      std::vector<std::pair<HistorySubmapId, HistorySubmapId>> links);

  const SubmapVotingConfig& config() const { return config_; }

 private:
  explicit SubmapVoting(const SubmapVotingConfig& config) : config_(config) {}
  SubmapVotingConfig config_;
};

}  // namespace core
}  // namespace multisession_mapper
