#include "multisession_mapper/core/session_mapper.h"

#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>

#include "multisession_mapper/core/se3.h"
#include "synthetic_lidar_scene.h"

namespace multisession_mapper {
namespace core {
namespace {

// A 3 m/s drive around a loop of ~85 m among boxes, back past the start: the last submaps
// must close a loop with the first ones.
class SessionMapperLoop : public ::testing::Test {
 protected:
  SessionMapperLoop()
      : trajectory_(3.0, {{4.0, 0.0}, {21.0, 2.0 * M_PI / 21.0}, {4.0, 0.0}}, 2.0),
        scene_(7, 60, 60.0, trajectory_.PathXy(0.25), 3.0) {}

  Pose3 Truth(double t) const { return trajectory_.PoseAt(t); }

  test::VehicleTrajectory trajectory_;
  test::SyntheticScene scene_;
};

TEST_F(SessionMapperLoop, ClosesTheLoopAndTracksGroundTruth) {
  SessionMapperConfig config;
  config.intra_pairs.enabled = true;  // off by default; checked here on a static world
  StatusOr<SessionMapper> mapper = SessionMapper::Create(config, "s00");
  ASSERT_TRUE(mapper.ok()) << mapper.status().message();
  const double period = 0.1;
  const int scans = static_cast<int>(trajectory_.duration_s() / period) - 1;
  for (int i = 0; i < scans; ++i) {
    const LidarScan scan = test::SimulateVlp16(
        scene_, [&](double t) { return Truth(t); }, i * period, 100 + i, 0.02, 900);
    ASSERT_TRUE(mapper.value().AddScan(scan).ok()) << "scan " << i;
  }
  StatusOr<SessionResult> result = mapper.value().Finish();
  ASSERT_TRUE(result.ok()) << result.status().message();
  const SessionResult& r = result.value();
  EXPECT_EQ(r.scans_processed, static_cast<std::size_t>(scans));
  EXPECT_GE(r.submaps.size(), 4u);
  EXPECT_EQ(r.trajectory.size(), static_cast<std::size_t>(scans));
  // The pair detection between neighbouring submaps (switched on above) ran over every submap and
  // the next one; the world is static, so it removes (almost) nothing.
  EXPECT_EQ(r.intra_pairs.pairs, r.submaps.size() - 1);
  std::size_t points = 0;
  for (const Submap& s : r.submaps) points += s.points.size();
  EXPECT_LT(r.intra_pairs.points_removed, points / 1000 + 1)
      << r.intra_pairs.points_removed << " of " << points;

  // Ground truth in the session frame (the sensor frame of the first scan).
  const Pose3 T0_inv = Truth(r.trajectory.front().stamp_s).inverse();
  double sum_sq = 0.0;
  for (const StampedPose& sp : r.trajectory) {
    sum_sq += (sp.pose.translation() - (T0_inv * Truth(sp.stamp_s)).translation()).squaredNorm();
  }
  const double ate = std::sqrt(sum_sq / r.trajectory.size());
  EXPECT_LT(ate, 0.10) << "ATE RMSE " << ate << " m";

  // At least one accepted intra-session loop, and every accepted loop is correct.
  int accepted = 0;
  for (const LoopRecord& loop : r.loops) {
    if (loop.status != LoopStatus::kAccepted) continue;
    ++accepted;
    const Submap& history = r.submaps[loop.history_submap];
    const Submap& current = r.submaps[loop.current_submap];
    const Pose3 truth = se3::Between(Truth(history.first_stamp_s()), Truth(current.first_stamp_s()));
    const Pose3 error = se3::Between(truth, loop.T_history_current);
    EXPECT_LT(se3::TranslationNorm(error), 0.3) << "loop " << loop.history_submap << "->"
                                                << loop.current_submap;
    EXPECT_LT(se3::RotationAngleRad(error), 1.0 * M_PI / 180.0);
  }
  EXPECT_GE(accepted, 1);
  // Consecutive submaps are linked by odometry edges: (submaps - 1) of them.
  int odometry_edges = 0;
  for (const PoseGraphEdge& e : r.graph.edges()) odometry_edges += e.kind == EdgeKind::kOdometry;
  EXPECT_EQ(odometry_edges, static_cast<int>(r.submaps.size()) - 1);

  // The boxes' sides are vertical: the submaps get vertical priors, and the graph's up
  // direction is the true one as seen from the first scan.
  EXPECT_GE(r.graph.vertical_priors().size(), r.submaps.size() / 2);
  const Eigen::Vector3d true_up =
      Truth(r.trajectory.front().stamp_s).rotation().transpose() * Eigen::Vector3d::UnitZ();
  const double up_error_deg =
      std::acos(std::min(1.0, r.graph.up().dot(true_up))) * 180.0 / M_PI;
  EXPECT_LT(up_error_deg, 0.3) << "up " << r.graph.up().transpose();
}

// The nodelets run the odometry in ScanMatchingNodelet and hand the registered scans to
// SubmapManagerNodelet (AddRegisteredScan): the result must equal AddScan's, so that online
// and offline runs match.
TEST_F(SessionMapperLoop, SplitPathEqualsAddScan) {
  SessionMapperConfig config;
  StatusOr<SessionMapper> whole = SessionMapper::Create(config, "s00");
  StatusOr<SessionMapper> split = SessionMapper::Create(config, "s00");
  StatusOr<Odometry> odometry = Odometry::Create(config.odometry);
  ASSERT_TRUE(whole.ok() && split.ok() && odometry.ok());
  const double period = 0.1;
  const int scans = static_cast<int>(trajectory_.duration_s() / period) - 1;
  for (int i = 0; i < scans; ++i) {
    const LidarScan scan = test::SimulateVlp16(
        scene_, [&](double t) { return Truth(t); }, i * period, 100 + i, 0.02, 900);
    ASSERT_TRUE(whole.value().AddScan(scan).ok()) << "scan " << i;
    StatusOr<OdometryResult> registered = odometry.value().ProcessScan(scan);
    ASSERT_TRUE(registered.ok()) << "scan " << i;
    ASSERT_TRUE(split.value().AddRegisteredScan(registered.value()).ok()) << "scan " << i;
    EXPECT_EQ(whole.value().current_submap_id(), split.value().current_submap_id());
  }
  // While mapping, the accessors the SubmapManagerNodelet publishes from agree too.
  ASSERT_EQ(whole.value().num_finished_submaps(), split.value().num_finished_submaps());
  ASSERT_GE(split.value().num_finished_submaps(), 3u);
  for (std::uint32_t id = 0; id < split.value().num_finished_submaps(); ++id) {
    EXPECT_TRUE(whole.value().SubmapOrigin(id).isApprox(split.value().SubmapOrigin(id), 1e-12));
    EXPECT_EQ(whole.value().finished_submap(id).points.size(),
              split.value().finished_submap(id).points.size());
  }
  EXPECT_TRUE(whole.value().SessionFromOdometry().isApprox(split.value().SessionFromOdometry(),
                                                           1e-12));
  EXPECT_EQ(whole.value().loops().size(), split.value().loops().size());

  StatusOr<SessionResult> a = whole.value().Finish();
  StatusOr<SessionResult> b = split.value().Finish();
  ASSERT_TRUE(a.ok() && b.ok());
  ASSERT_EQ(a.value().submaps.size(), b.value().submaps.size());
  ASSERT_EQ(a.value().trajectory.size(), b.value().trajectory.size());
  for (std::size_t i = 0; i < a.value().trajectory.size(); ++i) {
    EXPECT_EQ(a.value().trajectory[i].stamp_s, b.value().trajectory[i].stamp_s);
    EXPECT_TRUE(a.value().trajectory[i].pose.isApprox(b.value().trajectory[i].pose, 1e-12));
  }
  ASSERT_EQ(a.value().odometry.size(), b.value().odometry.size());
  for (std::size_t i = 0; i < a.value().odometry.size(); ++i) {
    EXPECT_TRUE(a.value().odometry[i].pose.isApprox(b.value().odometry[i].pose, 1e-12));
  }
  ASSERT_EQ(a.value().loops.size(), b.value().loops.size());
  for (std::size_t i = 0; i < a.value().loops.size(); ++i) {
    EXPECT_EQ(a.value().loops[i].status, b.value().loops[i].status);
    EXPECT_EQ(a.value().loops[i].history_submap, b.value().loops[i].history_submap);
  }
  EXPECT_EQ(a.value().scans_processed, b.value().scans_processed);
}

TEST(SessionMapper, SplitPathRefusesStampsThatDoNotIncrease) {
  StatusOr<SessionMapper> mapper = SessionMapper::Create(SessionMapperConfig(), "s");
  ASSERT_TRUE(mapper.ok());
  OdometryResult r;
  r.stamp_s = 2.0;
  r.deskewed_scan.stamp_s = 2.0;
  LidarPoint p;
  p.position_m = Eigen::Vector3f(5.0f, 0.0f, 0.0f);
  r.deskewed_scan.points.push_back(p);
  ASSERT_TRUE(mapper.value().AddRegisteredScan(r).ok());
  EXPECT_FALSE(mapper.value().AddRegisteredScan(r).ok());  // same stamp
  r.stamp_s = 1.0;
  EXPECT_FALSE(mapper.value().AddRegisteredScan(r).ok());  // earlier stamp
  r.stamp_s = 3.0;
  r.deskewed_scan.points.clear();
  EXPECT_FALSE(mapper.value().AddRegisteredScan(r).ok());  // empty scan
}

TEST(SessionMapper, UpdateConfigAppliesToTheNextScanAndRefusesInvalidValues) {
  StatusOr<SessionMapper> mapper = SessionMapper::Create(SessionMapperConfig(), "s");
  ASSERT_TRUE(mapper.ok());
  SessionMapperConfig changed;
  changed.submaps.max_translation_m = 5.0;
  changed.intra_loops.search_radius_m = 7.0;
  changed.odometry.map_voxel_size_m = 0.6;  // at most the registration voxel (0.75 m)
  ASSERT_TRUE(mapper.value().UpdateConfig(changed).ok());
  EXPECT_EQ(mapper.value().config().submaps.max_translation_m, 5.0);
  EXPECT_EQ(mapper.value().config().intra_loops.search_radius_m, 7.0);
  // The odometry of AddScan keeps its creation config.
  EXPECT_EQ(mapper.value().config().odometry.map_voxel_size_m, OdometryConfig().map_voxel_size_m);
  SessionMapperConfig bad = changed;
  bad.submaps.max_translation_m = -1.0;
  EXPECT_FALSE(mapper.value().UpdateConfig(bad).ok());
  EXPECT_EQ(mapper.value().config().submaps.max_translation_m, 5.0);

  // 5 m submaps from the next scan on: driving 12 m in a straight line gives >= 2 submaps.
  OdometryResult r;
  LidarPoint p;
  p.position_m = Eigen::Vector3f(5.0f, 1.0f, 0.0f);
  r.deskewed_scan.points.assign(50, p);
  r.registered = true;
  for (int i = 0; i <= 24; ++i) {
    r.stamp_s = 0.1 * (i + 1);
    r.deskewed_scan.stamp_s = r.stamp_s;
    r.pose = Pose3::Identity();
    r.pose.translation() = Eigen::Vector3d(0.5 * i, 0.0, 0.0);
    ASSERT_TRUE(mapper.value().AddRegisteredScan(r).ok());
  }
  EXPECT_GE(mapper.value().current_submap_id(), 2u);
}

TEST(SessionMapper, SkipsBadScansAndKeepsGoing) {
  StatusOr<SessionMapper> mapper = SessionMapper::Create(SessionMapperConfig(), "s01");
  ASSERT_TRUE(mapper.ok());
  LidarScan empty;
  empty.stamp_s = 1.0;
  const Status s = mapper.value().AddScan(empty);
  EXPECT_FALSE(s.ok());
  StatusOr<SessionResult> result = mapper.value().Finish();
  ASSERT_FALSE(result.ok());
  EXPECT_NE(result.status().message().find("no submap"), std::string::npos);
}

// After the first scan, a scan whose scan-to-map ICP failed (a jump of the sensor, a long
// gap) has only a predicted pose: it is skipped with a message, never mapped at that pose.
TEST(SessionMapper, ScansWhoseRegistrationFailedAreNotMapped) {
  StatusOr<SessionMapper> mapper = SessionMapper::Create(SessionMapperConfig(), "s");
  ASSERT_TRUE(mapper.ok());
  OdometryResult r;
  LidarPoint p;
  p.position_m = Eigen::Vector3f(5.0f, 1.0f, 0.0f);
  r.deskewed_scan.points.assign(50, p);
  for (int i = 0; i < 6; ++i) {
    r.stamp_s = 0.1 * (i + 1);
    r.deskewed_scan.stamp_s = r.stamp_s;
    r.pose = Pose3::Identity();
    r.pose.translation() = Eigen::Vector3d(0.5 * i, 0.0, 0.0);
    r.registered = i != 0 && i != 3;  // the first scan has no map to register to
    r.message = "too few correspondences";
    const Status s = mapper.value().AddRegisteredScan(r);
    if (i == 3) {
      ASSERT_FALSE(s.ok());
      EXPECT_NE(s.message().find("too few correspondences"), std::string::npos) << s.message();
    } else {
      EXPECT_TRUE(s.ok()) << "scan " << i << ": " << s.message();
    }
  }
  StatusOr<SessionResult> result = mapper.value().Finish();
  ASSERT_TRUE(result.ok()) << result.status().message();
  EXPECT_EQ(result.value().scans_processed, 5u);
  EXPECT_EQ(result.value().scans_skipped, 1u);
  ASSERT_EQ(result.value().trajectory.size(), 5u);
  for (const StampedPose& sp : result.value().trajectory) EXPECT_NE(sp.stamp_s, 0.1 * 4);
}

TEST(SessionMapper, InvalidConfigIsRefused) {
  SessionMapperConfig config;
  config.submaps.max_translation_m = -1.0;
  EXPECT_FALSE(SessionMapper::Create(config, "s").ok());
  config = SessionMapperConfig();
  config.intra_loops.search_radius_m = 0.0;
  EXPECT_FALSE(SessionMapper::Create(config, "s").ok());
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
