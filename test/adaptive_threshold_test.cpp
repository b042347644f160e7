#include "multisession_mapper/core/adaptive_threshold.h"

#include <cmath>

#include <gtest/gtest.h>

#include "multisession_mapper/core/se3.h"

namespace multisession_mapper {
namespace core {
namespace {

TEST(AdaptiveThresholdTest, StartsAtInitialThenFollowsTheModelError) {
  AdaptiveThresholdConfig config;
  config.max_range_m = 50.0;
  config.max_threshold_m = 3.0;
  AdaptiveThreshold threshold = AdaptiveThreshold::Create(config).value();
  EXPECT_DOUBLE_EQ(threshold.Sigma(), config.initial_threshold_m);

  const Pose3 motion = se3::FromXyzRpy(0.3, 0.0, 0.0, 0.0, 0.0, 0.0);
  // Deviation: 0.2 m translation and 0.01 rad -> 2 * 50 * sin(0.005) + 0.2.
  const Pose3 deviation = se3::FromXyzRpy(0.2, 0.0, 0.0, 0.0, 0.0, 0.01);
  threshold.Update(deviation, motion);
  const double e1 = 2.0 * 50.0 * std::sin(0.005) + 0.2;
  EXPECT_NEAR(threshold.Sigma(), e1, 1e-9);
  threshold.Update(Pose3::Identity(), motion);  // perfect prediction
  EXPECT_NEAR(threshold.Sigma(), std::sqrt(e1 * e1 / 2.0), 1e-9);
  EXPECT_EQ(threshold.num_samples(), 2u);
}

TEST(AdaptiveThresholdTest, StandingStillAddsNoSampleAndSigmaIsClamped) {
  AdaptiveThresholdConfig config;
  AdaptiveThreshold threshold = AdaptiveThreshold::Create(config).value();
  threshold.Update(se3::FromXyzRpy(5.0, 0, 0, 0, 0, 0), Pose3::Identity());
  EXPECT_EQ(threshold.num_samples(), 0u);
  const Pose3 motion = se3::FromXyzRpy(1.0, 0.0, 0.0, 0.0, 0.0, 0.0);
  for (int i = 0; i < 10; ++i) threshold.Update(Pose3::Identity(), motion);
  EXPECT_DOUBLE_EQ(threshold.Sigma(), config.min_threshold_m);
  threshold.Update(se3::FromXyzRpy(100.0, 0, 0, 0, 0, 0), motion);
  EXPECT_DOUBLE_EQ(threshold.Sigma(), config.max_threshold_m);
  threshold.Reset();
  EXPECT_DOUBLE_EQ(threshold.Sigma(), config.initial_threshold_m);
}

TEST(AdaptiveThresholdTest, ValidateRejectsBadConfig) {
  AdaptiveThresholdConfig config;
  config.min_threshold_m = 5.0;  // above max
  EXPECT_FALSE(AdaptiveThreshold::Create(config).ok());
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
