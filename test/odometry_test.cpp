#include "multisession_mapper/core/odometry.h"

#include <algorithm>
#include <cmath>
#include <iostream>
#include <limits>
#include <vector>

#include <gtest/gtest.h>

#include "multisession_mapper/sim/campus_simulator.h"
#include "synthetic_lidar_scene.h"

namespace multisession_mapper {
namespace core {
namespace {

constexpr double kDeg = M_PI / 180.0;

struct SequenceErrors {
  double max_translation_m = 0.0;
  double max_rotation_rad = 0.0;
  double final_translation_m = 0.0;
  std::vector<double> total_ms;
  int registered = 0;
  int turn_hypotheses_tried = 0;
  int turn_hypotheses_won = 0;
  std::vector<double> icp_iterations;  ///< per registered scan, all its ICP runs
};

// Drives the odometry along `trajectory` through a synthetic scene at 10 Hz and compares its
// poses with the truth (odom frame = sensor frame of the first scan).
SequenceErrors RunSequence(const test::VehicleTrajectory& trajectory, bool with_time,
                           const OdometryConfig& config = OdometryConfig()) {
  const test::SyntheticScene scene(31, 120, 70.0, trajectory.PathXy(), 4.0);
  Odometry odometry = Odometry::Create(config).value();
  const auto pose_at = [&](double t) { return trajectory.PoseAt(t); };
  const Pose3 T_w0 = trajectory.PoseAt(0.0);
  SequenceErrors errors;
  const int num_scans = static_cast<int>(trajectory.duration_s() / 0.1) - 1;
  for (int k = 0; k < num_scans; ++k) {
    const double stamp = 0.1 * k;
    const LidarScan scan = test::SimulateVlp16(scene, pose_at, stamp, 100 + k, 0.01, 1200, 0.1,
                                               with_time);
    const StatusOr<OdometryResult> result = odometry.ProcessScan(scan);
    EXPECT_TRUE(result.ok()) << result.status().message();
    if (!result.ok()) continue;
    errors.registered += result.value().registered ? 1 : 0;
    errors.turn_hypotheses_tried += result.value().turn_hypotheses_tried ? 1 : 0;
    errors.turn_hypotheses_won += result.value().turn_hypothesis_won ? 1 : 0;
    errors.total_ms.push_back(result.value().timing.total_ms);
    if (result.value().registered) {
      errors.icp_iterations.push_back(result.value().icp_iterations);
    }
    const Pose3 truth = se3::Between(T_w0, trajectory.PoseAt(stamp));
    const Pose3 error = se3::Between(truth, result.value().pose);
    errors.max_translation_m = std::max(errors.max_translation_m, se3::TranslationNorm(error));
    errors.max_rotation_rad = std::max(errors.max_rotation_rad, se3::RotationAngleRad(error));
    errors.final_translation_m = se3::TranslationNorm(error);
  }
  return errors;
}

double Median(std::vector<double> v) {
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

// 3 m/s with a left and a right turn at 1 rad/s, reached at 2 rad/s^2 (3 m/s^2 lateral: a
// sharp turn for a ground robot), and +-0.3 deg of roll/pitch sway: ~24 m.
test::VehicleTrajectory SharpTurns() {
  return test::VehicleTrajectory(3.0, {{1.5, 0.0}, {1.6, 1.0}, {1.5, 0.0}, {1.6, -1.0}, {2.3, 0.0}},
                                 2.0, 0.25);
}

// The same course with campus-robot turns (0.4 rad/s, 1 rad/s^2).
test::VehicleTrajectory GentleTurns() {
  return test::VehicleTrajectory(3.0, {{1.5, 0.0}, {1.6, 0.4}, {1.5, 0.0}, {1.6, -0.4}, {2.3, 0.0}},
                                 1.0, 0.25);
}

// 1.8 m/s with yaw rates that step 0 <-> +-0.4 rad/s within one scan, as the campus simulator
// starts and ends its turns (no limit on the yaw acceleration).
test::VehicleTrajectory YawRateSteps() {
  return test::VehicleTrajectory(1.8, {{2.0, 0.0}, {2.5, 0.4}, {2.0, 0.0}, {2.5, -0.4}, {2.0, 0.0}},
                                 1e9, 0.25);
}

TEST(OdometryTest, TracksFastVehicleInGentleTurns) {
  const SequenceErrors e = RunSequence(GentleTurns(), true);
  std::cout << "gentle turns: max error " << e.max_translation_m << " m, "
            << e.max_rotation_rad / kDeg << " deg, final " << e.final_translation_m
            << " m, median " << Median(e.total_ms) << " ms/scan" << std::endl;
  EXPECT_GE(e.registered, static_cast<int>(e.total_ms.size()) - 1);  // all but the first
  // Measured ~0.09 m / 0.35 deg peak (the roll sway is tracked with a lag), ~0.02 m final;
  // with session 32's defaults (motion prior, its release, turn hypotheses) 0.061 m /
  // 0.35 deg, 0.060 m final.
  EXPECT_LT(e.max_translation_m, 0.2);
  EXPECT_LT(e.max_rotation_rad, 0.7 * kDeg);
  EXPECT_LT(e.final_translation_m, 0.1);
}

TEST(OdometryTest, KeepsTrackInSharpTurns) {
  const SequenceErrors e = RunSequence(SharpTurns(), true);
  std::cout << "sharp turns: max error " << e.max_translation_m << " m, "
            << e.max_rotation_rad / kDeg << " deg, final " << e.final_translation_m << " m"
            << std::endl;
  EXPECT_GE(e.registered, static_cast<int>(e.total_ms.size()) - 1);
  // Measured 0.06 m / 0.44 deg (session 32's defaults: 0.077 m / 0.41 deg, 0.067 m final;
  // with the motion model of the last interval only, 0.4-0.5 m /
  // ~1 deg transient while the yaw rate ramps), a few cm once the turn is steady.
  EXPECT_LT(e.max_translation_m, 0.8);
  EXPECT_LT(e.max_rotation_rad, 2.0 * kDeg);
  EXPECT_LT(e.final_translation_m, 0.15);
}

// The odometry's convergence thresholds (3 mm, 3e-4 rad, and 1 mm, 1e-4 rad for the runs that
// are compared; the ICP's own are 0.1 mm, 1e-5 rad) stop the iterations early for the same
// track.
TEST(OdometryTest, DefaultConvergenceSavesIterationsNotAccuracy) {
  const OdometryConfig loose;
  EXPECT_DOUBLE_EQ(loose.icp.convergence_translation_m, 3e-3);
  EXPECT_DOUBLE_EQ(loose.icp.convergence_rotation_rad, 3e-4);
  EXPECT_DOUBLE_EQ(loose.judge_convergence_translation_m, 1e-3);
  EXPECT_DOUBLE_EQ(loose.judge_convergence_rotation_rad, 1e-4);
  OdometryConfig tight = loose;  // the judge is never coarser than the ICP: 0.1 mm too
  tight.icp.convergence_translation_m = IcpConfig().convergence_translation_m;
  tight.icp.convergence_rotation_rad = IcpConfig().convergence_rotation_rad;
  const SequenceErrors with_loose = RunSequence(GentleTurns(), true, loose);
  const SequenceErrors with_tight = RunSequence(GentleTurns(), true, tight);
  const double loose_iterations = Median(with_loose.icp_iterations);
  const double tight_iterations = Median(with_tight.icp_iterations);
  std::cout << "ICP iterations per scan median: " << loose_iterations << " (3 mm, 3e-4 rad) "
            << tight_iterations << " (0.1 mm, 1e-5 rad); max error " << with_loose.max_translation_m
            << " m, " << with_loose.max_rotation_rad / kDeg << " deg against "
            << with_tight.max_translation_m << " m, " << with_tight.max_rotation_rad / kDeg
            << " deg" << std::endl;
  EXPECT_LT(loose_iterations, 0.8 * tight_iterations);
  EXPECT_LT(with_loose.max_translation_m, with_tight.max_translation_m + 0.02);
  EXPECT_LT(with_loose.max_rotation_rad, with_tight.max_rotation_rad + 0.1 * kDeg);
}

// Turns whose yaw rate steps from 0 to 0.4 rad/s and back within one scan (as the campus
// simulator drives): the prediction and its de-skew are a whole step (2.3 deg) off there.
TEST(OdometryTest, TurnHypothesesFollowYawRateSteps) {
  const test::VehicleTrajectory steps = YawRateSteps();
  // Measured with the ICP source voxel of their session (26), 1.5 m. With the 0.75 m default
  // of session 31 the trigger below rarely fires on this sequence (0.088 m / 0.48 deg
  // triggered against 0.087 m / 0.59 deg without; every scan 0.052 m / 0.26 deg).
  // Without the motion prior and the hypotheses, then the hypotheses on every scan (the
  // defaults since session 32 are the prior with a 0.9 trigger and 2 levels).
  OdometryConfig base;
  base.registration_voxel_size_m = 1.5;
  base.motion_prior_weight = 0.0;
  base.turn_hypothesis_step_rad_s = 0.0;
  base.turn_hypothesis_trigger = 0.0;
  base.turn_hypothesis_levels = 1;
  const SequenceErrors without = RunSequence(steps, true, base);
  OdometryConfig config = base;
  config.turn_hypothesis_step_rad_s = 0.4;
  config.turn_hypothesis_window_scans = 10;  // the first step comes after 20 scans
  const SequenceErrors with = RunSequence(steps, true, config);
  std::cout << "yaw-rate steps: max error without hypotheses " << without.max_translation_m
            << " m, " << without.max_rotation_rad / kDeg << " deg; with "
            << with.max_translation_m << " m, " << with.max_rotation_rad / kDeg << " deg"
            << std::endl;
  // Measured 0.099 m / 0.61 deg without, 0.045 m / 0.28 deg with (session 36's convergence
  // defaults: 0.099 m / 0.64 deg, 0.048 m / 0.27 deg).
  EXPECT_LT(with.max_translation_m, 0.07);
  EXPECT_LT(with.max_rotation_rad, 0.4 * kDeg);
  EXPECT_LT(with.max_rotation_rad, 0.7 * without.max_rotation_rad);
  EXPECT_EQ(without.turn_hypotheses_tried, 0);
  EXPECT_GT(with.turn_hypotheses_won, 0);

  // The hypotheses are judged by their mean kernel weight, so every run compared converges
  // at the judge's steps and iterations (1 mm, 1e-4 rad, 60), not at the coarse 3 mm /
  // 3e-4 rad of the other scans. Without the judge a hypothesis that needs more than 30
  // iterations to turn back 2.3 deg stops half-way, fits worse and loses (measured 0.56 deg
  // worst yaw error against 0.27 deg with the judge).
  // Compared with the crown filter from 0.5 m above the sensor, where it was measured: from
  // 1 m (the default since session 40) the box tops between 0.5 and 1 m take part again and
  // the unjudged hypotheses happen to turn back as far in this scene (0.270 against 0.269 deg
  // worst yaw error), so the judge's effect does not show there.
  // And with the rotation rate of the last interval, where it was measured: with the window
  // of 3 (the default since session 41) 0.320 deg with the judge, 0.313 deg without (the
  // hypotheses above: 0.050 m / 0.31 deg with, 0.146 m / 0.85 deg without).
  // And without the refinement with the map's ground normals (session 49), where it was
  // measured: with it 0.287 deg with the judge, 0.196 deg without in this synthetic scene.
  OdometryConfig judged = config;
  judged.high_point_min_height_m = 0.5;
  judged.rotation_window_scans = 1;
  judged.map_ground_min_depth_m = std::numeric_limits<double>::infinity();
  const SequenceErrors with_judge = RunSequence(steps, true, judged);
  OdometryConfig unjudged = judged;
  unjudged.judge_convergence_translation_m = unjudged.icp.convergence_translation_m;
  unjudged.judge_convergence_rotation_rad = unjudged.icp.convergence_rotation_rad;
  unjudged.judge_max_iterations = unjudged.icp.max_iterations;
  const SequenceErrors without_judge = RunSequence(steps, true, unjudged);
  std::cout << "crown filter from 0.5 m, hypotheses with the judge: max error "
            << with_judge.max_translation_m << " m, " << with_judge.max_rotation_rad / kDeg
            << " deg; without it " << without_judge.max_translation_m << " m, "
            << without_judge.max_rotation_rad / kDeg << " deg" << std::endl;
  EXPECT_LT(with_judge.max_rotation_rad, 0.7 * without_judge.max_rotation_rad);

  // Tried only where the fit drops against the scans before: the same turns are followed
  // with the hypotheses tried on a fraction of the scans.
  config.turn_hypothesis_trigger = 0.95;
  const SequenceErrors triggered = RunSequence(steps, true, config);
  std::cout << "triggered at 0.95: tried on " << triggered.turn_hypotheses_tried << " of "
            << triggered.total_ms.size() << " scans (every scan: " << with.turn_hypotheses_tried
            << "), won " << triggered.turn_hypotheses_won << "; max error "
            << triggered.max_translation_m << " m, " << triggered.max_rotation_rad / kDeg
            << " deg" << std::endl;
  EXPECT_GT(triggered.turn_hypotheses_won, 0);
  EXPECT_LT(triggered.turn_hypotheses_tried, with.turn_hypotheses_tried / 2);
  EXPECT_LT(triggered.max_rotation_rad, 0.7 * without.max_rotation_rad);

  // And in every scan of a turn (where the turn's end comes), whatever its fit.
  config.turn_hypothesis_in_turns = true;
  const SequenceErrors in_turns = RunSequence(steps, true, config);
  std::cout << "triggered at 0.95 and in turns: tried on " << in_turns.turn_hypotheses_tried
            << ", won " << in_turns.turn_hypotheses_won << "; max error "
            << in_turns.max_translation_m << " m, " << in_turns.max_rotation_rad / kDeg << " deg"
            << std::endl;
  EXPECT_GT(in_turns.turn_hypotheses_tried, triggered.turn_hypotheses_tried + 30);
  EXPECT_LT(in_turns.turn_hypotheses_tried, with.turn_hypotheses_tried);
  EXPECT_LT(in_turns.max_rotation_rad, 0.7 * without.max_rotation_rad);

  // Half steps too: the same scans try them, with rates in between.
  config.turn_hypothesis_levels = 2;
  const SequenceErrors halves = RunSequence(steps, true, config);
  std::cout << "with half steps: tried on " << halves.turn_hypotheses_tried << ", won "
            << halves.turn_hypotheses_won << "; max error " << halves.max_translation_m
            << " m, " << halves.max_rotation_rad / kDeg << " deg" << std::endl;
  EXPECT_LT(halves.max_translation_m, 0.07);
  EXPECT_LT(halves.max_rotation_rad, 0.7 * without.max_rotation_rad);
}

// The defaults on the yaw-rate steps, with and without trying the hypotheses at every scan
// whose motion prior was released (a turn's first scan fits poorly with the prior; the fit
// without it need not fall below the weight trigger).
TEST(OdometryTest, TurnHypothesesOnReleaseFollowYawRateSteps) {
  const test::VehicleTrajectory steps = YawRateSteps();
  OdometryConfig on;
  on.turn_hypothesis_window_scans = 10;  // the first step comes after 20 scans
  ASSERT_TRUE(on.turn_hypothesis_on_release);
  OdometryConfig off = on;
  off.turn_hypothesis_on_release = false;
  const SequenceErrors without = RunSequence(steps, true, off);
  const SequenceErrors with = RunSequence(steps, true, on);
  std::cout << "yaw-rate steps, defaults: hypotheses on release " << with.max_translation_m
            << " m, " << with.max_rotation_rad / kDeg << " deg (tried "
            << with.turn_hypotheses_tried << ", won " << with.turn_hypotheses_won << "); without "
            << without.max_translation_m << " m, " << without.max_rotation_rad / kDeg
            << " deg (tried " << without.turn_hypotheses_tried << ", won "
            << without.turn_hypotheses_won << ")" << std::endl;
  // Measured 0.040 m / 0.30 deg (tried 9, won 8) against 0.074 m / 0.55 deg (tried 6, won 6).
  EXPECT_GT(with.turn_hypotheses_tried, without.turn_hypotheses_tried);
  EXPECT_LT(with.max_rotation_rad, 0.8 * without.max_rotation_rad);
  EXPECT_LT(with.max_translation_m, 0.06);
}

TEST(OdometryTest, TracksWithoutPerPointTime) {
  // No time field: no de-skewing; the skew costs accuracy but tracking holds.
  const SequenceErrors e = RunSequence(GentleTurns(), false);
  std::cout << "gentle turns without time: max error " << e.max_translation_m << " m, "
            << e.max_rotation_rad / kDeg << " deg" << std::endl;
  EXPECT_GE(e.registered, static_cast<int>(e.total_ms.size()) - 1);
  // Measured with session 32's defaults: 0.185 m / 1.35 deg.
  EXPECT_LT(e.max_translation_m, 1.0);
  EXPECT_LT(e.max_rotation_rad, 3.0 * kDeg);
}

TEST(OdometryTest, RejectsBadInputWithoutChangingState) {
  Odometry odometry = Odometry::Create(OdometryConfig()).value();
  LidarScan empty;
  empty.stamp_s = 1.0;
  EXPECT_FALSE(odometry.ProcessScan(empty).ok());
  EXPECT_TRUE(odometry.trajectory().empty());

  const test::VehicleTrajectory still(0.0, {{1.0, 0.0}});
  const test::SyntheticScene scene(5, 40, 40.0, still.PathXy(), 4.0);
  const auto pose_at = [&](double t) { return still.PoseAt(t); };
  ASSERT_TRUE(odometry.ProcessScan(test::SimulateVlp16(scene, pose_at, 1.0, 1)).ok());
  const StatusOr<OdometryResult> same_stamp =
      odometry.ProcessScan(test::SimulateVlp16(scene, pose_at, 1.0, 2));
  ASSERT_FALSE(same_stamp.ok());
  EXPECT_NE(same_stamp.status().message().find("does not increase"), std::string::npos);
  EXPECT_EQ(odometry.trajectory().size(), 1u);

  OdometryConfig bad;
  bad.registration_voxel_size_m = 0.1;  // finer than the map voxel
  EXPECT_FALSE(Odometry::Create(bad).ok());
  bad = OdometryConfig();
  bad.local_map.voxel_size_m = -1.0;
  EXPECT_FALSE(Odometry::Create(bad).ok());
  bad = OdometryConfig();
  bad.turn_hypothesis_trigger = -0.5;
  EXPECT_FALSE(Odometry::Create(bad).ok());
  bad = OdometryConfig();
  bad.turn_hypothesis_levels = 0;
  EXPECT_FALSE(Odometry::Create(bad).ok());
  bad = OdometryConfig();
  bad.turn_hypothesis_window_scans = 0;
  EXPECT_FALSE(Odometry::Create(bad).ok());
  bad = OdometryConfig();
  bad.motion_prior_release_ratio = 1.5;
  EXPECT_FALSE(Odometry::Create(bad).ok());
}

TEST(OdometryTest, ReportsPoseDeskewedScanAndMapPoints) {
  const test::VehicleTrajectory trajectory(2.0, {{1.0, 0.5}});
  const test::SyntheticScene scene(6, 60, 50.0, trajectory.PathXy(), 4.0);
  const auto pose_at = [&](double t) { return trajectory.PoseAt(t); };
  const Pose3 start = se3::FromXyzRpy(10.0, 5.0, 0.0, 0.0, 0.0, 1.0);
  Odometry odometry = Odometry::Create(OdometryConfig(), start).value();
  StatusOr<OdometryResult> last = Status::Error("none");
  for (int k = 0; k < 5; ++k) {
    last = odometry.ProcessScan(test::SimulateVlp16(scene, pose_at, 0.1 * k, k));
    ASSERT_TRUE(last.ok()) << last.status().message();
    // The ICP work it reports: none on the first scan (an empty map), then at least one run
    // whose iterations and searches are among the summed ones.
    const OdometryResult& r = last.value();
    if (k == 0) {
      EXPECT_EQ(r.registrations, 0);
      EXPECT_EQ(r.icp_iterations, 0);
    } else {
      EXPECT_GE(r.registrations, 1);
      EXPECT_GE(r.icp_iterations, r.icp.iterations);
      EXPECT_GE(r.icp_iterations, r.registrations);
      EXPECT_GE(r.icp_searches, r.icp.searches);
      EXPECT_LE(r.icp_searches, r.icp_iterations);
      // A second run is a refinement, hypotheses or the prior's release (tried, kept or not).
      if (!r.refined && !r.turn_hypotheses_tried) {
        EXPECT_LE(r.registrations, 2);
      }
      if (r.refined || r.motion_prior_released) {
        EXPECT_GE(r.registrations, 2);
      }
    }
  }
  const OdometryResult& r = last.value();
  EXPECT_TRUE(r.registered);
  EXPECT_TRUE(r.deskew_stats.applied);
  EXPECT_EQ(r.deskewed_scan.points.size(), r.filter_stats.kept);
  EXPECT_GT(r.map_points.size(), 100u);
  EXPECT_LT(r.map_points.size(), r.deskewed_scan.points.size());
  EXPECT_GT(r.icp.fitness, 0.5);
  // The initial pose defines the odom frame: the 5th pose is start * truth motion.
  const Pose3 truth = start * se3::Between(trajectory.PoseAt(0.0), trajectory.PoseAt(0.4));
  EXPECT_LT(se3::TranslationNorm(se3::Between(truth, r.pose)), 0.05);
  EXPECT_EQ(odometry.trajectory().size(), 5u);
  EXPECT_GT(odometry.local_map().NumPoints(), 1000u);
  EXPECT_GT(odometry.velocity()(0), 1.5);  // ~2 m/s forward
}


// Regression (simulator sessions, issue "odometry stands still"): a robot starting from rest
// and accelerating slowly (2.4 cm per scan at first, like the simulated campus robot) in a
// scene of far facades with relief. The local map then holds the first scan's rings only;
// with its single-ring "normals" the odometry stayed at the start (measured here: ~0.5 m
// travelled of 8.4 m with use_scan_normals = false).
double StartFromRestFinalError(bool use_scan_normals, double* travelled_m) {
  // Facades 15-45 m away: boxes with 0.3 m deep pilasters every 4 m (relief across a ring).
  std::vector<test::SceneBox> boxes;
  const auto add_box = [&](double x, double y, double sx, double sy, double sz) {
    test::SceneBox b;
    b.center = Eigen::Vector3d(x, y, sz * 0.5);
    b.half_size = Eigen::Vector3d(sx, sy, sz) * 0.5;
    b.bound_radius = b.half_size.norm();
    boxes.push_back(b);
  };
  for (int side = -1; side <= 1; side += 2) {
    add_box(0.0, side * 18.0, 120.0, 2.0, 12.0);                  // long facades along the road
    for (double x = -58.0; x <= 58.0; x += 4.0) add_box(x, side * 16.85, 0.6, 0.3, 12.0);
  }
  add_box(45.0, 0.0, 2.0, 30.0, 15.0);                              // facade across the road
  for (double y = -14.0; y <= 14.0; y += 4.0) add_box(43.85, y, 0.3, 0.6, 15.0);
  test::SyntheticScene scene(1, 0, 1.0, {}, 0.0);
  scene.SetBoxes(boxes);
  // x(t) = v0 t + a t^2 / 2 with v0 = 0.24 m/s, a = 0.4 m/s^2: 8.8 m in 6 s.
  const auto pose_at = [](double t) {
    return se3::FromXyzRpy(0.24 * t + 0.2 * t * t, 0.0, 1.5, 0.0, 0.0, 0.0);
  };
  OdometryConfig config;
  config.use_scan_normals = use_scan_normals;
  Odometry odometry = Odometry::Create(config).value();
  Pose3 last = Pose3::Identity();
  const int num_scans = 60;
  for (int k = 0; k < num_scans; ++k) {
    const LidarScan scan = test::SimulateVlp16(scene, pose_at, 0.1 * k, 500 + k, 0.025, 1800);
    const StatusOr<OdometryResult> result = odometry.ProcessScan(scan);
    EXPECT_TRUE(result.ok()) << result.status().message();
    if (result.ok()) last = result.value().pose;
  }
  const Pose3 truth = se3::Between(pose_at(0.0), pose_at(0.1 * (num_scans - 1)));
  *travelled_m = last.translation().x();
  return se3::TranslationNorm(se3::Between(truth, last));
}

// Along-track speed error (RMS, m/s), largest along-track step error (m) and final rotation
// error (deg) of the odometry over scans [first, first + count) of a simulated campus session.
struct SegmentErrors {
  double speed_rms_mps = 0.0;
  double max_step_error_m = 0.0;
  double final_rotation_deg = 0.0;
  double max_rotation_deg = 0.0;
  int prior_released = 0;  ///< scans registered without the motion prior (released)
  double yaw_swing_deg = 0.0;  ///< max - min of the yaw error after the first 10 scans
  /// RMS of the tilt (roll and pitch) error of the motion over 1 s (10 scans) [deg].
  double tilt_rms_1s_deg = 0.0;
};
SegmentErrors CampusSegmentErrors(const sim::CampusSimulator& simulator, int session, int first,
                                  int count, const OdometryConfig& config) {
  Odometry odometry = Odometry::Create(config).value();
  Pose3 start_truth = Pose3::Identity(), previous = Pose3::Identity();
  Pose3 previous_truth = Pose3::Identity();
  SegmentErrors errors;
  double sum_sq = 0.0;
  int n = 0;
  std::vector<double> yaw_errors_deg;
  std::vector<Pose3> poses, truths;
  double tilt_sum_sq = 0.0;
  int tilt_n = 0;
  for (int k = first; k < first + count; ++k) {
    const sim::SimulatedScan sweep = simulator.SimulateScan(session, k);
    const StatusOr<OdometryResult> result = odometry.ProcessScan(sweep.scan);
    EXPECT_TRUE(result.ok()) << result.status().message();
    if (!result.ok()) continue;
    if (k == first) start_truth = sweep.pose_at_stamp;
    const Pose3 truth = se3::Between(start_truth, sweep.pose_at_stamp);
    const Pose3& pose = result.value().pose;
    if (k >= first + 10) {  // after the start from zero velocity
      const double speed = se3::Between(previous, pose).translation().x() / 0.1;
      const double truth_speed = se3::Between(previous_truth, truth).translation().x() / 0.1;
      sum_sq += (speed - truth_speed) * (speed - truth_speed);
      errors.max_step_error_m = std::max(errors.max_step_error_m, std::abs(speed - truth_speed) * 0.1);
      ++n;
    }
    errors.final_rotation_deg = se3::RotationAngleRad(se3::Between(truth, pose)) / kDeg;
    errors.max_rotation_deg = std::max(errors.max_rotation_deg, errors.final_rotation_deg);
    if (k >= first + 10) {
      const Eigen::Matrix3d error = truth.rotation().transpose() * pose.rotation();
      yaw_errors_deg.push_back(std::atan2(error(1, 0), error(0, 0)) / kDeg);
    }
    errors.prior_released += result.value().motion_prior_released ? 1 : 0;
    poses.push_back(pose);
    truths.push_back(truth);
    if (poses.size() > 10) {
      const std::size_t j = poses.size() - 11;
      const Eigen::Matrix3d motion_error =
          se3::Between(truths[j], truth).rotation().transpose() *
          se3::Between(poses[j], pose).rotation();
      const double tilt = std::acos(std::min(1.0, motion_error(2, 2))) / kDeg;
      tilt_sum_sq += tilt * tilt;
      ++tilt_n;
    }
    previous = pose;
    previous_truth = truth;
  }
  errors.speed_rms_mps = std::sqrt(sum_sq / std::max(n, 1));
  errors.tilt_rms_1s_deg = std::sqrt(tilt_sum_sq / std::max(tilt_n, 1));
  if (!yaw_errors_deg.empty()) {
    const auto [lo, hi] = std::minmax_element(yaw_errors_deg.begin(), yaw_errors_deg.end());
    errors.yaw_swing_deg = *hi - *lo;
  }
  return errors;
}

StatusOr<sim::CampusSimulator> CampusSeed(int seed) {
  sim::CampusSimulatorConfig config;
  config.campus.profile = "campus";
  config.campus.seed = seed;
  return sim::CampusSimulator::Create(config);
}

// Regression (campus s00 seed 1, first 500 scans): with the velocity of the last interval
// only (velocity_window_scans = 1), the motion model fed the along-track ICP noise back into
// the de-skew, an oscillation (see Odometry::WindowVelocity) that began in the turn at scan
// ~300 and tilted the odometry by 3 deg per 100 m after it. Measured here: along-track speed
// error RMS 1.28 m/s with the last interval, 0.14 m/s with the window of 3 over the whole
// twist, 0.18 m/s with the window over the translation only (the default).
TEST(OdometryTest, VelocityWindowDampsAlongTrackOscillationOnCampus) {
  const auto simulator = CampusSeed(1);
  ASSERT_TRUE(simulator.ok()) << simulator.status().message();
  OdometryConfig odometry_config;
  odometry_config.velocity_window_scans = 3;
  // The window alone, as measured: the motion prior (default since session 32) holds the
  // along-track motion by itself.
  odometry_config.motion_prior_weight = 0.0;
  odometry_config.turn_hypothesis_step_rad_s = 0.0;
  const SegmentErrors errors = CampusSegmentErrors(simulator.value(), 0, 0, 500, odometry_config);
  std::cout << "campus s00 scans 0-500: along-track speed error RMS " << errors.speed_rms_mps
            << " m/s, final rotation error " << errors.final_rotation_deg << " deg\n";
  EXPECT_LT(errors.speed_rms_mps, 0.3);
  EXPECT_LT(errors.final_rotation_deg, 0.7);
}

// Campus s02 seed 1, scans 900-1120: a straight drive through a parking lot before the turn at
// 112 s. The pairs hold the yaw only weakly there; with the rotation rate of the last interval
// only (rotation_window_scans = 1) the predicted yaw 2 e_k - e_{k-1} fed each scan's yaw error
// into the next (see odometry.h) and, in the whole session (seeds 1 and 3 alike), the yaw swung
// +-0.8 deg with a 1.6 s period, growing until the turn. Over three intervals it decays.
// Measured here (from a cold start at scan 900): yaw error swing 0.80 deg with the last
// interval, 0.035 deg with the default window of 3.
TEST(OdometryTest, RotationWindowDampsTheYawSwingInAParkingLot) {
  const auto simulator = CampusSeed(1);
  ASSERT_TRUE(simulator.ok()) << simulator.status().message();
  OdometryConfig last_interval;
  last_interval.rotation_window_scans = 1;
  const SegmentErrors swung = CampusSegmentErrors(simulator.value(), 2, 900, 220, last_interval);
  const SegmentErrors damped = CampusSegmentErrors(simulator.value(), 2, 900, 220, OdometryConfig());
  std::cout << "campus s02 scans 900-1120, yaw error swing (max - min) / final [deg]: last "
               "interval "
            << swung.yaw_swing_deg << " / " << swung.final_rotation_deg << ", defaults "
            << damped.yaw_swing_deg << " / " << damped.final_rotation_deg << "\n";
  EXPECT_EQ(OdometryConfig().rotation_window_scans, 3);
  EXPECT_LT(damped.yaw_swing_deg, 0.5 * swung.yaw_swing_deg);
}

// Campus s02 seed 1, scans 1950-2150: a straight road between long walls parallel to it, a
// lamp post every 30 m. Along the road the pairs constrain the scan weakly (the Hessian's
// smallest translation eigenvalue 40-60 weighted pairs there, 100-200 elsewhere) and the ICP
// follows a few biased pairs: steps of -0.2 to +0.5 m where the robot drove 0.18 m. The motion
// prior (odometry.motion_prior_weight, on by default since session 32, see odometry.h) holds
// the track there.
TEST(OdometryTest, MotionPriorHoldsTheTrackAlongAStraightWalledRoad) {
  const auto simulator = CampusSeed(1);
  ASSERT_TRUE(simulator.ok()) << simulator.status().message();
  OdometryConfig with_config;
  with_config.motion_prior_weight = 30.0;
  const SegmentErrors with = CampusSegmentErrors(simulator.value(), 2, 1950, 200, with_config);
  OdometryConfig without_config;
  without_config.motion_prior_weight = 0.0;
  const SegmentErrors without =
      CampusSegmentErrors(simulator.value(), 2, 1950, 200, without_config);
  std::cout << "campus s02 scans 1950-2150: along-track speed error RMS " << with.speed_rms_mps
            << " m/s, largest step error " << with.max_step_error_m << " m (without the prior "
            << without.speed_rms_mps << " m/s, " << without.max_step_error_m << " m)\n";
  EXPECT_LT(with.max_step_error_m, 0.1);
  EXPECT_LT(with.speed_rms_mps, 0.5 * without.speed_rms_mps);
}

// Campus s02 seed 1, scans 1400-1800: the walled road where two pedestrians walk beside the
// robot for 30 s. Points of the ground beyond ~10 m get no scan normal (the next ring is
// farther than the normal's patch reaches), so roll and pitch rested on the nearest ground
// rings and few walls, and the tilt jittered (whole session, 10 s steps: 0.05 deg median,
// 0.25 deg at most; 0.019 / 0.015 deg median with the map's ground normals). The refinement with
// the local map's ground normals (map_ground_min_depth_m) steadies it.
TEST(OdometryTest, MapGroundNormalsSteadyTheTilt) {
  const auto simulator = CampusSeed(1);
  ASSERT_TRUE(simulator.ok()) << simulator.status().message();
  OdometryConfig without_config;
  without_config.map_ground_min_depth_m = std::numeric_limits<double>::infinity();
  const SegmentErrors with = CampusSegmentErrors(simulator.value(), 2, 1400, 400, OdometryConfig());
  const SegmentErrors without =
      CampusSegmentErrors(simulator.value(), 2, 1400, 400, without_config);
  std::cout << "campus s02 scans 1400-1800: tilt error of the motion over 1 s, RMS "
            << with.tilt_rms_1s_deg << " deg (without the map's ground normals "
            << without.tilt_rms_1s_deg << " deg); largest rotation error " << with.max_rotation_deg
            << " / " << without.max_rotation_deg << " deg\n";
  EXPECT_EQ(OdometryConfig().map_ground_min_depth_m, 1.0);
  EXPECT_LT(with.tilt_rms_1s_deg, 0.8 * without.tilt_rms_1s_deg);
  // Heading and position stay the chosen fit's: the refinement must not cost rotation
  // (measured 0.405 against 0.450 deg largest rotation error).
  EXPECT_LE(with.max_rotation_deg, without.max_rotation_deg + 0.05);
}

// Campus s02 seed 3, scans 5250-5370: a sharp right turn whose yaw rate steps 0 -> -0.4 rad/s
// within the scan at 528.8 s (the first pose it shows in: 528.9 s) and back at 532.8 s. With
// the motion prior on every scan, the scans de-skewed with the old yaw rate fit poorly and the
// prior held the old rate (yaw steps of -0.2 to -0.4 deg where the truth turned -2.3 deg, then
// too much at the end): the prior is released where the fit drops
// (motion_prior_release_ratio), and the turn hypotheses try the scan de-skewed with other
// rates.
TEST(OdometryTest, MotionPriorIsReleasedWhereTheYawRateSteps) {
  const auto simulator = CampusSeed(3);
  ASSERT_TRUE(simulator.ok()) << simulator.status().message();
  OdometryConfig held;
  held.motion_prior_weight = 30.0;
  held.motion_prior_release_ratio = 0.0;
  held.turn_hypothesis_step_rad_s = 0.0;
  // The rotation rate of the last interval, where the bounds below were measured (the default
  // window of 3 since session 41 lags a turn's start by design: see the defaults below).
  held.rotation_window_scans = 1;
  OdometryConfig released = held;
  released.motion_prior_release_ratio = 0.9;
  // The defaults (prior 30, release 0.9, hypotheses) but the crown filter from 0.5 m above the
  // sensor, where the bounds below were measured: this turn, 39 scans after a cold start, is
  // chaotic in that height. Max / final rotation error [deg] with the hypotheses (without):
  // 0.5 m 0.46 / 0.26 (25.4 / 24.5), 0.75 m 0.77 / 0.39 (3.49 / 3.23), 1.0 m 2.09 / 0.25
  // (the same: no hypothesis wins), 1.25 m 2.14 / 0.29 (the same), 1.5 m 0.76 / 0.40
  // (4.18 / 3.64). The defaults (1 m) are checked below for keeping the track (1 m with the
  // last interval's rotation rate 2.09 / 0.25 deg, with the window of 3: 1.10 / 0.26 deg).
  OdometryConfig with_hypotheses;
  with_hypotheses.high_point_min_height_m = 0.5;
  with_hypotheses.rotation_window_scans = 1;
  EXPECT_EQ(with_hypotheses.motion_prior_weight, held.motion_prior_weight);
  const SegmentErrors h = CampusSegmentErrors(simulator.value(), 2, 5250, 120, held);
  const SegmentErrors r = CampusSegmentErrors(simulator.value(), 2, 5250, 120, released);
  const SegmentErrors t = CampusSegmentErrors(simulator.value(), 2, 5250, 120, with_hypotheses);
  std::cout << "campus seed 3 s02 sharp turn, rotation error max / final [deg]: prior held "
            << h.max_rotation_deg << " / " << h.final_rotation_deg << ", released "
            << r.max_rotation_deg << " / " << r.final_rotation_deg << " (" << r.prior_released
            << " scans), with turn hypotheses " << t.max_rotation_deg << " / "
            << t.final_rotation_deg << "\n";
  EXPECT_GT(r.prior_released, 0);
  EXPECT_GT(t.prior_released, 0);
  EXPECT_LT(r.max_rotation_deg, 0.5 * h.max_rotation_deg);
  // Measured (session 36's defaults: ICP at 3 mm / 3e-4 rad, the compared runs at 1 mm /
  // 1e-4 rad and up to 60 iterations) 72.5 / 67.8 deg held (the prior kept the old rate and
  // the track was lost), 2.67 / 2.66 deg released (5 scans), 0.68 / 0.35 deg with the
  // hypotheses too. Session 35 (everything at 1 mm): 3.52 / 2.25, 0.48 / 0.21, 1.03 / 0.23
  // deg. The release alone lands where its runs happen to stop in this turn (at 0.8 / 1.2 mm
  // it was 1.17 / 2.70 deg), so the 1 deg bound is on the defaults, the release with the
  // hypotheses. On the whole session (warm local map) the one-scan yaw errors over 0.5 deg
  // were 10 held, 8 released, 1 with both (session 32, docs/status_details.md).
  EXPECT_LT(t.max_rotation_deg, 0.5 * h.max_rotation_deg);
  EXPECT_LT(t.max_rotation_deg, 1.0);
  // The defaults keep the track through the turn (held, it was lost: 80 deg and more).
  const SegmentErrors d = CampusSegmentErrors(simulator.value(), 2, 5250, 120, OdometryConfig());
  std::cout << "  defaults: " << d.max_rotation_deg << " / " << d.final_rotation_deg << "\n";
  EXPECT_LT(d.max_rotation_deg, 0.1 * h.max_rotation_deg);
  EXPECT_LT(d.final_rotation_deg, 0.5);
}

TEST(OdometryTest, StartsFromRestAmongRingStructuredFacades) {
  double travelled_m = 0.0;
  const double error_m = StartFromRestFinalError(true, &travelled_m);
  std::cout << "start from rest: travelled " << travelled_m << " m of 8.38 m, error " << error_m
            << " m\n";
  EXPECT_LT(error_m, 0.25);
  double travelled_without_m = 0.0;
  const double error_without_m = StartFromRestFinalError(false, &travelled_without_m);
  std::cout << "  with the local map's normals: travelled " << travelled_without_m
            << " m, error " << error_without_m << " m\n";
}
}  // namespace
}  // namespace core
}  // namespace multisession_mapper
