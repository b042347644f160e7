#include "multisession_mapper/sim/robot_trajectory.h"

#include <cmath>

#include <gtest/gtest.h>

#include "multisession_mapper/core/se3.h"

namespace multisession_mapper {
namespace sim {
namespace {

// A 4 % slope along x, 2 % along y.
Terrain Slope() {
  TerrainGrid g;
  g.origin_m = Eigen::Vector2d(-100, -100);
  g.resolution_m = 2.0;
  g.cols = g.rows = 101;
  for (int r = 0; r < g.rows; ++r) {
    for (int c = 0; c < g.cols; ++c) {
      g.heights_m.push_back(static_cast<float>(0.04 * (-100 + 2 * c) + 0.02 * (-100 + 2 * r)));
    }
  }
  g.materials.assign(100 * 100, 1);
  return Terrain::Create(g).value();
}

TEST(SimRobotTrajectoryTest, SmoothSpeedTurnsAndTerrainFollowing) {
  const Terrain terrain = Slope();
  RobotTrajectoryConfig config;
  config.cruise_speed_mps = 2.0;
  auto traj = RobotTrajectory::Create(config, {{-50, 0}, {30, 0}, {30, 40}}, terrain, 1000.0);
  ASSERT_TRUE(traj.ok()) << traj.status().message();
  const RobotTrajectory& t = traj.value();
  EXPECT_NEAR(t.start_stamp_s(), 1000.0, 1e-9);
  EXPECT_GT(t.length_m(), 110.0);
  EXPECT_LT(t.length_m(), 120.0);
  double max_speed = 0.0, max_accel = 0.0;
  const double dt = 0.1;
  for (double s = t.start_stamp_s() + dt; s < t.end_stamp_s() - dt; s += dt) {
    const double v = t.Speed(s);
    max_speed = std::max(max_speed, v);
    max_accel = std::max(max_accel, std::abs(t.Speed(s + dt) - t.Speed(s - dt)) / (2 * dt));
    // Speed agrees with the motion of the pose.
    const double moved =
        (t.BasePose(s + 0.05).translation() - t.BasePose(s - 0.05).translation()).norm();
    EXPECT_NEAR(moved / 0.1, v, 0.1);
    // Sensor 1.5 m above the ground, the base on it.
    const Eigen::Vector3d base = t.BasePose(s).translation();
    EXPECT_NEAR(base.z(), terrain.Height(base.x(), base.y()), 0.02);
    const Eigen::Vector3d sensor = t.SensorPose(s).translation();
    EXPECT_NEAR(sensor.z() - terrain.Height(sensor.x(), sensor.y()), 1.5, 0.05);
  }
  EXPECT_LE(max_speed, 2.0 + 1e-6);
  EXPECT_GT(max_speed, 1.9);
  EXPECT_LT(max_accel, 0.6);  // limit 0.5 m/s^2, smoothed (turn entries add a little)
  // Driving +x up a 4 % slope: nose up (negative pitch in the Rz Ry Rx convention).
  const Eigen::Vector3d forward = t.BasePose(1010.0).linear().col(0);
  EXPECT_NEAR(forward.z(), 0.04 / std::sqrt(1.0 + 0.0016), 0.005);
  // Driving +y after the left turn: the 4 % slope is across, roll to the right side up... the
  // left (-x) side is lower: the body's y axis points to -x and down.
  const core::Pose3 after_turn = t.BasePose(t.end_stamp_s() - 3.0);
  EXPECT_NEAR(after_turn.linear().col(0).y(), 1.0, 0.01);
  EXPECT_NEAR(after_turn.linear().col(1).z(), -0.04, 0.005);
  // Right lane: 1.5 m right of the centreline (y = 0 while driving +x).
  EXPECT_NEAR(t.BasePose(1010.0).translation().y(), -1.5, 1e-6);
}

TEST(SimRobotTrajectoryTest, RejectsBadInput) {
  const Terrain terrain = Slope();
  RobotTrajectoryConfig config;
  EXPECT_FALSE(RobotTrajectory::Create(config, {{0, 0}}, terrain, 0.0).ok());
  EXPECT_FALSE(RobotTrajectory::Create(config, {{0, 0}, {0, 0}}, terrain, 0.0).ok());
  EXPECT_FALSE(RobotTrajectory::Create(config, {{0, 0}, {10, 0}, {0, 0}}, terrain, 0.0).ok());
  config.cruise_speed_mps = -1.0;
  EXPECT_FALSE(RobotTrajectory::Create(config, {{0, 0}, {10, 0}}, terrain, 0.0).ok());
}

}  // namespace
}  // namespace sim
}  // namespace multisession_mapper
