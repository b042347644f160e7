// What LoopCandidatesDisplay draws for a LoopCandidateArray (src/rviz/loop_candidate_visuals).
#include "loop_candidate_visuals.h"

#include <limits>

#include <gtest/gtest.h>

namespace multisession_mapper {
namespace rviz_plugins {
namespace {

geometry_msgs::Point P(double x, double y, double z) {
  geometry_msgs::Point p;
  p.x = x;
  p.y = y;
  p.z = z;
  return p;
}

LoopCandidate Candidate(uint8_t status, const std::string& history_session, float vote,
                        float overlap) {
  LoopCandidate c;
  c.current_session = "s01";
  c.current_submap = 4;
  c.history_session = history_session;
  c.history_submap = history_session.empty() ? 0 : 7;
  c.status = status;
  c.vote_proportion = vote;
  c.overlap_ratio = overlap;
  return c;
}

constexpr std::array<bool, kNumLoopStatuses> kShowAll = {true, true, true, true};

// One candidate of every status: three segments and one marker, labels carry the numbers.
TEST(LoopCandidateVisualsTest, OneVisualPerStatus) {
  LoopCandidateArray msg;
  msg.candidates = {Candidate(LoopCandidate::CANDIDATE, "s00", 0.5f, 0.f),
                    Candidate(LoopCandidate::ACCEPTED, "s00", 0.62f, 0.48f),
                    Candidate(LoopCandidate::REJECTED, "s00", 0.3f, 0.1f),
                    Candidate(LoopCandidate::UNDEFINED, "", 0.2f, 0.f)};
  msg.current_origins = {P(1, 2, 3), P(4, 5, 6), P(7, 8, 9), P(10, 11, 12)};
  msg.history_origins = {P(-1, 0, 0), P(-2, 0, 0), P(-3, 0, 0), P(0, 0, 0)};

  const LoopVisualList list = BuildLoopVisuals(msg, kShowAll);
  ASSERT_EQ(list.visuals.size(), 4u);
  EXPECT_EQ(list.num_invalid, 0);
  for (int s = 0; s < kNumLoopStatuses; ++s) EXPECT_EQ(list.count_by_status[s], 1) << s;

  // Drawing order: rejected, undefined, candidate, accepted (accepted on top).
  EXPECT_EQ(list.visuals[0].status, LoopCandidate::REJECTED);
  EXPECT_EQ(list.visuals[1].status, LoopCandidate::UNDEFINED);
  EXPECT_EQ(list.visuals[2].status, LoopCandidate::CANDIDATE);
  const LoopVisual& accepted = list.visuals[3];
  EXPECT_EQ(accepted.status, LoopCandidate::ACCEPTED);
  EXPECT_TRUE(accepted.has_segment);
  EXPECT_DOUBLE_EQ(accepted.current_origin.x, 4.0);
  EXPECT_DOUBLE_EQ(accepted.history_origin.x, -2.0);
  EXPECT_EQ(accepted.label, "s01:4 -> s00:7\nvote 0.62  overlap 0.48");

  const LoopVisual& undefined = list.visuals[1];
  EXPECT_FALSE(undefined.has_segment);
  EXPECT_DOUBLE_EQ(undefined.current_origin.z, 12.0);
  EXPECT_EQ(undefined.label, "s01:4 undefined\nvote 0.20");
}

// Within a status the message order is kept.
TEST(LoopCandidateVisualsTest, DrawOrderIsStableWithinAStatus) {
  LoopCandidateArray msg;
  msg.candidates = {Candidate(LoopCandidate::ACCEPTED, "s00", 0.6f, 0.5f),
                    Candidate(LoopCandidate::REJECTED, "s00", 0.3f, 0.1f),
                    Candidate(LoopCandidate::ACCEPTED, "s00", 0.7f, 0.4f)};
  msg.current_origins = {P(0, 0, 0), P(1, 0, 0), P(2, 0, 0)};
  msg.history_origins = {P(0, 1, 0), P(1, 1, 0), P(2, 1, 0)};

  const LoopVisualList list = BuildLoopVisuals(msg, kShowAll);
  ASSERT_EQ(list.visuals.size(), 3u);
  EXPECT_DOUBLE_EQ(list.visuals[0].current_origin.x, 1.0);
  EXPECT_DOUBLE_EQ(list.visuals[1].current_origin.x, 0.0);
  EXPECT_DOUBLE_EQ(list.visuals[2].current_origin.x, 2.0);
}

// Hidden statuses are counted but not drawn.
TEST(LoopCandidateVisualsTest, HiddenStatusesAreCountedNotDrawn) {
  LoopCandidateArray msg;
  msg.candidates = {Candidate(LoopCandidate::ACCEPTED, "s00", 0.6f, 0.5f),
                    Candidate(LoopCandidate::REJECTED, "s00", 0.3f, 0.1f),
                    Candidate(LoopCandidate::REJECTED, "s00", 0.3f, 0.1f)};
  msg.current_origins = {P(0, 0, 0), P(1, 0, 0), P(2, 0, 0)};
  msg.history_origins = {P(0, 1, 0), P(1, 1, 0), P(2, 1, 0)};

  const LoopVisualList list =
      BuildLoopVisuals(msg, {true, true, /*rejected=*/false, true});
  ASSERT_EQ(list.visuals.size(), 1u);
  EXPECT_EQ(list.visuals[0].status, LoopCandidate::ACCEPTED);
  EXPECT_EQ(list.count_by_status[LoopCandidate::REJECTED], 2);
}

// Missing or non-finite origins and unknown statuses are reported, never drawn.
TEST(LoopCandidateVisualsTest, InvalidCandidatesAreSkipped) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  LoopCandidateArray msg;
  msg.candidates = {Candidate(LoopCandidate::ACCEPTED, "s00", 0.6f, 0.5f),   // NaN current
                    Candidate(LoopCandidate::ACCEPTED, "s00", 0.6f, 0.5f),   // Inf history
                    Candidate(17, "s00", 0.6f, 0.5f),                        // unknown status
                    Candidate(LoopCandidate::ACCEPTED, "s00", 0.6f, 0.5f),   // valid
                    Candidate(LoopCandidate::ACCEPTED, "s00", 0.6f, 0.5f)};  // no origins
  msg.current_origins = {P(nan, 0, 0), P(0, 0, 0), P(0, 0, 0), P(3, 0, 0)};
  msg.history_origins = {P(0, 0, 0), P(0, inf, 0), P(0, 0, 0), P(3, 1, 0)};

  const LoopVisualList list = BuildLoopVisuals(msg, kShowAll);
  ASSERT_EQ(list.visuals.size(), 1u);
  EXPECT_DOUBLE_EQ(list.visuals[0].current_origin.x, 3.0);
  EXPECT_EQ(list.num_invalid, 4);
  EXPECT_EQ(list.count_by_status[LoopCandidate::ACCEPTED], 1);
}

// An UNDEFINED candidate needs no history origin, even when history_origins is empty.
TEST(LoopCandidateVisualsTest, UndefinedNeedsNoHistoryOrigin) {
  LoopCandidateArray msg;
  msg.candidates = {Candidate(LoopCandidate::UNDEFINED, "", 0.1f, 0.f)};
  msg.current_origins = {P(5, 5, 0)};

  const LoopVisualList list = BuildLoopVisuals(msg, kShowAll);
  ASSERT_EQ(list.visuals.size(), 1u);
  EXPECT_FALSE(list.visuals[0].has_segment);
  EXPECT_EQ(list.num_invalid, 0);
}

TEST(LoopCandidateVisualsTest, EmptyMessage) {
  const LoopVisualList list = BuildLoopVisuals(LoopCandidateArray(), kShowAll);
  EXPECT_TRUE(list.visuals.empty());
  EXPECT_EQ(list.num_invalid, 0);
}

}  // namespace
}  // namespace rviz_plugins
}  // namespace multisession_mapper
