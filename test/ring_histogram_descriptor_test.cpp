#include "place_recognition_test_scans.h"  // first: defines PCL_NO_PRECOMPILE

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <random>

#include <gtest/gtest.h>

#include "multisession_mapper/core/ring_histogram_descriptor.h"

namespace multisession_mapper {
namespace core {
namespace {

using msm_pr_test::L2;
using msm_pr_test::TurnSensor;

const double kYaws[] = {0.37, 1.2, 2.0, M_PI, -2.7, -0.05, 4.4};

RingHistogramDescriptor MakeDescriptor() {
  auto d = RingHistogramDescriptor::Create(RingHistogramDescriptorConfig());
  EXPECT_TRUE(d.ok()) << d.status().message();
  return d.value();
}

TEST(RingHistogramDescriptorTest, ConfigValidation) {
  RingHistogramDescriptorConfig config;
  EXPECT_TRUE(config.Validate().ok());
  config.min_range_m = 0.0;  // log bins need > 0
  EXPECT_FALSE(RingHistogramDescriptor::Create(config).ok());
  config = RingHistogramDescriptorConfig();
  config.diff_bins = 2;
  EXPECT_NE(config.Validate().message().find("diff_bins"), std::string::npos);
  config = RingHistogramDescriptorConfig();
  config.max_range_m = std::nan("");
  EXPECT_FALSE(config.Validate().ok());
}

TEST(RingHistogramDescriptorTest, DimensionAndNormalisation) {
  const RingHistogramDescriptor descriptor = MakeDescriptor();
  const LidarScan scan = msm_pr_test::ScanYard(msm_pr_test::RandomYard(1), 11);
  RingHistogramStats stats;
  const PlaceDescriptor d = descriptor.Compute(scan, &stats);
  EXPECT_EQ(d.kind, DescriptorKind::kRingHistogram);
  ASSERT_EQ(static_cast<int>(d.key.size()), 16 * (6 + 12));
  EXPECT_TRUE(d.matrix.empty());
  EXPECT_EQ(stats.rings_used, 16);
  // Every ring used -> each square-rooted histogram has unit norm; with the weights w (range)
  // and 1 (differences) and the scale 1 / sqrt(16 (1 + w^2)) the whole vector has norm 1.
  double norm_sq = 0.0;
  for (float v : d.key) {
    EXPECT_GE(v, 0.0f);
    norm_sq += double(v) * v;
  }
  EXPECT_NEAR(norm_sq, 1.0, 1e-4);
  // An empty scan gives the zero vector.
  const PlaceDescriptor empty = descriptor.Compute(LidarScan());
  for (float v : empty.key) EXPECT_EQ(v, 0.0f);
}

TEST(RingHistogramDescriptorTest, YawInvariantOnSyntheticScan) {
  const RingHistogramDescriptor descriptor = MakeDescriptor();
  const LidarScan scan = msm_pr_test::ScanYard(msm_pr_test::RandomYard(2), 12);
  const PlaceDescriptor reference = descriptor.Compute(scan);
  double worst_rotated = 0.0;
  for (double yaw : kYaws) {
    const PlaceDescriptor rotated = descriptor.Compute(TurnSensor(scan, yaw));
    worst_rotated = std::max(worst_rotated, L2(reference.key, rotated.key));
  }
  EXPECT_LT(worst_rotated, 0.01);
  // Other places (different yards) and the same yard seen from elsewhere are far away.
  for (std::uint32_t seed = 3; seed < 8; ++seed) {
    const PlaceDescriptor other =
        descriptor.Compute(msm_pr_test::ScanYard(msm_pr_test::RandomYard(seed), 12));
    EXPECT_GT(L2(reference.key, other.key), 10.0 * std::max(worst_rotated, 1e-3))
        << "yard seed " << seed;
  }
}

TEST(RingHistogramDescriptorTest, RingFromElevationMatchesRingField) {
  const RingHistogramDescriptor descriptor = MakeDescriptor();
  LidarScan scan = msm_pr_test::ScanYard(msm_pr_test::RandomYard(4), 13);
  const PlaceDescriptor with_ring = descriptor.Compute(scan);
  scan.has_ring = false;
  for (LidarPoint& p : scan.points) p.ring = 0;  // must not be read
  RingHistogramStats stats;
  const PlaceDescriptor from_elevation = descriptor.Compute(scan, &stats);
  EXPECT_EQ(stats.rings_used, 16);
  EXPECT_LT(L2(with_ring.key, from_elevation.key), 0.01);
}

TEST(RingHistogramDescriptorTest, PointOrderDoesNotMatter) {
  // Rings in firing order take the no-sort path; a shuffled scan must be sorted first.
  const RingHistogramDescriptor descriptor = MakeDescriptor();
  LidarScan scan = msm_pr_test::ScanYard(msm_pr_test::RandomYard(6), 15);
  const PlaceDescriptor ordered = descriptor.Compute(scan);
  std::mt19937 rng(42);
  std::shuffle(scan.points.begin(), scan.points.end(), rng);
  EXPECT_LT(L2(ordered.key, descriptor.Compute(scan).key), 1e-6);
  // Reversed firing order (a sensor spinning the other way) too.
  std::reverse(scan.points.begin(), scan.points.end());
  EXPECT_LT(L2(ordered.key, descriptor.Compute(scan).key), 1e-6);
}

TEST(RingHistogramDescriptorTest, IgnoresNonFiniteAndOutOfRangePoints) {
  const RingHistogramDescriptor descriptor = MakeDescriptor();
  LidarScan scan = msm_pr_test::ScanYard(msm_pr_test::RandomYard(5), 14);
  const PlaceDescriptor clean = descriptor.Compute(scan);
  LidarPoint bad;
  bad.position_m = Eigen::Vector3f(std::nanf(""), 1.0f, 0.0f);
  scan.points.push_back(bad);
  bad.position_m = Eigen::Vector3f(0.1f, 0.0f, 0.0f);  // below min_range_m
  scan.points.push_back(bad);
  bad.position_m = Eigen::Vector3f(0.0f, 0.0f, 5.0f);  // no azimuth
  scan.points.push_back(bad);
  bad.position_m = Eigen::Vector3f(5.0f, 0.0f, 0.0f);
  bad.ring = 40;  // no such ring
  scan.points.push_back(bad);
  EXPECT_EQ(L2(clean.key, descriptor.Compute(scan).key), 0.0);
}

TEST(RingHistogramDescriptorTest, YawInvariantOnRealVlp16Scans) {
  const std::string dir = msm_pr_test::RealVlp16Dir();
  if (!std::filesystem::exists(dir + "/0.pcd")) {
    GTEST_SKIP() << "real data absent: " << dir << " (needs ../shared/data beside the checkout)";
  }
  const RingHistogramDescriptor descriptor = MakeDescriptor();
  const int files[] = {0, 7, 14, 21, 29};
  std::vector<PlaceDescriptor> references;
  double worst_rotated = 0.0;
  for (int f : files) {
    LidarScan scan;
    ASSERT_TRUE(msm_pr_test::LoadVlp16Pcd(dir + "/" + std::to_string(f) + ".pcd", &scan)) << f;
    RingHistogramStats stats;
    references.push_back(descriptor.Compute(scan, &stats));
    EXPECT_EQ(stats.rings_used, 16) << "file " << f;
    for (double yaw : kYaws) {
      const double d = L2(references.back().key, descriptor.Compute(TurnSensor(scan, yaw)).key);
      worst_rotated = std::max(worst_rotated, d);
    }
  }
  EXPECT_LT(worst_rotated, 0.01);
  // The same real place rotated is much closer than any other recorded scan.
  double nearest_other = 1e9;
  for (std::size_t i = 0; i < references.size(); ++i) {
    for (std::size_t j = i + 1; j < references.size(); ++j) {
      nearest_other = std::min(nearest_other, L2(references[i].key, references[j].key));
    }
  }
  EXPECT_GT(nearest_other, 3.0 * std::max(worst_rotated, 1e-3));
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
