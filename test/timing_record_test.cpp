// Tests of core/timing_record: summaries, the YAML record (merge stages) and the peak memory.
#include <cstring>
#include <memory>

#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include "multisession_mapper/core/timing_record.h"

namespace core = multisession_mapper::core;

TEST(TimingRecord, SummarizeGivesMedianAndNearestRankP95) {
  std::vector<double> samples;
  for (int i = 1; i <= 100; ++i) samples.push_back(i);
  const core::TimingSummary s = core::Summarize(samples);
  EXPECT_EQ(s.samples, 100u);
  EXPECT_NEAR(s.median, 50.5, 0.51);
  EXPECT_NEAR(s.p95, 95.0, 1.0);
  const core::TimingSummary none = core::Summarize({});
  EXPECT_EQ(none.samples, 0u);
  EXPECT_EQ(none.median, 0.0);
}

TEST(TimingRecord, YamlHasTheMergeStagesAndTheirParts) {
  core::SessionTimings timings;
  core::SessionRunInfo run;
  run.merge_s = 10.0;
  run.merge_matching_s = 3.0;
  run.merge_optimisation_s = 2.0;
  run.merge_update_s = 4.5;
  run.merge_update_dynamics_s = 2.5;
  run.merge_update_fusion_s = 1.25;
  run.merge_update_database_s = 0.5;
  run.peak_rss_mb = 123.0;
  const YAML::Node yaml = YAML::Load(core::TimingYaml(timings, run));
  EXPECT_DOUBLE_EQ(yaml["merge_s"].as<double>(), 10.0);
  EXPECT_DOUBLE_EQ(yaml["peak_rss_mb"].as<double>(), 123.0);
  const YAML::Node stages = yaml["merge_stages_s"];
  ASSERT_TRUE(stages.IsMap());
  EXPECT_DOUBLE_EQ(stages["matching"].as<double>(), 3.0);
  EXPECT_DOUBLE_EQ(stages["optimisation"].as<double>(), 2.0);
  EXPECT_DOUBLE_EQ(stages["update"].as<double>(), 4.5);
  EXPECT_DOUBLE_EQ(stages["update_dynamics"].as<double>(), 2.5);
  EXPECT_DOUBLE_EQ(stages["update_fusion"].as<double>(), 1.25);
  EXPECT_DOUBLE_EQ(stages["update_database"].as<double>(), 0.5);
}

TEST(TimingRecord, YamlHasTheOdometryStagesAndIcpWork) {
  core::SessionTimings timings;
  timings.odometry_registration_ms = {4.0, 8.0, 6.0};
  timings.odometry_deskew_ms = {1.0};
  timings.odometry_map_ground_ms = {0.5, 1.5};
  timings.odometry_icp_iterations = {10.0, 30.0, 12.0, 14.0};
  timings.odometry_registrations = {1.0, 1.0, 3.0};
  const YAML::Node yaml = YAML::Load(core::TimingYaml(timings, core::SessionRunInfo{}));
  const YAML::Node stages = yaml["odometry_stages_ms"];
  ASSERT_TRUE(stages.IsMap());
  EXPECT_DOUBLE_EQ(stages["registration"]["median"].as<double>(), 6.0);
  EXPECT_EQ(stages["registration"]["samples"].as<int>(), 3);
  EXPECT_DOUBLE_EQ(stages["deskew"]["median"].as<double>(), 1.0);
  EXPECT_EQ(stages["filter"]["samples"].as<int>(), 0);
  EXPECT_DOUBLE_EQ(stages["map_ground"]["median"].as<double>(), 1.0);
  EXPECT_EQ(stages["map_ground"]["samples"].as<int>(), 2);
  ASSERT_TRUE(stages["map_update"].IsMap());
  ASSERT_TRUE(stages["downsample_normals"].IsMap());
  const YAML::Node icp = yaml["odometry_icp_per_scan"];
  ASSERT_TRUE(icp.IsMap());
  EXPECT_DOUBLE_EQ(icp["iterations"]["median"].as<double>(), 13.0);
  EXPECT_DOUBLE_EQ(icp["registrations"]["median"].as<double>(), 1.0);
  EXPECT_DOUBLE_EQ(icp["registrations"]["p95"].as<double>(), 3.0);
  EXPECT_EQ(icp["searches"]["samples"].as<int>(), 0);
}

TEST(TimingRecord, PeakRssGrowsWithTouchedMemory) {
  const double before = core::ProcessPeakRssMb();
  EXPECT_GT(before, 1.0);  // a running test binary uses more than 1 MB
  constexpr std::size_t kBytes = 64u << 20;  // 64 MB, every page written
  std::unique_ptr<char[]> block(new char[kBytes]);
  std::memset(block.get(), 1, kBytes);
  volatile char sink = block[kBytes - 1];
  (void)sink;
  EXPECT_GE(core::ProcessPeakRssMb(), before + 32.0);
}
