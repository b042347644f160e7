#include "multisession_mapper/core/local_ground.h"

#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>

namespace multisession_mapper {
namespace core {
namespace {

// A sloped street (z = 0.05 x) sampled every 0.2 m, a car body 0.3-1.5 m above it over
// 4 m x 1.8 m (no ground under it), and a canopy 5 m above the ground.
TEST(LocalGround, HeightsFollowTheSlopeAndBridgeTheGroundUnderACar) {
  PointVector points;
  std::vector<float> expected;
  const auto ground_z = [](double x) { return 0.05 * x; };
  for (double x = -10.0; x <= 10.0; x += 0.2) {
    for (double y = -5.0; y <= 5.0; y += 0.2) {
      const bool under_car = x > -2.0 && x < 2.0 && y > -0.9 && y < 0.9;
      if (under_car) continue;
      points.emplace_back(x, y, ground_z(x));
      expected.push_back(0.0f);
    }
  }
  // The car's sides (its faces at y = +-0.9) and roof.
  for (double x = -1.9; x <= 1.9; x += 0.2) {
    for (double z = 0.3; z <= 1.5; z += 0.2) {
      for (double y : {-0.9, 0.9}) {
        points.emplace_back(x, y, ground_z(x) + z);
        expected.push_back(static_cast<float>(z));
      }
    }
    for (double y = -0.8; y <= 0.8; y += 0.2) {
      points.emplace_back(x, y, ground_z(x) + 1.5);
      expected.push_back(1.5f);
    }
  }
  points.emplace_back(6.0, 3.0, ground_z(6.0) + 5.0);
  expected.push_back(5.0f);
  const std::vector<float> h = HeightsAboveLocalGround(points, 0.5);
  ASSERT_EQ(h.size(), points.size());
  int car_points = 0;
  for (std::size_t i = 0; i < h.size(); ++i) {
    // The ground of a 3 x 3 window is its lowest cell's: on the slope up to 0.05 * 1.5 m low,
    // and under the middle of the car the nearest ground is 1 m away (the window reaches it
    // only from cells next to the car's sides; its roof centre sees no ground and takes the
    // body's own bottom row: heights measured from 0.3 m).
    if (expected[i] == 0.0f) {
      EXPECT_LE(h[i], 0.08f) << i;
    } else if (expected[i] == 5.0f) {
      EXPECT_NEAR(h[i], 5.0f, 0.08f);
    } else {
      ++car_points;
      EXPECT_GE(h[i], expected[i] - 0.3f - 0.08f) << i;
      EXPECT_LE(h[i], expected[i] + 0.08f) << i;
      EXPECT_GT(h[i], 0.0f) << i;
    }
  }
  EXPECT_GT(car_points, 200);
  EXPECT_TRUE(HeightsAboveLocalGround({}, 0.5).empty());
}

// Ground points next to a pole (a point 1 m up) are near standing points; those 2 cells away
// and the pole's own top at 5 m (outside the band) are not counted as standing.
TEST(LocalGround, NearStandingPointsAreThoseWithinOneCellOfSomethingStanding) {
  PointVector points;
  for (double x = 0.05; x < 5.0; x += 0.5) points.emplace_back(x, 0.05, 0.0);
  points.emplace_back(2.05, 0.05, 1.0);  // the pole, in the cell of x = 2.05
  points.emplace_back(4.55, 0.05, 5.0);  // a crown above the band
  const std::vector<float> heights = HeightsAboveLocalGround(points, 0.5);
  const std::vector<std::uint8_t> near = NearStandingPoints(points, heights, 0.5, 0.25, 3.5);
  ASSERT_EQ(near.size(), points.size());
  for (std::size_t i = 0; i < 10; ++i) {
    const double x = points[i].x();
    EXPECT_EQ(near[i], std::abs(x - 2.05) < 0.6 ? 1 : 0) << "ground at x = " << x;
  }
  EXPECT_EQ(near[10], 1);  // the pole itself
  EXPECT_EQ(near[11], 0);  // the crown: nothing standing within a cell
  // Without the pole nothing is near anything.
  PointVector bare(points.begin(), points.begin() + 10);
  const std::vector<std::uint8_t> none =
      NearStandingPoints(bare, HeightsAboveLocalGround(bare, 0.5), 0.5, 0.25, 3.5);
  EXPECT_EQ(std::count(none.begin(), none.end(), 1), 0);
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
