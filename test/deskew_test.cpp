#include "multisession_mapper/core/deskew.h"

#include <cmath>
#include <algorithm>
#include <vector>
#include <random>

#include <gtest/gtest.h>

#include "synthetic_lidar_scene.h"

namespace multisession_mapper {
namespace core {
namespace {

TEST(DeskewTest, RemovesAKnownConstantVelocityDistortionExactly) {
  // True points in the frame at the stamp; the sensor moves with twist xi, so a point seen at
  // time t is measured in the frame Exp(xi t): p_t = Exp(xi t)^-1 p_0.
  se3::Vector6d xi;
  xi << 3.0, 0.4, 0.0, 0.02, -0.01, 1.2;  // 3 m/s forward, 1.2 rad/s yaw
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-40.0, 40.0);
  LidarScan scan;
  scan.has_time = true;
  PointVector truth;
  for (int i = 0; i < 5000; ++i) {
    const Eigen::Vector3d p0(u(rng), u(rng), u(rng) * 0.1);
    const double t = 0.1 * i / 5000.0;
    LidarPoint p;
    p.position_m = (se3::Exp(xi * t).inverse() * p0).cast<float>();
    p.time_s = static_cast<float>(t);
    scan.points.push_back(p);
    truth.push_back(p0);
  }
  const Deskewer deskewer = Deskewer::Create(DeskewConfig()).value();
  DeskewStats stats;
  const LidarScan out = deskewer.Apply(scan, xi, &stats);
  EXPECT_TRUE(stats.applied);
  ASSERT_EQ(out.points.size(), truth.size());
  double max_err = 0.0, max_skew = 0.0;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    max_err = std::max(max_err, (out.points[i].position_m.cast<double>() - truth[i]).norm());
    max_skew = std::max(max_skew, (scan.points[i].position_m.cast<double>() - truth[i]).norm());
  }
  EXPECT_GT(max_skew, 1.0);    // the distortion is large ...
  EXPECT_LT(max_err, 1e-4);    // ... and removed down to float precision
  EXPECT_FLOAT_EQ(out.points.back().time_s, scan.points.back().time_s);  // attributes kept
}

TEST(DeskewTest, MatchesTheTrueMotionOfATurningVehicle) {
  // Sensor turning at 1.5 rad/s and driving 3 m/s past boxes, velocity from the true motion
  // over the sweep: de-skewed points land where the true motion puts them.
  const test::VehicleTrajectory trajectory(3.0, {{2.0, 1.5}});
  const test::SyntheticScene scene(11, 60, 50.0, trajectory.PathXy(), 4.0);
  const auto pose_at = [&](double t) { return trajectory.PoseAt(t); };
  const double stamp = 1.0;
  const LidarScan scan = test::SimulateVlp16(scene, pose_at, stamp, 1, 0.0);
  const Pose3 T0 = trajectory.PoseAt(stamp);
  const Pose3 T1 = trajectory.PoseAt(stamp + 0.1);
  const se3::Vector6d xi = Deskewer::VelocityFromMotion(se3::Between(T0, T1), 0.1);
  const LidarScan out = Deskewer::Create(DeskewConfig()).value().Apply(scan, xi);
  // Truth: the measured point moved by the true motion since the stamp, T0^-1 T(t).
  std::vector<double> raw_err, fixed_err;
  for (std::size_t i = 0; i < scan.points.size(); ++i) {
    const Pose3 T_t = trajectory.PoseAt(stamp + scan.points[i].time_s);
    const Eigen::Vector3d truth = T0.inverse() * T_t * scan.points[i].position_m.cast<double>();
    raw_err.push_back((scan.points[i].position_m.cast<double>() - truth).norm());
    fixed_err.push_back((out.points[i].position_m.cast<double>() - truth).norm());
  }
  ASSERT_GT(raw_err.size(), 5000u);
  const auto median = [](std::vector<double> v) {
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    return v[v.size() / 2];
  };
  EXPECT_GT(median(raw_err), 0.5);    // metres of skew at 1.5 rad/s
  EXPECT_LT(median(fixed_err), 0.02);  // only the arc-vs-line and sway model error remains
  EXPECT_LT(*std::max_element(fixed_err.begin(), fixed_err.end()), 0.1);
}

TEST(DeskewTest, ScanWithoutTimeOrDisabledIsUnchanged) {
  LidarScan scan;
  scan.has_time = false;
  LidarPoint p;
  p.position_m = Eigen::Vector3f(10.0f, 0.0f, 0.0f);
  p.time_s = 0.05f;
  scan.points.push_back(p);
  se3::Vector6d xi = se3::Vector6d::Zero();
  xi(0) = 3.0;
  DeskewStats stats;
  const Deskewer deskewer = Deskewer::Create(DeskewConfig()).value();
  EXPECT_EQ(deskewer.Apply(scan, xi, &stats).points[0].position_m, p.position_m);
  EXPECT_FALSE(stats.applied);
  DeskewConfig off;
  off.enabled = false;
  scan.has_time = true;
  EXPECT_EQ(Deskewer::Create(off).value().Apply(scan, xi, &stats).points[0].position_m,
            p.position_m);
  EXPECT_FALSE(stats.applied);
}

TEST(DeskewTest, ClampsCorruptTimesAndVelocityRoundTrips) {
  LidarScan scan;
  scan.has_time = true;
  LidarPoint p;
  p.position_m = Eigen::Vector3f(1.0f, 0.0f, 0.0f);
  p.time_s = 50.0f;  // corrupt
  scan.points.push_back(p);
  se3::Vector6d xi = se3::Vector6d::Zero();
  xi(0) = 1.0;
  DeskewStats stats;
  const LidarScan out = Deskewer::Create(DeskewConfig()).value().Apply(scan, xi, &stats);
  EXPECT_EQ(stats.clamped, 1u);
  EXPECT_NEAR(out.points[0].position_m.x(), 1.0f + 0.2f, 1e-5);

  const Pose3 motion = se3::FromXyzRpy(0.3, 0.01, 0.0, 0.0, 0.0, 0.12);
  const se3::Vector6d v = Deskewer::VelocityFromMotion(motion, 0.1);
  EXPECT_TRUE(se3::Exp(v * 0.1).isApprox(motion, 1e-9));
  EXPECT_TRUE(Deskewer::VelocityFromMotion(motion, 0.0).isZero());
  DeskewConfig bad;
  bad.max_time_offset_s = 0.0;
  EXPECT_FALSE(Deskewer::Create(bad).ok());
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
