#include "multisession_mapper/sim/road_path.h"

#include <cmath>

#include <gtest/gtest.h>

namespace multisession_mapper {
namespace sim {
namespace {

TEST(SimRoadPathTest, RoundedCornerHasTheRightLengthAndOffsets) {
  // An L: 50 m east, 50 m north, corner radius 6 m.
  auto path = RoadPath::Create({{0, 0}, {50, 0}, {50, 50}}, 6.0, 0.05);
  ASSERT_TRUE(path.ok()) << path.status().message();
  const RoadPath& p = path.value();
  // Straight parts 44 + 44 m plus a quarter circle of radius 6 m.
  EXPECT_NEAR(p.length_m(), 88.0 + 0.5 * M_PI * 6.0, 0.01);
  Eigen::Vector2d tangent;
  double curvature = 0.0;
  const Eigen::Vector2d a = p.Point(10.0, 1.5, &tangent, &curvature);
  EXPECT_NEAR(a.x(), 10.0, 1e-9);
  EXPECT_NEAR(a.y(), -1.5, 1e-9);  // right of travel = -y when driving +x
  EXPECT_NEAR(tangent.x(), 1.0, 1e-9);
  EXPECT_NEAR(curvature, 0.0, 1e-12);
  p.Point(44.0 + 0.25 * M_PI * 6.0, 0.0, &tangent, &curvature);
  EXPECT_NEAR(curvature, 1.0 / 6.0, 1e-9);  // left turn
  EXPECT_NEAR(tangent.x(), std::sqrt(0.5), 0.01);
  const Eigen::Vector2d end = p.Point(1e9, 0.0, &tangent);
  EXPECT_NEAR(end.x(), 50.0, 1e-9);
  EXPECT_NEAR(end.y(), 50.0, 1e-9);
  EXPECT_NEAR(tangent.y(), 1.0, 1e-9);
  // Consecutive samples are continuous.
  for (double s = 0.0; s < p.length_m(); s += 0.3) {
    EXPECT_LT((p.Point(s + 0.1) - p.Point(s)).norm(), 0.1 + 1e-6);
  }
}

TEST(SimRoadPathTest, ShortSegmentsShrinkTheFilletAndBadInputFails) {
  auto path = RoadPath::Create({{0, 0}, {4, 0}, {4, 4}}, 10.0, 0.05);
  ASSERT_TRUE(path.ok());
  EXPECT_GT(path.value().length_m(), 6.0);
  EXPECT_LT(path.value().length_m(), 8.0);
  EXPECT_FALSE(RoadPath::Create({{0, 0}}, 5.0).ok());
  EXPECT_FALSE(RoadPath::Create({{0, 0}, {0, 0}}, 5.0).ok());
  EXPECT_FALSE(RoadPath::Create({{0, 0}, {10, 0}, {0, 0}}, 5.0).ok());  // U-turn
  EXPECT_FALSE(RoadPath::Create({{0, 0}, {10, 0}}, -1.0).ok());
}

}  // namespace
}  // namespace sim
}  // namespace multisession_mapper
