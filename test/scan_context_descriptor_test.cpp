#include "place_recognition_test_scans.h"  // first: defines PCL_NO_PRECOMPILE

#include <cmath>
#include <filesystem>

#include <gtest/gtest.h>

#include "multisession_mapper/core/scan_context_descriptor.h"

namespace multisession_mapper {
namespace core {
namespace {

using msm_pr_test::L2;
using msm_pr_test::TurnSensor;

double AngleDiff(double a, double b) { return std::remainder(a - b, 2.0 * M_PI); }

ScanContextDescriptor MakeDescriptor() {
  auto d = ScanContextDescriptor::Create(ScanContextConfig());
  EXPECT_TRUE(d.ok()) << d.status().message();
  return d.value();
}

TEST(ScanContextDescriptorTest, ConfigValidation) {
  ScanContextConfig config;
  EXPECT_TRUE(config.Validate().ok());
  config.num_sectors = 2;
  EXPECT_NE(config.Validate().message().find("num_sectors"), std::string::npos);
  config = ScanContextConfig();
  config.max_radius_m = 0.5;  // below min_radius_m
  EXPECT_FALSE(ScanContextDescriptor::Create(config).ok());
}

TEST(ScanContextDescriptorTest, ShapeAndRingKey) {
  const ScanContextDescriptor sc = MakeDescriptor();
  const PlaceDescriptor d = sc.Compute(msm_pr_test::ScanYard(msm_pr_test::RandomYard(1), 1));
  EXPECT_EQ(d.kind, DescriptorKind::kScanContext);
  EXPECT_EQ(d.rows, 20);
  EXPECT_EQ(d.cols, 60);
  ASSERT_EQ(d.matrix.size(), 1200u);
  ASSERT_EQ(d.key.size(), 20u);
  double row0 = 0.0;
  for (int s = 0; s < 60; ++s) row0 += d.matrix[s];
  EXPECT_NEAR(d.key[0], row0 / 60.0, 1e-5);
  // Identical scans: distance 0, no yaw.
  const ScanContextMatch self = sc.Distance(d, d);
  EXPECT_NEAR(self.distance, 0.0, 1e-6);
  EXPECT_EQ(self.shift, 0);
  // A malformed descriptor is "infinitely" far, not a crash.
  PlaceDescriptor bad = d;
  bad.matrix.pop_back();
  EXPECT_EQ(sc.Distance(bad, d).distance, 1.0f);
}

void ExpectYawRecovered(const ScanContextDescriptor& sc, const LidarScan& scan) {
  const PlaceDescriptor candidate = sc.Compute(scan);
  const double sector_rad = 2.0 * M_PI / sc.config().num_sectors;
  for (double yaw : {0.3, 1.05, 2.5, M_PI, -1.9, -0.6}) {
    const PlaceDescriptor query = sc.Compute(TurnSensor(scan, yaw));
    const ScanContextMatch match = sc.Distance(query, candidate);
    // The query sensor is turned by yaw: T_candidate_query has yaw `yaw`.
    EXPECT_LE(std::fabs(AngleDiff(match.yaw_rad, yaw)), sector_rad) << "applied yaw " << yaw;
    EXPECT_LT(match.distance, 0.2) << "applied yaw " << yaw;
    // The ring key is yaw invariant up to points moving between cells (a cell keeps the
    // highest point).
    const std::vector<float> zero(candidate.key.size(), 0.0f);
    EXPECT_LT(L2(query.key, candidate.key), 0.1 * L2(candidate.key, zero));
  }
}

TEST(ScanContextDescriptorTest, RecoversAppliedYawOnSyntheticScan) {
  const ScanContextDescriptor sc = MakeDescriptor();
  ExpectYawRecovered(sc, msm_pr_test::ScanYard(msm_pr_test::RandomYard(2), 2));
}

TEST(ScanContextDescriptorTest, RecoversAppliedYawOnRealVlp16Scan) {
  const std::string dir = msm_pr_test::RealVlp16Dir();
  if (!std::filesystem::exists(dir + "/0.pcd")) {
    GTEST_SKIP() << "real data absent: " << dir << " (needs ../shared/data beside the checkout)";
  }
  LidarScan scan;
  ASSERT_TRUE(msm_pr_test::LoadVlp16Pcd(dir + "/0.pcd", &scan));
  ExpectYawRecovered(MakeDescriptor(), scan);
}

TEST(ScanContextDescriptorTest, DifferentPlacesAreFartherThanRotatedSamePlace) {
  const ScanContextDescriptor sc = MakeDescriptor();
  const LidarScan scan = msm_pr_test::ScanYard(msm_pr_test::RandomYard(3), 3);
  const PlaceDescriptor reference = sc.Compute(scan);
  const double rotated = sc.Distance(sc.Compute(TurnSensor(scan, 2.2)), reference).distance;
  for (std::uint32_t seed = 4; seed < 9; ++seed) {
    const PlaceDescriptor other =
        sc.Compute(msm_pr_test::ScanYard(msm_pr_test::RandomYard(seed), 3));
    EXPECT_GT(sc.Distance(other, reference).distance, rotated + 0.05) << "yard seed " << seed;
  }
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
