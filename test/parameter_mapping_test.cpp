// The dynamic_reconfigure .cfg files and cfg/default.yaml must not drift apart: every .cfg
// default equals the value the YAML (or, for keys the YAML does not list, the core struct)
// gives, and every parameter reaches a core field and comes back unchanged.
#include "multisession_mapper/ros/parameter_mapping.h"

#include <set>
#include <string>

#include <gtest/gtest.h>

#include "multisession_mapper/core/pipeline_config.h"

namespace multisession_mapper {
namespace ros_params {
namespace {

core::PipelineConfig DefaultYaml() {
  core::StatusOr<core::PipelineConfig> c =
      core::LoadPipelineConfig(std::string(MSM_SOURCE_DIR) + "/cfg/default.yaml");
  EXPECT_TRUE(c.ok()) << c.status().message();
  return c.ok() ? c.value() : core::PipelineConfig();
}

// Every parameter of `a` equals that of `b` (doubles exactly: both come from the same literal).
template <typename Config>
void ExpectSameValues(const Config& a, const Config& b, const std::string& what) {
  dynamic_reconfigure::Config ma, mb;
  a.__toMessage__(ma);
  b.__toMessage__(mb);
  ASSERT_EQ(ma.doubles.size(), mb.doubles.size());
  for (std::size_t i = 0; i < ma.doubles.size(); ++i) {
    EXPECT_EQ(ma.doubles[i].value, mb.doubles[i].value) << what << ": " << ma.doubles[i].name;
  }
  ASSERT_EQ(ma.ints.size(), mb.ints.size());
  for (std::size_t i = 0; i < ma.ints.size(); ++i) {
    EXPECT_EQ(ma.ints[i].value, mb.ints[i].value) << what << ": " << ma.ints[i].name;
  }
  ASSERT_EQ(ma.bools.size(), mb.bools.size());
  for (std::size_t i = 0; i < ma.bools.size(); ++i) {
    EXPECT_EQ(ma.bools[i].value, mb.bools[i].value) << what << ": " << ma.bools[i].name;
  }
}

// Every parameter set to a value different from its default (inside its bounds), except the
// ROS-only ones listed in `ros_only`.
template <typename Config>
Config Perturbed(const std::set<std::string>& ros_only, int* changed) {
  const Config def = Config::__getDefault__();
  const Config max = Config::__getMax__();
  dynamic_reconfigure::Config m, mmax;
  def.__toMessage__(m);
  max.__toMessage__(mmax);
  *changed = 0;
  for (std::size_t i = 0; i < m.doubles.size(); ++i) {
    if (ros_only.count(m.doubles[i].name)) continue;
    m.doubles[i].value = 0.5 * (m.doubles[i].value + mmax.doubles[i].value);
    ++*changed;
  }
  for (std::size_t i = 0; i < m.ints.size(); ++i) {
    if (ros_only.count(m.ints[i].name)) continue;
    m.ints[i].value = m.ints[i].value + 1 <= mmax.ints[i].value ? m.ints[i].value + 1 : m.ints[i].value - 1;
    ++*changed;
  }
  for (std::size_t i = 0; i < m.bools.size(); ++i) {
    if (ros_only.count(m.bools[i].name)) continue;
    m.bools[i].value = !m.bools[i].value;
    ++*changed;
  }
  Config out = def;
  EXPECT_TRUE(out.__fromMessage__(m));
  return out;
}

TEST(ParameterMapping, CfgDefaultsEqualDefaultYaml) {
  const core::PipelineConfig yaml = DefaultYaml();
  ExpectSameValues(ToScanMatchingConfig(yaml.session.odometry), ScanMatchingConfig::__getDefault__(),
                   "ScanMatching.cfg");
  ExpectSameValues(ToSubmapManagerConfig(yaml.session), SubmapManagerConfig::__getDefault__(),
                   "SubmapManager.cfg");
  ExpectSameValues(ToPlaceRecognitionConfig(yaml.place_recognition, yaml.merge.matching),
                   PlaceRecognitionConfig::__getDefault__(), "PlaceRecognition.cfg");
  ExpectSameValues(ToMapMergingConfig(yaml.merge), MapMergingConfig::__getDefault__(),
                   "MapMerging.cfg");
}

TEST(ParameterMapping, EveryParameterReachesTheCoreAndComesBack) {
  int changed = 0;
  {
    const ScanMatchingConfig p = Perturbed<ScanMatchingConfig>({}, &changed);
    core::OdometryConfig c;
    ApplyScanMatchingConfig(p, &c);
    ExpectSameValues(ToScanMatchingConfig(c), p, "ScanMatching");
    EXPECT_EQ(changed, 10);
  }
  {
    const SubmapManagerConfig p = Perturbed<SubmapManagerConfig>({}, &changed);
    core::SessionMapperConfig c;
    ApplySubmapManagerConfig(p, &c);
    ExpectSameValues(ToSubmapManagerConfig(c), p, "SubmapManager");
    EXPECT_EQ(changed, 62);
    EXPECT_TRUE(c.Validate().ok()) << c.Validate().message();
  }
  {
    const PlaceRecognitionConfig p = Perturbed<PlaceRecognitionConfig>({}, &changed);
    core::PlaceRecognizerConfig r;
    core::InterSessionMatcherConfig m;
    ApplyPlaceRecognitionConfig(p, &r, &m);
    ExpectSameValues(ToPlaceRecognitionConfig(r, m), p, "PlaceRecognition");
    EXPECT_EQ(changed, 8);
  }
  {
    // idle_finish_s and merged_map_voxel_m are read by the nodelet, not by the core.
    const MapMergingConfig p =
        Perturbed<MapMergingConfig>({"idle_finish_s", "merged_map_voxel_m"}, &changed);
    core::SessionMergerConfig c;
    ApplyMapMergingConfig(p, &c);
    ExpectSameValues(ToMapMergingConfig(c), p, "MapMerging");
    EXPECT_EQ(changed, 71);
  }
}

TEST(ParameterMapping, ApplyChangesTheCoreField) {
  SubmapManagerConfig p = SubmapManagerConfig::__getDefault__();
  p.submap_max_translation_m = 12.5;
  p.in_session_dynamics_enabled = false;
  core::SessionMapperConfig c;
  ApplySubmapManagerConfig(p, &c);
  EXPECT_EQ(c.submaps.max_translation_m, 12.5);
  EXPECT_FALSE(c.submaps.dynamic_filter.enabled);
  MapMergingConfig m = MapMergingConfig::__getDefault__();
  m.low_dynamics_seed_distance_m = 0.4;
  core::SessionMergerConfig g;
  ApplyMapMergingConfig(m, &g);
  EXPECT_EQ(g.dynamics.seed_distance_m, 0.4);
}

}  // namespace
}  // namespace ros_params
}  // namespace multisession_mapper
