#include "multisession_mapper/core/local_plane.h"

#include <cmath>
#include <random>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

namespace multisession_mapper {
namespace core {
namespace {

TEST(LocalPlaneTest, TiltedPlaneGivesItsNormal) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-0.5, 0.5);
  std::normal_distribution<double> noise(0.0, 0.005);
  const Eigen::Vector3d n = Eigen::Vector3d(0.3, -0.2, 1.0).normalized();
  const Eigen::Vector3d e1 = n.unitOrthogonal();
  const Eigen::Vector3d e2 = n.cross(e1);
  CovarianceAccumulator acc;
  for (int i = 0; i < 30; ++i) acc.Add(u(rng) * e1 + u(rng) * e2 + noise(rng) * n);
  Eigen::Vector3d normal;
  ASSERT_TRUE(acc.Normal(LocalPlaneCriteria(), &normal));
  EXPECT_GT(std::abs(normal.dot(n)), 0.999);
}

TEST(LocalPlaneTest, LineBlobAndTooFewPointsGiveNoNormal) {
  Eigen::Vector3d normal;
  CovarianceAccumulator line;
  for (int i = 0; i < 20; ++i) line.Add(Eigen::Vector3d(0.1 * i, 0.0, 0.001 * (i % 2)));
  EXPECT_FALSE(line.Normal(LocalPlaneCriteria(), &normal));

  std::mt19937 rng(4);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  CovarianceAccumulator blob;
  for (int i = 0; i < 200; ++i) blob.Add(Eigen::Vector3d(u(rng), u(rng), u(rng)));
  EXPECT_FALSE(blob.Normal(LocalPlaneCriteria(), &normal));

  CovarianceAccumulator few;
  few.Add(Eigen::Vector3d(0, 0, 0));
  few.Add(Eigen::Vector3d(1, 0, 0));
  few.Add(Eigen::Vector3d(0, 1, 0));
  EXPECT_FALSE(few.Normal(LocalPlaneCriteria(), &normal));  // min_points = 5
}

TEST(LocalPlaneTest, ValidateRejectsBadCriteria) {
  LocalPlaneCriteria c;
  EXPECT_TRUE(c.Validate().ok());
  c.min_points = 2;
  EXPECT_FALSE(c.Validate().ok());
  c = LocalPlaneCriteria();
  c.max_flatness = 0.0;
  EXPECT_FALSE(c.Validate().ok());
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
