#include "multisession_mapper/core/fast_atan2.h"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

namespace multisession_mapper {
namespace core {
namespace {

TEST(FastAtan2Test, WithinBoundOfStdAtan2OverAllDirections) {
  double worst = 0.0;
  for (int i = 0; i < 360000; ++i) {  // every 0.001 deg, at two radii
    const double a = -M_PI + 2.0 * M_PI * i / 360000.0;
    for (const double r : {0.05, 80.0}) {
      const double y = r * std::sin(a), x = r * std::cos(a);
      worst = std::max(worst, std::abs(FastAtan2(y, x) - std::atan2(y, x)));
    }
  }
  EXPECT_LT(worst, 3e-7);
}

TEST(FastAtan2Test, RandomArgumentsAndAxes) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-100.0, 100.0);
  for (int i = 0; i < 100000; ++i) {
    const double y = u(rng), x = u(rng);
    ASSERT_NEAR(FastAtan2(y, x), std::atan2(y, x), 3e-7) << y << " " << x;
  }
  EXPECT_DOUBLE_EQ(FastAtan2(0.0, 1.0), 0.0);
  EXPECT_NEAR(FastAtan2(1.0, 0.0), M_PI_2, 3e-7);
  EXPECT_NEAR(FastAtan2(-1.0, 0.0), -M_PI_2, 3e-7);
  EXPECT_NEAR(FastAtan2(0.0, -1.0), M_PI, 3e-7);
  EXPECT_NEAR(FastAtan2(1.0, 1.0), M_PI_4, 3e-7);
  EXPECT_EQ(FastAtan2(0.0, 0.0), 0.0);
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
