#include "multisession_mapper/ros/conversions.h"

#include <cmath>
#include <cstring>
#include <limits>

#include <gtest/gtest.h>

namespace multisession_mapper {
namespace conversions {
namespace {

using sensor_msgs::PointField;

core::LidarScan MakeScan() {
  core::LidarScan scan;
  scan.stamp_s = 1700000000.25;
  scan.has_ring = true;
  scan.has_time = true;
  for (int i = 0; i < 5; ++i) {
    core::LidarPoint p;
    p.position_m = Eigen::Vector3f(1.0f + i, -2.0f * i, 0.5f);
    p.intensity = 10.0f * i;
    p.ring = static_cast<std::uint16_t>(i * 3);
    p.time_s = 0.02f * i;
    scan.points.push_back(p);
  }
  return scan;
}

void AddField(sensor_msgs::PointCloud2* msg, const std::string& name, std::uint32_t offset,
              std::uint8_t type) {
  PointField f;
  f.name = name;
  f.offset = offset;
  f.datatype = type;
  f.count = 1;
  msg->fields.push_back(f);
}

TEST(Conversions, VelodyneLayoutRoundTrip) {
  const core::LidarScan in = MakeScan();
  const sensor_msgs::PointCloud2 msg = ToPointCloud2(in, "velodyne");
  EXPECT_EQ(msg.header.frame_id, "velodyne");
  EXPECT_EQ(msg.width, 5u);
  core::StatusOr<core::LidarScan> out = FromPointCloud2(msg);
  ASSERT_TRUE(out.ok()) << out.status().message();
  ASSERT_EQ(out.value().points.size(), in.points.size());
  EXPECT_TRUE(out.value().has_ring);
  EXPECT_TRUE(out.value().has_time);
  EXPECT_NEAR(out.value().stamp_s, in.stamp_s, 1e-6);
  for (std::size_t i = 0; i < in.points.size(); ++i) {
    EXPECT_TRUE(out.value().points[i].position_m.isApprox(in.points[i].position_m));
    EXPECT_EQ(out.value().points[i].ring, in.points[i].ring);
    EXPECT_FLOAT_EQ(out.value().points[i].time_s, in.points[i].time_s);
    EXPECT_FLOAT_EQ(out.value().points[i].intensity, in.points[i].intensity);
  }
}

TEST(Conversions, EmptyCloud) {
  core::LidarScan empty;
  empty.stamp_s = 5.0;
  core::StatusOr<core::LidarScan> out = FromPointCloud2(ToPointCloud2(empty, "velodyne"));
  ASSERT_TRUE(out.ok()) << out.status().message();
  EXPECT_TRUE(out.value().points.empty());
  // A message with no fields at all is rejected with a message naming x/y/z.
  sensor_msgs::PointCloud2 bare;
  core::StatusOr<core::LidarScan> bad = FromPointCloud2(bare);
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("x/y/z"), std::string::npos);
}

TEST(Conversions, NaNAndInfPointsPassThroughAndMarkNotDense) {
  core::LidarScan in = MakeScan();
  in.points[1].position_m.x() = std::numeric_limits<float>::quiet_NaN();
  in.points[2].position_m.z() = std::numeric_limits<float>::infinity();
  const sensor_msgs::PointCloud2 msg = ToPointCloud2(in, "velodyne");
  EXPECT_FALSE(msg.is_dense);
  core::StatusOr<core::LidarScan> out = FromPointCloud2(msg);
  ASSERT_TRUE(out.ok());
  EXPECT_TRUE(std::isnan(out.value().points[1].position_m.x()));
  EXPECT_TRUE(std::isinf(out.value().points[2].position_m.z()));
}

TEST(Conversions, OusterNanosecondTimeAndFloat64Xyz) {
  sensor_msgs::PointCloud2 msg;
  msg.header.stamp = ros::Time(100, 0);
  AddField(&msg, "x", 0, PointField::FLOAT64);
  AddField(&msg, "y", 8, PointField::FLOAT64);
  AddField(&msg, "z", 16, PointField::FLOAT64);
  AddField(&msg, "t", 24, PointField::UINT32);
  AddField(&msg, "ring", 28, PointField::UINT8);
  msg.point_step = 32;
  msg.width = 2;
  msg.height = 1;
  msg.row_step = 64;
  msg.data.assign(64, 0);
  for (int i = 0; i < 2; ++i) {
    const double xyz[3] = {1.5 + i, 2.5, -0.5};
    const std::uint32_t t_ns = 50000000u * (i + 1);
    const std::uint8_t ring = 9;
    std::memcpy(msg.data.data() + 32 * i, xyz, 24);
    std::memcpy(msg.data.data() + 32 * i + 24, &t_ns, 4);
    std::memcpy(msg.data.data() + 32 * i + 28, &ring, 1);
  }
  core::StatusOr<core::LidarScan> out = FromPointCloud2(msg);
  ASSERT_TRUE(out.ok()) << out.status().message();
  ASSERT_EQ(out.value().points.size(), 2u);
  EXPECT_FLOAT_EQ(out.value().points[1].position_m.x(), 2.5f);
  EXPECT_NEAR(out.value().points[1].time_s, 0.1, 1e-6);
  EXPECT_EQ(out.value().points[0].ring, 9);
  EXPECT_FALSE(out.value().points[0].intensity != 0.0f);  // no intensity field: default 0
}

TEST(Conversions, PlainXyzHasNoRingOrTime) {
  const core::PointVector points = {Eigen::Vector3d(1, 2, 3), Eigen::Vector3d(4, 5, 6)};
  const sensor_msgs::PointCloud2 msg = ToPointCloud2(points, "map", ros::Time(3, 0));
  core::StatusOr<core::LidarScan> out = FromPointCloud2(msg);
  ASSERT_TRUE(out.ok());
  EXPECT_FALSE(out.value().has_ring);
  EXPECT_FALSE(out.value().has_time);
  EXPECT_TRUE(out.value().points[1].position_m.isApprox(Eigen::Vector3f(4, 5, 6)));
}

TEST(Conversions, TruncatedDataIsRejected) {
  sensor_msgs::PointCloud2 msg = ToPointCloud2(MakeScan(), "velodyne");
  msg.data.resize(msg.data.size() - 3);
  core::StatusOr<core::LidarScan> out = FromPointCloud2(msg);
  ASSERT_FALSE(out.ok());
  EXPECT_NE(out.status().message().find("bytes"), std::string::npos);
}

TEST(Conversions, FieldOutsidePointStepIsRejected) {
  sensor_msgs::PointCloud2 msg = ToPointCloud2(MakeScan(), "velodyne");
  msg.fields[5].offset = 22;  // 'time' float32 would overrun the 24-byte point
  core::StatusOr<core::LidarScan> out = FromPointCloud2(msg);
  ASSERT_FALSE(out.ok());
  EXPECT_NE(out.status().message().find("time"), std::string::npos);
}

TEST(Conversions, BigEndianAndZeroPointStepAreRejected) {
  sensor_msgs::PointCloud2 msg = ToPointCloud2(MakeScan(), "velodyne");
  msg.is_bigendian = true;
  EXPECT_FALSE(FromPointCloud2(msg).ok());
  msg.is_bigendian = false;
  msg.point_step = 0;
  EXPECT_FALSE(FromPointCloud2(msg).ok());
}

TEST(Conversions, RowStepSmallerThanWidthIsRejected) {
  sensor_msgs::PointCloud2 msg = ToPointCloud2(MakeScan(), "velodyne");
  msg.row_step = msg.point_step;  // claims one point per row but width is 5
  EXPECT_FALSE(FromPointCloud2(msg).ok());
}

TEST(Conversions, PoseRoundTripAndInvalidPose) {
  core::Pose3 pose = core::Pose3::Identity();
  pose.linear() = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  pose.translation() = Eigen::Vector3d(-4, 5, 6);
  core::StatusOr<core::Pose3> back = FromPoseMsg(ToPoseMsg(pose));
  ASSERT_TRUE(back.ok());
  EXPECT_TRUE(back.value().isApprox(pose, 1e-12));

  geometry_msgs::Pose zero;  // all-zero quaternion
  EXPECT_FALSE(FromPoseMsg(zero).ok());
  geometry_msgs::Pose nan_pose = ToPoseMsg(pose);
  nan_pose.position.y = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(FromPoseMsg(nan_pose).ok());
}

TEST(Conversions, LoopRecordToMessage) {
  core::LoopRecord record;
  record.current_session = "s01";
  record.current_submap = 7;
  record.history_session = "s00";
  record.history_submap = 3;
  record.status = core::LoopStatus::kAccepted;
  record.vote_proportion = 0.97;
  record.overlap_ratio = std::numeric_limits<double>::quiet_NaN();
  record.has_pose = true;
  record.T_history_current.translation() = Eigen::Vector3d(1, 2, 3);
  record.reason = "ok";
  const multisession_mapper::LoopCandidate msg = ToLoopCandidateMsg(record);
  EXPECT_EQ(msg.current_session, "s01");
  EXPECT_EQ(msg.current_submap, 7u);
  EXPECT_EQ(msg.history_submap, 3u);
  EXPECT_EQ(msg.status, multisession_mapper::LoopCandidate::ACCEPTED);
  EXPECT_FLOAT_EQ(msg.vote_proportion, 0.97f);
  EXPECT_EQ(msg.overlap_ratio, 0.0f);  // NaN is not sent
  EXPECT_DOUBLE_EQ(msg.relative_pose.position.z, 3.0);

  core::LoopRecord undefined;
  undefined.status = core::LoopStatus::kUndefined;
  undefined.history_submap = -1;
  undefined.vote_proportion = std::numeric_limits<double>::infinity();
  const multisession_mapper::LoopCandidate u = ToLoopCandidateMsg(undefined);
  EXPECT_EQ(u.status, multisession_mapper::LoopCandidate::UNDEFINED);
  EXPECT_EQ(u.history_submap, 0u);
  EXPECT_EQ(u.vote_proportion, 0.0f);
  EXPECT_DOUBLE_EQ(u.relative_pose.orientation.w, 1.0);
  EXPECT_EQ(ToLoopStatusMsg(core::LoopStatus::kCandidate), multisession_mapper::LoopCandidate::CANDIDATE);
  EXPECT_EQ(ToLoopStatusMsg(core::LoopStatus::kRejected), multisession_mapper::LoopCandidate::REJECTED);
}

TEST(Conversions, TimeConversion) {
  EXPECT_NEAR(ToSeconds(ToRosTime(1700000000.123456)), 1700000000.123456, 1e-6);
  EXPECT_EQ(ToRosTime(std::numeric_limits<double>::quiet_NaN()), ros::Time(0));
  EXPECT_EQ(ToRosTime(-1.0), ros::Time(0));
}

}  // namespace
}  // namespace conversions
}  // namespace multisession_mapper
