#include "multisession_mapper/core/odometry_worker.h"

#include <vector>

#include <gtest/gtest.h>

#include "synthetic_lidar_scene.h"

namespace multisession_mapper {
namespace core {
namespace {

std::vector<LidarScan> Sequence(int num_scans) {
  const test::VehicleTrajectory trajectory(2.0, {{4.0, 0.3}});
  const test::SyntheticScene scene(3, 60, 50.0, trajectory.PathXy(), 4.0);
  const auto pose_at = [&](double t) { return trajectory.PoseAt(t); };
  std::vector<LidarScan> scans;
  for (int k = 0; k < num_scans; ++k) {
    scans.push_back(test::SimulateVlp16(scene, pose_at, 0.1 * k, 40 + k, 0.01, 900));
  }
  // A scan whose stamp does not increase: the odometry refuses it, the worker must say so in
  // its place in the order.
  LidarScan repeated = scans[5];
  scans.insert(scans.begin() + 6, repeated);
  return scans;
}

TEST(OdometryWorkerTest, GivesTheResultsOfTheOdometryInOrder) {
  const std::vector<LidarScan> scans = Sequence(20);
  Odometry direct = Odometry::Create(OdometryConfig()).value();
  std::vector<StatusOr<OdometryResult>> expected;
  for (const LidarScan& scan : scans) expected.push_back(direct.ProcessScan(scan));

  auto worker = OdometryWorker::Create(OdometryConfig(), 2);
  ASSERT_TRUE(worker.ok()) << worker.status().message();
  std::vector<StatusOr<OdometryResult>> got;
  // Push all (popping whatever is ready in between, as the offline runner does), then wait.
  for (const LidarScan& scan : scans) {
    worker.value()->Push(scan);
    while (auto r = worker.value()->Pop(false)) got.push_back(std::move(*r));
  }
  while (auto r = worker.value()->Pop(true)) got.push_back(std::move(*r));
  EXPECT_EQ(worker.value()->pending(), 0u);
  EXPECT_FALSE(worker.value()->Pop(true).has_value());  // nothing pending: no wait

  ASSERT_EQ(got.size(), expected.size());
  for (std::size_t i = 0; i < got.size(); ++i) {
    ASSERT_EQ(got[i].ok(), expected[i].ok()) << "scan " << i;
    if (!got[i].ok()) {
      EXPECT_EQ(got[i].status().message(), expected[i].status().message());
      continue;
    }
    EXPECT_EQ(got[i].value().stamp_s, expected[i].value().stamp_s);
    EXPECT_TRUE(got[i].value().pose.matrix() == expected[i].value().pose.matrix()) << "scan " << i;
    EXPECT_EQ(got[i].value().map_points.size(), expected[i].value().map_points.size());
  }
  EXPECT_FALSE(got[6].ok());  // the repeated stamp
}

TEST(OdometryWorkerTest, DestroyedWithScansPendingFinishesCleanly) {
  const std::vector<LidarScan> scans = Sequence(6);
  auto worker = OdometryWorker::Create(OdometryConfig(), 8);
  ASSERT_TRUE(worker.ok());
  for (const LidarScan& scan : scans) worker.value()->Push(scan);
  auto first = worker.value()->Pop(true);
  ASSERT_TRUE(first.has_value());
  EXPECT_TRUE(first->ok());
  EXPECT_GT(worker.value()->pending(), 0u);  // the rest is queued or being processed
  worker.value().reset();  // must join the thread (finishing the queue) without a hang
}

TEST(OdometryWorkerTest, RejectsAnInvalidConfiguration) {
  OdometryConfig config;
  config.velocity_window_scans = 0;
  EXPECT_FALSE(OdometryWorker::Create(config).ok());
  EXPECT_FALSE(OdometryWorker::Create(OdometryConfig(), 0).ok());
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
