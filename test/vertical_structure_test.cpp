#include "multisession_mapper/core/vertical_structure.h"

#include <algorithm>
#include <cmath>
#include <random>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "multisession_mapper/core/se3.h"

namespace multisession_mapper {
namespace core {
namespace {

constexpr double kDeg = M_PI / 180.0;

constexpr double kSensorHeight = 1.8;  // the frames below are the sensor's: ground at -1.8 m

// Points on the vertical rectangle from (x0, y0) to (x1, y1), 0-6 m high, every ~0.1 m, with
// 1 cm of range noise along its normal.
void AddWall(double x0, double y0, double x1, double y1, std::mt19937* rng, PointVector* out) {
  std::normal_distribution<double> noise(0.0, 0.01);
  const Eigen::Vector3d a(x0, y0, 0.0), b(x1, y1, 0.0);
  const Eigen::Vector3d along = (b - a).normalized();
  const Eigen::Vector3d normal(-along.y(), along.x(), 0.0);
  const int n = static_cast<int>((b - a).norm() / 0.1);
  for (int i = 0; i <= n; ++i) {
    for (int k = 0; k <= 60; ++k) {
      out->push_back(a + (b - a) * i / n + Eigen::Vector3d(0, 0, 0.1 * k - kSensorHeight) +
                     noise(*rng) * normal);
    }
  }
}

// Ground sloping 4 % along x (a ramp): its normal is 2.3 deg from vertical and must not count.
void AddSlopedGround(std::mt19937* rng, PointVector* out) {
  std::normal_distribution<double> noise(0.0, 0.01);
  for (double x = -15.0; x <= 15.0; x += 0.15) {
    for (double y = -15.0; y <= 15.0; y += 0.15) {
      out->push_back({x, y, 0.04 * x - kSensorHeight + noise(*rng)});
    }
  }
}

// A row of parked cars (1.5 m boxes) standing on a road that slopes 4 % sideways: their sides
// lean 2.3 deg with it.
void AddParkedCarsOnASlope(std::mt19937* rng, PointVector* out) {
  std::normal_distribution<double> noise(0.0, 0.01);
  const Eigen::Matrix3d lean = Eigen::AngleAxisd(std::atan(0.04), Eigen::Vector3d::UnitX()).toRotationMatrix();
  for (int car = 0; car < 6; ++car) {
    const double x0 = -13.0 + 4.5 * car;
    for (double x = x0; x <= x0 + 4.2; x += 0.1) {
      for (double h = 0.3; h <= 1.5; h += 0.1) {
        for (double y : {-2.0, -0.2}) {
          out->push_back(lean * Eigen::Vector3d(x, y + noise(*rng), h) -
                         Eigen::Vector3d(0, 0, kSensorHeight));
        }
      }
    }
  }
}

PointVector Rotated(const PointVector& points, const Eigen::Matrix3d& R) {
  PointVector out;
  for (const Eigen::Vector3d& p : points) out.push_back(R * p);
  return out;
}

double AngleDeg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::min(1.0, std::abs(a.normalized().dot(b.normalized())))) / kDeg;
}

// Four facades around a sloped yard with cars parked on the slope.
PointVector Courtyard(std::mt19937* rng) {
  PointVector world;
  AddWall(-12, -10, 12, -10, rng, &world);
  AddWall(12, -10, 12, 10, rng, &world);
  AddWall(12, 10, -12, 10, rng, &world);
  AddWall(-12, 10, -12, -10, rng, &world);
  AddSlopedGround(rng, &world);
  AddParkedCarsOnASlope(rng, &world);
  return world;
}

TEST(VerticalStructureTest, CourtyardGivesTheTrueVerticalDespiteASlopedGround) {
  std::mt19937 rng(1);
  const PointVector world = Courtyard(&rng);
  // The sensor frame is tilted: the world's up is R * z in it.
  const Eigen::Matrix3d R = se3::FromXyzRpy(0, 0, 0, 1.5 * kDeg, -1.0 * kDeg, 0.4).rotation();
  const VerticalStructureConfig config;
  const VerticalEvidence evidence = EstimateVerticalEvidence(Rotated(world, R), config);
  ASSERT_TRUE(evidence.valid);
  const Eigen::Vector3d truth = R * Eigen::Vector3d::UnitZ();
  EXPECT_LT(AngleDeg(evidence.up, truth), 0.05);
  EXPECT_GT(evidence.up.z(), 0.0);
  // Without the height gate the leaning cars pull the estimate off.
  VerticalStructureConfig every_point = config;
  every_point.min_height_m = -10.0;
  const VerticalEvidence biased = EstimateVerticalEvidence(Rotated(world, R), every_point);
  ASSERT_TRUE(biased.valid);
  EXPECT_GT(AngleDeg(biased.up, truth), 0.1);
  EXPECT_GT(evidence.conditioning, 0.5);  // walls in both directions
  // Scaled so that the best-seen axis has sigma_rad; nothing along up itself.
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(evidence.information);
  EXPECT_NEAR(solver.eigenvalues()(2), 1.0 / (config.sigma_rad * config.sigma_rad), 1e-3);
  EXPECT_LT(truth.dot(evidence.information * truth), 1e-3 * solver.eigenvalues()(2));
  // A 1 deg tilt costs about (1 deg / sigma)^2 in each direction.
  const Eigen::Vector3d tilted = Eigen::AngleAxisd(1.0 * kDeg, R * Eigen::Vector3d::UnitX()) * truth;
  const double cost = tilted.dot(evidence.information * tilted);
  EXPECT_GT(cost, 0.4 * std::pow(kDeg / config.sigma_rad, 2));
}

TEST(VerticalStructureTest, ThreadsChangeNothing) {
  // The normals are estimated in blocks on the threads and gathered in point order: the
  // evidence must be the same to the bit with 1, 2 and 3 threads.
  std::mt19937 rng(4);
  const PointVector world = Courtyard(&rng);
  VerticalStructureConfig config;
  config.threads = 1;
  const VerticalEvidence one = EstimateVerticalEvidence(world, config);
  ASSERT_TRUE(one.valid);
  ASSERT_GT(one.wall_points, 1024) << "several blocks of points";
  for (const int threads : {2, 3}) {
    config.threads = threads;
    const VerticalEvidence more = EstimateVerticalEvidence(world, config);
    EXPECT_EQ(more.wall_points, one.wall_points) << threads << " threads";
    EXPECT_EQ(more.up, one.up) << threads << " threads";
    EXPECT_EQ(more.information, one.information) << threads << " threads";
  }
  config.threads = 0;
  EXPECT_FALSE(config.Validate().ok());
}

TEST(VerticalStructureTest, ThePointOrderChangesNothing) {
  // A submap's points may come in any order: the wall sample does not depend on it.
  std::mt19937 rng(6);
  PointVector world = Courtyard(&rng);
  const VerticalStructureConfig config;
  const VerticalEvidence evidence = EstimateVerticalEvidence(world, config);
  ASSERT_TRUE(evidence.valid);
  std::shuffle(world.begin(), world.end(), rng);
  const VerticalEvidence shuffled = EstimateVerticalEvidence(world, config);
  EXPECT_EQ(shuffled.wall_points, evidence.wall_points);
  EXPECT_EQ(shuffled.up, evidence.up);
  EXPECT_EQ(shuffled.information, evidence.information);
}

TEST(VerticalStructureTest, ParallelWallsConstrainOnlyTheTiltAboutTheirNormal) {
  std::mt19937 rng(2);
  PointVector world;
  AddWall(-20, 5, 20, 5, &rng, &world);  // two facades facing each other across a street
  AddWall(20, -5, -20, -5, &rng, &world);
  const VerticalEvidence evidence = EstimateVerticalEvidence(world, VerticalStructureConfig());
  ASSERT_TRUE(evidence.valid);
  EXPECT_LT(evidence.conditioning, 0.05);
  const Eigen::Vector3d normal = Eigen::Vector3d::UnitY(), along = Eigen::Vector3d::UnitX();
  EXPECT_GT(normal.dot(evidence.information * normal),
            50.0 * along.dot(evidence.information * along));
}

TEST(VerticalStructureTest, NoWallsGiveNoEvidence) {
  std::mt19937 rng(3);
  PointVector ground;
  AddSlopedGround(&rng, &ground);
  const VerticalEvidence evidence = EstimateVerticalEvidence(ground, VerticalStructureConfig());
  EXPECT_FALSE(evidence.valid);
  EXPECT_TRUE(evidence.information.isZero());
  VerticalStructureConfig disabled;
  disabled.enabled = false;
  PointVector walls;
  AddWall(-12, -10, 12, -10, &rng, &walls);
  AddWall(12, -10, 12, 10, &rng, &walls);
  EXPECT_TRUE(EstimateVerticalEvidence(walls, VerticalStructureConfig()).valid);
  EXPECT_FALSE(EstimateVerticalEvidence(walls, disabled).valid);
  EXPECT_FALSE(EstimateVerticalEvidence(PointVector(), VerticalStructureConfig()).valid);
}

TEST(VerticalStructureTest, ConfigIsValidated) {
  EXPECT_TRUE(VerticalStructureConfig().Validate().ok());
  VerticalStructureConfig c;
  c.sigma_rad = 0.0;
  EXPECT_FALSE(c.Validate().ok());
  c = VerticalStructureConfig();
  c.max_wall_tilt_rad = 2.0;
  EXPECT_FALSE(c.Validate().ok());
  c = VerticalStructureConfig();
  c.min_height_m = NAN;
  EXPECT_FALSE(c.Validate().ok());
  c = VerticalStructureConfig();
  c.neighbours = 1;
  EXPECT_FALSE(c.Validate().ok());
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
