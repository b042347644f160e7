#include "multisession_mapper/core/submap_registration.h"

#include <algorithm>
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "multisession_mapper/core/se3.h"
#include "multisession_mapper/core/voxel_downsample.h"
#include "synthetic_lidar_scene.h"

namespace multisession_mapper {
namespace core {
namespace {

constexpr double kDeg = M_PI / 180.0;

// Two "submaps" of the synthetic scene: 5 static scans each, around poses 3 m apart.
struct SubmapPair {
  PointVector target, source;  // each in its own frame
  Pose3 T_target_source;
};

SubmapPair MakeSubmapPair() {
  const test::SyntheticScene scene(5, 60, 50.0, {Eigen::Vector2d(0, 0), Eigen::Vector2d(3, 0)},
                                   6.0);
  const Pose3 T_world_target = se3::FromXyzRpy(0.0, 0.0, 1.8, 0.0, 0.0, 0.0);
  const Pose3 T_world_source = se3::FromXyzRpy(3.0, 0.4, 1.8, 0.0, 0.0, 10.0 * kDeg);
  SubmapPair pair;
  pair.T_target_source = T_world_target.inverse() * T_world_source;
  for (int i = 0; i < 5; ++i) {
    const Pose3 step = se3::FromXyzRpy(0.6 * i, 0.0, 0.0, 0.0, 0.0, 1.0 * kDeg * i);
    for (const auto& [T_world_submap, out] :
         {std::pair<Pose3, PointVector*>{T_world_target, &pair.target},
          std::pair<Pose3, PointVector*>{T_world_source, &pair.source}}) {
      const Pose3 T_world_sensor = T_world_submap * step;
      const LidarScan scan = test::SimulateVlp16(
          scene, [&](double) { return T_world_sensor; }, 0.0, 30 + i, 0.01, 1800, 0.1, false);
      for (const Eigen::Vector3d& p : ScanToPointVector(scan)) out->push_back(step * p);
    }
  }
  return pair;
}

TEST(SubmapRegistrationTest, RegistersFromAPerturbedPriorAndAcceptsTheLoop) {
  const SubmapPair pair = MakeSubmapPair();
  const SubmapRegistrationConfig config;
  const SubmapRegistration registration = SubmapRegistration::Create(config).value();
  const SubmapTarget target = SubmapTarget::Create(pair.target, config).value();
  const Pose3 prior = pair.T_target_source * se3::FromXyzRpy(0.5, -0.3, 0.1, 0.0, 0.0, 3 * kDeg);
  const SubmapRegistrationResult result = registration.Register(pair.source, target, prior);
  ASSERT_TRUE(result.accepted) << result.reason;
  const Pose3 error = se3::Between(pair.T_target_source, result.T_target_source);
  EXPECT_LT(se3::TranslationNorm(error), 0.05);
  EXPECT_LT(se3::RotationAngleRad(error), 0.2 * kDeg);
  EXPECT_GT(result.overlap_ratio, config.min_overlap_ratio);
}

// A submap's points may come in any order (they are stored in Z-order since session 69): the
// registration samples them independently of it, so shuffled submaps give the same result to
// the bit.
TEST(SubmapRegistrationTest, ThePointOrderChangesNothing) {
  const SubmapPair pair = MakeSubmapPair();
  const SubmapRegistrationConfig config;
  const SubmapRegistration registration = SubmapRegistration::Create(config).value();
  const Pose3 prior = pair.T_target_source * se3::FromXyzRpy(0.3, -0.2, 0.0, 0.0, 0.0, 2 * kDeg);
  const SubmapRegistrationResult result = registration.Register(
      pair.source, SubmapTarget::Create(pair.target, config).value(), prior);
  ASSERT_TRUE(result.accepted) << result.reason;
  PointVector source = pair.source, target = pair.target;
  std::mt19937 rng(3);
  std::shuffle(source.begin(), source.end(), rng);
  std::shuffle(target.begin(), target.end(), rng);
  const SubmapRegistrationResult shuffled =
      registration.Register(source, SubmapTarget::Create(target, config).value(), prior);
  EXPECT_EQ(shuffled.T_target_source.matrix(), result.T_target_source.matrix());
  EXPECT_EQ(shuffled.overlap_ratio, result.overlap_ratio);
}

// The merger's proximity search takes over the targets the inter-session matching built when
// they are built like its own: BuiltLike must tell apart every setting that changes a target.
TEST(SubmapRegistrationTest, BuiltLikeComparesTheTargetSettingsOnly) {
  const SubmapPair pair = MakeSubmapPair();
  SubmapRegistrationConfig config;
  const SubmapTarget target = SubmapTarget::Create(pair.target, config).value();
  EXPECT_TRUE(target.BuiltLike(config));
  SubmapRegistrationConfig other = config;
  other.max_correction_m = 1.0;  // registration bounds do not change the target
  other.source_voxel_m = 0.8;
  other.min_overlap_ratio = 0.7;
  EXPECT_TRUE(target.BuiltLike(other));
  other = config;
  other.target_voxel_m = 0.2;
  EXPECT_FALSE(target.BuiltLike(other));
  other = config;
  other.target.normal_neighbors = 12;
  EXPECT_FALSE(target.BuiltLike(other));
  other = config;
  other.target.max_normal_radius_m = 1.0;
  EXPECT_FALSE(target.BuiltLike(other));
  other = config;
  other.target.plane.max_flatness = 0.2;
  EXPECT_FALSE(target.BuiltLike(other));
  other = config;
  other.target.plane.min_mid_std_m = 0.05;
  EXPECT_FALSE(target.BuiltLike(other));

  // A target built like the config registers exactly as a fresh one.
  const SubmapRegistration registration = SubmapRegistration::Create(config).value();
  const SubmapTarget fresh = SubmapTarget::Create(pair.target, config).value();
  const Pose3 prior = pair.T_target_source * se3::FromXyzRpy(0.3, 0.2, 0.0, 0.0, 0.0, 2 * kDeg);
  const SubmapRegistrationResult a = registration.Register(pair.source, target, prior);
  const SubmapRegistrationResult b = registration.Register(pair.source, fresh, prior);
  EXPECT_TRUE(a.T_target_source.matrix().isApprox(b.T_target_source.matrix(), 0.0));
  EXPECT_EQ(a.overlap_ratio, b.overlap_ratio);
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
