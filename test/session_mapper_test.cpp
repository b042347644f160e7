#include "multisession_mapper/core/session_mapper.h"

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
