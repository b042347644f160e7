#include "multisession_mapper/core/pipeline_config.h"

#include <filesystem>

#include <gtest/gtest.h>

namespace multisession_mapper {
namespace core {
namespace {

// Every configuration file shipped in cfg/ loads and validates (cartographer's
// configuration_files_test idea).
TEST(PipelineConfig, EveryShippedConfigurationLoads) {
  int files = 0;
  for (const auto& entry :
       std::filesystem::directory_iterator(std::filesystem::path(MSM_SOURCE_DIR) / "cfg")) {
    if (entry.path().extension() != ".yaml") continue;
    ++files;
    StatusOr<PipelineConfig> config = LoadPipelineConfig(entry.path().string());
    EXPECT_TRUE(config.ok()) << config.status().message();
  }
  EXPECT_GE(files, 1);
}

TEST(PipelineConfig, DefaultFileEqualsBuiltInDefaults) {
  StatusOr<PipelineConfig> file =
      LoadPipelineConfig(std::string(MSM_SOURCE_DIR) + "/cfg/default.yaml");
  ASSERT_TRUE(file.ok()) << file.status().message();
  EXPECT_EQ(PipelineConfigToYaml(file.value()), PipelineConfigToYaml(PipelineConfig()));
}

TEST(PipelineConfig, OverridesKeysAndKeepsOthers) {
  StatusOr<PipelineConfig> config = PipelineConfigFromYaml(
      "submap:\n  max_translation_m: 12.5\nintra_loops:\n  enabled: false\n  min_id_gap: 5\n",
      "test");
  ASSERT_TRUE(config.ok()) << config.status().message();
  EXPECT_DOUBLE_EQ(config.value().session.submaps.max_translation_m, 12.5);
  EXPECT_FALSE(config.value().session.intra_loops.enabled);
  EXPECT_EQ(config.value().session.intra_loops.min_id_gap, 5);
  EXPECT_DOUBLE_EQ(config.value().session.submaps.max_rotation_rad, 0.7);
}

TEST(PipelineConfig, RoundTripThroughYaml) {
  PipelineConfig config;
  config.session.submaps.voxel_size_m = 0.15;
  config.session.submaps.dynamic_filter.check_every_n_scans = 4;
  StatusOr<PipelineConfig> back = PipelineConfigFromYaml(PipelineConfigToYaml(config), "rt");
  ASSERT_TRUE(back.ok()) << back.status().message();
  EXPECT_EQ(PipelineConfigToYaml(back.value()), PipelineConfigToYaml(config));
}

TEST(PipelineConfig, TheDescriptorKindIsReadAndWrittenByName) {
  EXPECT_EQ(PipelineConfig().place_recognition.descriptor.kind, DescriptorKind::kRingHistogram);
  StatusOr<PipelineConfig> config =
      PipelineConfigFromYaml("place_recognition:\n  descriptor: scan_context\n", "test");
  ASSERT_TRUE(config.ok()) << config.status().message();
  EXPECT_EQ(config.value().place_recognition.descriptor.kind, DescriptorKind::kScanContext);
  const std::string yaml = PipelineConfigToYaml(config.value());
  EXPECT_NE(yaml.find("descriptor: scan_context"), std::string::npos) << yaml;
  StatusOr<PipelineConfig> back = PipelineConfigFromYaml(yaml, "rt");
  ASSERT_TRUE(back.ok()) << back.status().message();
  EXPECT_EQ(back.value().place_recognition.descriptor.kind, DescriptorKind::kScanContext);
  StatusOr<PipelineConfig> bad =
      PipelineConfigFromYaml("place_recognition:\n  descriptor: locnet\n", "my.yaml");
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("ring_histogram or scan_context"), std::string::npos)
      << bad.status().message();
}

TEST(PipelineConfig, ErrorsNameTheProblem) {
  auto error = [](const std::string& yaml) {
    StatusOr<PipelineConfig> c = PipelineConfigFromYaml(yaml, "my.yaml");
    EXPECT_FALSE(c.ok()) << yaml;
    return c.ok() ? std::string() : c.status().message();
  };
  EXPECT_NE(error("submap:\n  max_translaton_m: 3\n").find("unknown key 'submap.max_translaton_m'"),
            std::string::npos);
  EXPECT_NE(error("submap:\n  max_translation_m: far\n").find("wrong type"), std::string::npos);
  EXPECT_NE(error("submap:\n  max_translation_m: -4\n").find("max_translation_m"),
            std::string::npos);
  EXPECT_NE(error("odometry:\n  map_ground_min_normal_z: 1.5\n").find("map_ground_min_normal_z"),
            std::string::npos);
  EXPECT_NE(error("odometry:\n  map_ground_min_depth_m: .nan\n").find("map_ground_min_depth_m"),
            std::string::npos);
  EXPECT_NE(error("odometry:\n  map_ground_min_depth_m: -.inf\n").find("map_ground_min_depth_m"),
            std::string::npos);
  EXPECT_TRUE(
      PipelineConfigFromYaml("odometry:\n  map_ground_min_depth_m: .inf\n", "off.yaml").ok());
  EXPECT_NE(error("[1, 2").find("my.yaml"), std::string::npos);
  EXPECT_NE(error("submap: 3\n").find("mapping"), std::string::npos);
  EXPECT_FALSE(LoadPipelineConfig("/nonexistent/config.yaml").ok());
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
