#include <map>

#include <gtest/gtest.h>

#include "multisession_mapper/core/submap_voting.h"

namespace multisession_mapper {
namespace core {
namespace {

using Outcome = SubmapVoteResult::Outcome;

HistorySubmapId H(int id, const std::string& session = "s00") { return {session, id}; }

// `count` matched scans voting for `id`.
void AddVotes(std::vector<ScanVote>* scans, const HistorySubmapId& id, int count) {
  for (int i = 0; i < count; ++i) scans->push_back({true, id});
}
void AddNoMatch(std::vector<ScanVote>* scans, int count) {
  for (int i = 0; i < count; ++i) scans->push_back({false, H(999, "ignored")});
}

SubmapVoting MakeVoting(SubmapVotingConfig config = SubmapVotingConfig()) {
  auto voting = SubmapVoting::Create(config);
  EXPECT_TRUE(voting.ok()) << voting.status().message();
  return voting.value();
}

TEST(SubmapVotingTest, ConfigValidation) {
  SubmapVotingConfig config;
  EXPECT_TRUE(config.Validate().ok());
  EXPECT_DOUBLE_EQ(config.gamma, 0.95);
  EXPECT_EQ(config.top_n, 5);
  config.gamma = 1.0;
  EXPECT_NE(config.Validate().message().find("gamma"), std::string::npos);
  config = SubmapVotingConfig();
  config.top_n = 0;
  EXPECT_FALSE(SubmapVoting::Create(config).ok());
}

TEST(SubmapVotingTest, SingleDominantSubmap) {
  std::vector<ScanVote> scans;
  AddVotes(&scans, H(7), 97);
  AddVotes(&scans, H(30), 3);
  const SubmapVoteResult r = MakeVoting().Vote(scans, SubmapVoting::ConsecutiveIds());
  EXPECT_EQ(r.outcome, Outcome::kSingle);
  ASSERT_EQ(r.candidates.size(), 1u);
  EXPECT_EQ(r.candidates[0], H(7));
  ASSERT_EQ(r.proportions.size(), 2u);
  EXPECT_EQ(r.proportions[0].history, H(7));
  EXPECT_EQ(r.proportions[0].votes, 97);
  EXPECT_DOUBLE_EQ(r.proportions[0].proportion, 0.97);
  EXPECT_DOUBLE_EQ(r.proportions[1].proportion, 0.03);
  EXPECT_EQ(r.scans_total, 100);
  EXPECT_EQ(r.scans_matched, 100);
}

TEST(SubmapVotingTest, ExactlyGammaIsNotEnough) {
  std::vector<ScanVote> scans;
  AddVotes(&scans, H(7), 95);
  AddVotes(&scans, H(40), 5);  // not a neighbour of 7
  const SubmapVoteResult r = MakeVoting().Vote(scans, SubmapVoting::ConsecutiveIds());
  EXPECT_EQ(r.outcome, Outcome::kUndefined);  // "larger than gamma" is strict
  EXPECT_TRUE(r.candidates.empty());
}

TEST(SubmapVotingTest, TopNNeighboursAreAllCandidates) {
  std::vector<ScanVote> scans;
  AddVotes(&scans, H(4), 50);
  AddVotes(&scans, H(5), 30);
  AddVotes(&scans, H(6), 18);  // 4-5-6 chained: connected although 4 and 6 are not adjacent
  AddVotes(&scans, H(20), 2);
  const SubmapVoteResult r = MakeVoting().Vote(scans, SubmapVoting::ConsecutiveIds());
  EXPECT_EQ(r.outcome, Outcome::kNeighbours);
  ASSERT_EQ(r.candidates.size(), 3u);
  EXPECT_EQ(r.candidates[0], H(4));
  EXPECT_EQ(r.candidates[1], H(5));
  EXPECT_EQ(r.candidates[2], H(6));
}

TEST(SubmapVotingTest, SmallestSufficientGroupIsUsed) {
  std::vector<ScanVote> scans;
  AddVotes(&scans, H(4), 60);
  AddVotes(&scans, H(5), 37);  // top 2 already hold 0.97
  AddVotes(&scans, H(40), 3);  // a far tail vote must not veto the group
  const SubmapVoteResult r = MakeVoting().Vote(scans, SubmapVoting::ConsecutiveIds());
  EXPECT_EQ(r.outcome, Outcome::kNeighbours);
  ASSERT_EQ(r.candidates.size(), 2u);
}

TEST(SubmapVotingTest, AFarTailVoteTiedWithANeighbourDoesNotVetoTheGroup) {
  // campus s01 submap 19: 31 and 28 votes for two passes over one place, 3 for a neighbour and
  // 3 for a place 200 m away. The top 3 by votes (the far one wins the tie) are not neighbours;
  // the top submap's neighbour group holds 62 of 65 votes.
  std::map<HistorySubmapId, Eigen::Vector3d> origins;
  origins[H(1)] = Eigen::Vector3d(0, 0, 0);
  origins[H(2)] = Eigen::Vector3d(20, 0, 0);
  origins[H(9)] = Eigen::Vector3d(200, 0, 0);
  origins[H(12)] = Eigen::Vector3d(35, 0, 0);
  std::vector<ScanVote> scans;
  AddVotes(&scans, H(1), 31);
  AddVotes(&scans, H(2), 28);
  AddVotes(&scans, H(9), 3);
  AddVotes(&scans, H(12), 3);
  const SubmapVoteResult r = MakeVoting().Vote(scans, SubmapVoting::OriginsWithin(origins, 30.0));
  ASSERT_EQ(r.proportions[2].history, H(9)) << "the far submap ranks third";
  EXPECT_EQ(r.outcome, Outcome::kNeighbours) << r.reason;
  EXPECT_EQ(r.candidates, (std::vector<HistorySubmapId>{H(1), H(2), H(12)}));
  // Without the neighbour: 59 of 65 = 0.91 in the group, undefined, and the reason says that
  // the concentrated votes were not on neighbours.
  scans.resize(scans.size() - 3);
  AddVotes(&scans, H(9), 3);
  const SubmapVoteResult spread =
      MakeVoting().Vote(scans, SubmapVoting::OriginsWithin(origins, 30.0));
  EXPECT_EQ(spread.outcome, Outcome::kUndefined);
  EXPECT_NE(spread.reason.find("not neighbours"), std::string::npos) << spread.reason;
}

TEST(SubmapVotingTest, NonNeighboursAreRejected) {
  std::vector<ScanVote> scans;
  AddVotes(&scans, H(4), 60);
  AddVotes(&scans, H(12), 39);  // sum 0.99 but submaps 4 and 12 are far apart
  AddVotes(&scans, H(30), 1);
  const SubmapVoteResult r = MakeVoting().Vote(scans, SubmapVoting::ConsecutiveIds());
  EXPECT_EQ(r.outcome, Outcome::kUndefined);
  EXPECT_TRUE(r.candidates.empty());
  EXPECT_NE(r.reason.find("not neighbours"), std::string::npos) << r.reason;
  // Same ids in different sessions are not neighbours either.
  scans.clear();
  AddVotes(&scans, H(4, "s00"), 60);
  AddVotes(&scans, H(5, "s01"), 40);
  EXPECT_EQ(MakeVoting().Vote(scans, SubmapVoting::ConsecutiveIds()).outcome,
            Outcome::kUndefined);
  // A caller's relation (e.g. linked in the pose graph) decides.
  const auto linked = [](const HistorySubmapId& a, const HistorySubmapId& b) {
    return (a.submap_id == 4 && b.submap_id == 12) || (a.submap_id == 12 && b.submap_id == 4);
  };
  scans.clear();
  AddVotes(&scans, H(4), 60);
  AddVotes(&scans, H(12), 40);
  EXPECT_EQ(MakeVoting().Vote(scans, linked).outcome, Outcome::kNeighbours);
}

TEST(SubmapVotingTest, LoopNeighboursByOriginDistanceOrGraphLinks) {
  // The end of a history route (submap 12) comes back to its start (submap 0).
  std::vector<ScanVote> scans;
  AddVotes(&scans, H(0), 80);
  AddVotes(&scans, H(12), 20);
  EXPECT_EQ(MakeVoting().Vote(scans, SubmapVoting::ConsecutiveIds()).outcome,
            Outcome::kUndefined);
  std::map<HistorySubmapId, Eigen::Vector3d> origins;
  origins[H(0)] = Eigen::Vector3d(0, 0, 0);
  origins[H(6)] = Eigen::Vector3d(100, 0, 0);
  origins[H(12)] = Eigen::Vector3d(12, 15, 0);
  const auto by_distance = SubmapVoting::OriginsWithin(origins, 30.0);
  EXPECT_TRUE(by_distance(H(12), H(0)));
  EXPECT_FALSE(by_distance(H(0), H(6)));
  EXPECT_FALSE(by_distance(H(0), H(7)));  // unknown origin
  EXPECT_EQ(MakeVoting().Vote(scans, by_distance).outcome, Outcome::kNeighbours);
  const auto linked = SubmapVoting::Linked({{H(12), H(0)}, {H(0), H(1)}});
  EXPECT_TRUE(linked(H(0), H(12)));
  EXPECT_TRUE(linked(H(1), H(0)));
  EXPECT_FALSE(linked(H(1), H(12)));
  EXPECT_EQ(MakeVoting().Vote(scans, linked).outcome, Outcome::kNeighbours);
  // Far-apart submaps stay rejected.
  scans.clear();
  AddVotes(&scans, H(0), 60);
  AddVotes(&scans, H(6), 40);
  EXPECT_EQ(MakeVoting().Vote(scans, by_distance).outcome, Outcome::kUndefined);
}

TEST(SubmapVotingTest, SpreadVotesAreUndefined) {
  std::vector<ScanVote> scans;
  AddVotes(&scans, H(4), 40);
  AddVotes(&scans, H(5), 30);
  AddVotes(&scans, H(6), 20);  // top 3 sum 0.9 <= gamma
  AddVotes(&scans, H(7), 10);
  SubmapVotingConfig n3;
  n3.top_n = 3;  // the paper's n
  const SubmapVoteResult r = MakeVoting(n3).Vote(scans, SubmapVoting::ConsecutiveIds());
  EXPECT_EQ(r.outcome, Outcome::kUndefined);
  EXPECT_EQ(r.proportions.size(), 4u);
  EXPECT_DOUBLE_EQ(r.proportions[0].proportion, 0.4);
  // The default n = 5 takes the fourth neighbour in (two passes over a place, two submaps each).
  const SubmapVoteResult r5 = MakeVoting().Vote(scans, SubmapVoting::ConsecutiveIds());
  EXPECT_EQ(r5.outcome, Outcome::kNeighbours);
  EXPECT_EQ(r5.candidates.size(), 4u);
  // Spread over more than five neighbours it stays undefined.
  scans.clear();
  for (int id = 0; id < 10; ++id) AddVotes(&scans, H(id), 10);
  EXPECT_EQ(MakeVoting().Vote(scans, SubmapVoting::ConsecutiveIds()).outcome,
            Outcome::kUndefined);
}

TEST(SubmapVotingTest, NoMatchScansAreLeftOutOfTheVote) {
  std::vector<ScanVote> scans;
  AddVotes(&scans, H(7), 40);
  AddNoMatch(&scans, 60);
  // Default (issue 6): p = 40 / 40 matched scans -> candidate.
  const SubmapVoteResult r = MakeVoting().Vote(scans, SubmapVoting::ConsecutiveIds());
  EXPECT_EQ(r.outcome, Outcome::kSingle);
  EXPECT_EQ(r.scans_total, 100);
  EXPECT_EQ(r.scans_matched, 40);
  EXPECT_EQ(r.denominator, 40);
  ASSERT_EQ(r.proportions.size(), 1u);  // the no-match scans voted for nobody
  EXPECT_DOUBLE_EQ(r.proportions[0].proportion, 1.0);
  // The paper's formula read literally: p = 40 / 100 scans -> undefined.
  SubmapVotingConfig config;
  config.denominator = SubmapVotingConfig::Denominator::kAllScans;
  const SubmapVoteResult all = MakeVoting(config).Vote(scans, SubmapVoting::ConsecutiveIds());
  EXPECT_EQ(all.outcome, Outcome::kUndefined);
  EXPECT_EQ(all.denominator, 100);
  EXPECT_DOUBLE_EQ(all.proportions[0].proportion, 0.4);
}

TEST(SubmapVotingTest, TooFewMatchedScansAreUndefined) {
  std::vector<ScanVote> scans;
  AddVotes(&scans, H(7), 4);  // min_matched_scans = 5
  AddNoMatch(&scans, 50);
  const SubmapVoteResult r = MakeVoting().Vote(scans, SubmapVoting::ConsecutiveIds());
  EXPECT_EQ(r.outcome, Outcome::kUndefined);
  EXPECT_EQ(r.proportions.size(), 1u);
  const SubmapVoteResult empty = MakeVoting().Vote({}, SubmapVoting::ConsecutiveIds());
  EXPECT_EQ(empty.outcome, Outcome::kUndefined);
  EXPECT_TRUE(empty.proportions.empty());
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
