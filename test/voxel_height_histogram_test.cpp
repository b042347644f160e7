#include "multisession_mapper/core/voxel_height_histogram.h"

#include <cmath>
#include <limits>
#include <random>

#include <gtest/gtest.h>

namespace multisession_mapper {
namespace core {
namespace {

constexpr double kVoxel = 0.2;

TEST(VoxelHeightHistogramTest, EmptyGivesTheFallback) {
  VoxelHeightHistogram h(0.0);
  EXPECT_EQ(h.count(), 0u);
  EXPECT_DOUBLE_EQ(h.RobustHeight(1.234), 1.234);
}

TEST(VoxelHeightHistogramTest, CleanGroundKeepsItsMean) {
  // Ground at 3.05 m with 1 cm noise, in the voxel [3.0, 3.2): the mean of all returns.
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 0.01);
  VoxelHeightHistogram h(3.0);
  double sum = 0.0;
  const int n = 500;
  for (int i = 0; i < n; ++i) {
    const double z = 3.05 + noise(rng);
    sum += z;
    h.Add(z, kVoxel);
  }
  EXPECT_EQ(h.count(), static_cast<std::uint32_t>(n));
  EXPECT_NEAR(h.RobustHeight(0.0), sum / n, 1e-3);
}

TEST(VoxelHeightHistogramTest, AMinorityAboveTheGroundDoesNotLiftIt) {
  // 60 % ground returns at -1.95 m (floor -2.0), 40 % feet returns 8-18 cm above it: the mean
  // of all is lifted by about 5 cm, the robust height stays within 5 mm of the ground.
  std::mt19937 rng(5);
  std::normal_distribution<double> noise(0.0, 0.005);
  std::uniform_real_distribution<double> feet(0.08, 0.18);
  VoxelHeightHistogram h(-2.0);
  double sum = 0.0;
  for (int i = 0; i < 1000; ++i) {
    const double z = i % 5 < 3 ? -1.95 + noise(rng) : -1.95 + feet(rng);
    sum += z;
    h.Add(z, kVoxel);
  }
  EXPECT_GT(sum / 1000.0 - (-1.95), 0.04);
  EXPECT_NEAR(h.RobustHeight(0.0), -1.95, 0.005);
}

TEST(VoxelHeightHistogramTest, UniformlySpreadReturnsStayInTheMiddle) {
  // A wall's voxel: returns over its whole height; the robust height is near the middle.
  VoxelHeightHistogram h(10.0);
  for (int i = 0; i < 800; ++i) h.Add(10.0 + kVoxel * (i + 0.5) / 800.0, kVoxel);
  EXPECT_NEAR(h.RobustHeight(0.0), 10.1, 0.015);
}

TEST(VoxelHeightHistogramTest, SaturatedCountsKeepTheProportions) {
  // 200,000 returns (beyond 16-bit counts): 70 % at 0.02 m, 30 % at 0.17 m above the floor.
  VoxelHeightHistogram h(0.0);
  for (int i = 0; i < 200000; ++i) h.Add(i % 10 < 7 ? 0.02 : 0.17, kVoxel);
  EXPECT_LT(h.count(), 200000u);
  EXPECT_GT(h.count(), 30000u);
  EXPECT_NEAR(h.RobustHeight(1.0), 0.02, 1e-4);
}

TEST(VoxelHeightHistogramTest, HeightsOutsideTheVoxelGoToTheEdgeSlices) {
  VoxelHeightHistogram h(0.0);
  h.Add(-0.01, kVoxel);   // rounding just below the floor
  h.Add(0.005, kVoxel);
  h.Add(0.21, kVoxel);    // just above the top
  EXPECT_EQ(h.count(), 3u);
  // Median in the lowest slice; its neighbour slice is empty: mean of the two low returns.
  EXPECT_NEAR(h.RobustHeight(1.0), -0.0025, 1e-6);
}

TEST(VoxelHeightHistogramTest, HugeHeightsAreClampedBeforeTheCast) {
  // Far outside the voxel (a caller's bug): counted in the edge slices, no out-of-range write.
  VoxelHeightHistogram h(0.0);
  h.Add(1e30, kVoxel);
  h.Add(-1e30, kVoxel);
  h.Add(std::numeric_limits<double>::quiet_NaN(), kVoxel);
  EXPECT_EQ(h.count(), 3u);
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
