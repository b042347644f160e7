#include <map>
#include <string>

#include <gtest/gtest.h>

#include "multisession_mapper/core/dependent_loops.h"
#include "multisession_mapper/core/se3.h"

namespace multisession_mapper {
namespace core {
namespace {

using DependentLoops = std::vector<DependentLoop, Eigen::aligned_allocator<DependentLoop>>;

LoopRecord Record(std::uint32_t current, std::int64_t history, LoopStatus status,
                  const std::string& reason) {
  LoopRecord r;
  r.kind = LoopKind::kInter;
  r.current_session = "s02";
  r.current_submap = current;
  r.history_session = "s01";
  r.history_submap = history;
  r.status = status;
  r.reason = reason;
  r.has_pose = true;
  return r;
}

DependentLoop Dependent(std::size_t record, std::size_t reference, std::uint32_t current,
                        std::size_t history, const Pose3& T_history_current) {
  DependentLoop d;
  d.record = record;
  d.reference_record = reference;
  d.loop.current_submap = current;
  d.loop.history_index = history;
  d.loop.T_history_current = T_history_current;
  return d;
}

// The graph's placement of (current submap, history index) pairs; a pair it does not know is
// "not in the graph".
struct Placements {
  std::map<std::pair<std::uint32_t, std::size_t>, Pose3> poses;
  GraphPlacement Function() const {
    return [this](const InterSessionLoop& loop, Pose3* T) {
      const auto it = poses.find({loop.current_submap, loop.history_index});
      if (it == poses.end()) return false;
      *T = it->second;
      return true;
    };
  }
};

// The seed-2 case: submap 51's loop is 1 m off and was rejected by the graph; the loops of 51
// (a second candidate, guided by it) and 52 (placed by it) were rejected for disagreeing.
class DependentLoopsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    records_.push_back(Record(51, 50, LoopStatus::kRejected,
                              "rejected by the joint pose graph (inconsistent)"));  // 0
    records_.push_back(Record(51, 48, LoopStatus::kRejected,
                              "disagrees with the loop of submap 51 that guided it"));  // 1
    records_.push_back(Record(52, 48, LoopStatus::kRejected,
                              "disagrees with the loop of submap 51 that placed it"));  // 2
    records_.push_back(Record(40, 30, LoopStatus::kAccepted, ""));  // 3, a reference that stands
    records_.push_back(Record(41, 30, LoopStatus::kRejected,
                              "disagrees with the loop of submap 40 that guided it"));  // 4
    true_51_48_ = se3::FromXyzRpy(7.67, -1.90, 0.02, 0.0, 0.0, 0.84);
    true_52_48_ = se3::FromXyzRpy(4.24, 3.69, 0.05, 0.0, 0.0, 1.58);
    dependent_.push_back(Dependent(1, 0, 51, 7, true_51_48_));
    dependent_.push_back(Dependent(2, 0, 52, 7, true_52_48_));
    dependent_.push_back(Dependent(4, 3, 41, 3, se3::FromXyzRpy(1.0, 0.0, 0.0, 0.0, 0.0, 0.0)));
  }

  LoopRecords records_;
  DependentLoops dependent_;
  Pose3 true_51_48_, true_52_48_;
};

TEST_F(DependentLoopsTest, LoopsAgreeingWithTheGraphAreAcceptedOnceTheirReferenceIsRejected) {
  Placements graph;
  // The graph (without the wrong loop) puts every pair 0.3 m / 0.01 rad from its loop.
  graph.poses[{51, 7}] = true_51_48_ * se3::FromXyzRpy(0.3, 0.0, 0.0, 0.0, 0.0, 0.01);
  graph.poses[{52, 7}] = true_52_48_ * se3::FromXyzRpy(0.0, -0.3, 0.0, 0.0, 0.0, -0.01);
  graph.poses[{41, 3}] = se3::FromXyzRpy(1.0, 0.0, 0.0, 0.0, 0.0, 0.0);
  const std::vector<std::size_t> accepted =
      RejudgeDependentLoops(dependent_, graph.Function(), DependentLoopBounds(), &records_);
  // Only submap 52's loop, which submap 51's rejected loop had placed.
  ASSERT_EQ(accepted, (std::vector<std::size_t>{1}));
  EXPECT_EQ(records_[2].status, LoopStatus::kAccepted);
  EXPECT_NE(records_[2].reason.find("accepted when judged again"), std::string::npos)
      << records_[2].reason;
  EXPECT_NE(records_[2].reason.find("submap 51"), std::string::npos) << records_[2].reason;
  // Submap 51's own second loop stays out: its two registrations disagree, so the submap is
  // suspect whichever of them the graph rejected.
  EXPECT_EQ(records_[1].status, LoopStatus::kRejected);
  EXPECT_NE(records_[1].reason.find("that guided it (not judged again"), std::string::npos)
      << records_[1].reason;
  // Submap 41's reference still stands, so the matcher's rejection stands too.
  EXPECT_EQ(records_[4].status, LoopStatus::kRejected);
  EXPECT_EQ(records_[4].reason, "disagrees with the loop of submap 40 that guided it");
  EXPECT_EQ(records_[0].status, LoopStatus::kRejected);  // the wrong loop itself
  EXPECT_EQ(records_[3].status, LoopStatus::kAccepted);
}

TEST_F(DependentLoopsTest, LoopsBeyondTheBoundsOrOutsideTheGraphStayRejected) {
  Placements graph;
  // 52's loop 0.03 rad from the graph (bound 0.02 rad); nothing for the pair (41, 3).
  graph.poses[{51, 7}] = true_51_48_;
  graph.poses[{52, 7}] = true_52_48_ * se3::FromXyzRpy(0.0, 0.0, 0.0, 0.0, 0.0, 0.03);
  records_[3].status = LoopStatus::kRejected;  // now the reference of 41 is rejected too
  dependent_.push_back(Dependent(99, 0, 52, 7, true_52_48_));  // record out of range
  LoopRecords before = records_;
  EXPECT_TRUE(
      RejudgeDependentLoops(dependent_, graph.Function(), DependentLoopBounds(), &records_)
          .empty());
  for (std::size_t i : {1, 2, 4}) EXPECT_EQ(records_[i].status, LoopStatus::kRejected) << i;
  EXPECT_NE(records_[2].reason.find("that placed it (judged again:"), std::string::npos)
      << records_[2].reason;
  EXPECT_NE(records_[2].reason.find("0.030000 rad"), std::string::npos) << records_[2].reason;
  EXPECT_EQ(records_[4].reason, before[4].reason);  // not in the graph: not judged

  // Wider bounds accept it; the same-submap loop stays out whatever the bounds.
  DependentLoopBounds wide;
  wide.max_rotation_rad = 0.04;
  records_ = before;
  EXPECT_EQ(RejudgeDependentLoops(dependent_, graph.Function(), wide, &records_),
            (std::vector<std::size_t>{1}));
  EXPECT_EQ(records_[1].status, LoopStatus::kRejected);
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
