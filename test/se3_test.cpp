#include "multisession_mapper/core/se3.h"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

namespace multisession_mapper {
namespace core {
namespace {

Pose3 RandomPose(std::mt19937* rng) {
  std::uniform_real_distribution<double> t(-50.0, 50.0);
  std::uniform_real_distribution<double> a(-M_PI, M_PI);
  return se3::FromXyzRpy(t(*rng), t(*rng), t(*rng), a(*rng) * 0.3, a(*rng) * 0.3, a(*rng));
}

TEST(Se3, ExpLogRoundTrip) {
  std::mt19937 rng(42);
  for (int i = 0; i < 200; ++i) {
    const Pose3 pose = RandomPose(&rng);
    const Pose3 back = se3::Exp(se3::Log(pose));
    EXPECT_TRUE(back.isApprox(pose, 1e-9)) << "iteration " << i;
  }
}

TEST(Se3, LogOfIdentityIsZero) {
  EXPECT_NEAR(se3::Log(Pose3::Identity()).norm(), 0.0, 1e-15);
}

TEST(Se3, FromXyzRpyMatchesAxisRotations) {
  const Pose3 yaw = se3::FromXyzRpy(1, 2, 3, 0, 0, M_PI / 2);
  // A 90 degree yaw maps the x axis onto y.
  EXPECT_TRUE((yaw.linear() * Eigen::Vector3d::UnitX()).isApprox(Eigen::Vector3d::UnitY(), 1e-12));
  EXPECT_TRUE(yaw.translation().isApprox(Eigen::Vector3d(1, 2, 3)));
  const Pose3 pitch = se3::FromXyzRpy(0, 0, 0, 0, M_PI / 2, 0);
  // A positive pitch about y maps z onto x.
  EXPECT_TRUE(
      (pitch.linear() * Eigen::Vector3d::UnitZ()).isApprox(Eigen::Vector3d::UnitX(), 1e-12));
}

TEST(Se3, InterpolateEndpointsAndMidpoint) {
  const Pose3 a = se3::FromXyzRpy(0, 0, 0, 0, 0, 0);
  const Pose3 b = se3::FromXyzRpy(2, 4, 0, 0, 0, 1.0);
  EXPECT_TRUE(se3::Interpolate(a, b, 0.0).isApprox(a, 1e-12));
  EXPECT_TRUE(se3::Interpolate(a, b, 1.0).isApprox(b, 1e-12));
  const Pose3 mid = se3::Interpolate(a, b, 0.5);
  EXPECT_TRUE(mid.translation().isApprox(Eigen::Vector3d(1, 2, 0), 1e-12));
  EXPECT_NEAR(se3::RotationAngleRad(mid), 0.5, 1e-12);
}

TEST(Se3, InterpolateExtrapolatesRotation) {
  const Pose3 a = Pose3::Identity();
  const Pose3 b = se3::FromXyzRpy(1, 0, 0, 0, 0, 0.2);
  const Pose3 c = se3::Interpolate(a, b, 2.0);
  EXPECT_NEAR(se3::RotationAngleRad(c), 0.4, 1e-12);
  EXPECT_NEAR(c.translation().x(), 2.0, 1e-12);
}

TEST(Se3, BetweenComposesBack) {
  std::mt19937 rng(7);
  for (int i = 0; i < 50; ++i) {
    const Pose3 a = RandomPose(&rng);
    const Pose3 b = RandomPose(&rng);
    EXPECT_TRUE((a * se3::Between(a, b)).isApprox(b, 1e-9));
  }
}

TEST(Se3, RotationAngleAndTranslationNorm) {
  const Pose3 p = se3::FromXyzRpy(3, 4, 0, 0.3, 0, 0);
  EXPECT_NEAR(se3::RotationAngleRad(p), 0.3, 1e-12);
  EXPECT_NEAR(se3::TranslationNorm(p), 5.0, 1e-12);
  EXPECT_NEAR(se3::RotationAngleRad(se3::FromXyzRpy(0, 0, 0, 0, 0, M_PI)), M_PI, 1e-9);
}

TEST(Se3, IsValidRejectsNonOrthonormalAndNaN) {
  Pose3 p = Pose3::Identity();
  EXPECT_TRUE(se3::IsValid(p));
  p.linear()(0, 0) = 1.1;
  EXPECT_FALSE(se3::IsValid(p));
  EXPECT_TRUE(se3::IsValid(se3::Normalized(se3::FromXyzRpy(1, 2, 3, 0.1, 0.2, 0.3))));
  Pose3 q = Pose3::Identity();
  q.translation().x() = std::nan("");
  EXPECT_FALSE(se3::IsValid(q));
  Pose3 mirror = Pose3::Identity();
  mirror.linear()(2, 2) = -1.0;  // orthonormal but a reflection
  EXPECT_FALSE(se3::IsValid(mirror));
}

// Heading and horizontal position of one pose, roll, pitch and height of the other.
TEST(Se3, WithTiltAndHeightOfKeepsHeadingAndPosition) {
  Pose3 pose = Pose3::Identity();
  pose.linear() = (Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ()) *
                   Eigen::AngleAxisd(0.01, Eigen::Vector3d::UnitY()))
                      .toRotationMatrix();
  pose.translation() = Eigen::Vector3d(3.0, -2.0, 1.0);
  Pose3 other = Pose3::Identity();
  other.linear() = (Eigen::AngleAxisd(0.75, Eigen::Vector3d::UnitZ()) *
                    Eigen::AngleAxisd(0.02, Eigen::Vector3d::UnitY()) *
                    Eigen::AngleAxisd(-0.03, Eigen::Vector3d::UnitX()))
                       .toRotationMatrix();
  other.translation() = Eigen::Vector3d(3.2, -2.1, 1.3);
  const Pose3 out = se3::WithTiltAndHeightOf(pose, other);
  EXPECT_NEAR(out.translation().x(), 3.0, 1e-12);
  EXPECT_NEAR(out.translation().y(), -2.0, 1e-12);
  EXPECT_NEAR(out.translation().z(), 1.3, 1e-12);
  const Eigen::Vector3d ypr = out.rotation().eulerAngles(2, 1, 0);
  EXPECT_NEAR(ypr(0), 0.7, 1e-9);
  EXPECT_NEAR(ypr(1), 0.02, 1e-9);
  EXPECT_NEAR(ypr(2), -0.03, 1e-9);
  // A pose whose x axis is vertical has no heading to keep: unchanged.
  Pose3 upright = Pose3::Identity();
  upright.linear() = Eigen::AngleAxisd(-M_PI / 2, Eigen::Vector3d::UnitY()).toRotationMatrix();
  EXPECT_TRUE(se3::WithTiltAndHeightOf(upright, other).isApprox(upright));
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
