#include "multisession_mapper/core/submap_loop_agreement.h"

#include <cmath>
#include <vector>

#include <gtest/gtest.h>

#include "multisession_mapper/core/se3.h"

namespace multisession_mapper {
namespace core {
namespace {

constexpr double kDeg = M_PI / 180.0;
// The defaults of SequenceConsistencyConfig::same_submap_*.
constexpr double kMaxT = 0.2;
constexpr double kMaxR = 0.006;

SubmapPlacement At(std::uint32_t submap, double x, double y, double yaw_deg) {
  SubmapPlacement p;
  p.current_submap = submap;
  p.T_map_current = se3::FromXyzRpy(x, y, 1.5, 0.0, 0.0, yaw_deg * kDeg);
  return p;
}

TEST(SubmapLoopAgreementTest, TheLoopApartFromTwoAgreeingOnesIsOdd) {
  // Campus seed 3, s01/17: two loops within 0.04 m / 0.08 deg of each other, a third
  // 0.31-0.35 m / 0.43-0.52 deg from them.
  const SubmapPlacements p = {At(17, 10.0, 5.0, 30.0), At(17, 10.03, 5.02, 30.08),
                              At(17, 10.3, 5.15, 30.5)};
  EXPECT_EQ(OddPlacementsOfOneSubmap(p, kMaxT, kMaxR), std::vector<std::size_t>({2}));
}

TEST(SubmapLoopAgreementTest, RotationAloneMakesALoopOdd) {
  const SubmapPlacements p = {At(3, 0.0, 0.0, 0.0), At(3, 0.05, 0.0, 0.1),
                              At(3, 0.0, 0.05, 0.45)};
  EXPECT_EQ(OddPlacementsOfOneSubmap(p, kMaxT, kMaxR), std::vector<std::size_t>({2}));
  // Within the bounds (0.34 deg) it stays.
  const SubmapPlacements q = {At(3, 0.0, 0.0, 0.0), At(3, 0.05, 0.0, 0.1),
                              At(3, 0.0, 0.05, 0.3)};
  EXPECT_TRUE(OddPlacementsOfOneSubmap(q, kMaxT, kMaxR).empty());
}

TEST(SubmapLoopAgreementTest, NoMajorityNoOddLoop) {
  // Two loops that disagree: nothing tells which one is wrong.
  const SubmapPlacements two = {At(1, 0.0, 0.0, 0.0), At(1, 1.0, 0.0, 0.0)};
  EXPECT_TRUE(OddPlacementsOfOneSubmap(two, kMaxT, kMaxR).empty());
  // Three that all disagree.
  const SubmapPlacements three = {At(1, 0.0, 0.0, 0.0), At(1, 0.5, 0.0, 0.0),
                                  At(1, 1.0, 0.0, 0.0)};
  EXPECT_TRUE(OddPlacementsOfOneSubmap(three, kMaxT, kMaxR).empty());
  // A chain: each agrees with its neighbour, the two ends do not agree with each other.
  const SubmapPlacements chain = {At(1, 0.0, 0.0, 0.0), At(1, 0.15, 0.0, 0.0),
                                  At(1, 0.3, 0.0, 0.0)};
  EXPECT_TRUE(OddPlacementsOfOneSubmap(chain, kMaxT, kMaxR).empty());
}

TEST(SubmapLoopAgreementTest, LoopsOfDifferentSubmapsAreNotCompared) {
  // Submaps 4 and 5 lie 20 m apart; each has loops that agree among themselves, and submap 6
  // has one loop far from everything.
  const SubmapPlacements p = {At(4, 0.0, 0.0, 0.0),  At(5, 20.0, 0.0, 0.0),
                              At(4, 0.02, 0.0, 0.0), At(5, 20.0, 0.03, 0.05),
                              At(4, 0.0, 0.04, 0.1), At(6, 50.0, 0.0, 0.0)};
  EXPECT_TRUE(OddPlacementsOfOneSubmap(p, kMaxT, kMaxR).empty());
  // A fourth loop of submap 5, 0.4 m off: odd in its submap, whatever the other submaps hold.
  SubmapPlacements q = p;
  q.push_back(At(5, 20.4, 0.0, 0.0));
  EXPECT_EQ(OddPlacementsOfOneSubmap(q, kMaxT, kMaxR), std::vector<std::size_t>({6}));
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
