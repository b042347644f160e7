// The one place where ROS messages become core types and back (cartographer's msg_conversion
// pattern). Every nodelet and tool converts through these functions; nothing else reads
// PointCloud2 bytes. Malformed input gives a Status naming the problem, never a crash.
#pragma once

#include <string>

#include <geometry_msgs/Pose.h>
#include <multisession_mapper/LoopCandidate.h>
#include <ros/time.h>
#include <sensor_msgs/PointCloud2.h>

#include "multisession_mapper/core/loop_record.h"
#include "multisession_mapper/core/status.h"
#include "multisession_mapper/core/types.h"

namespace multisession_mapper {
namespace conversions {

/// Reads a PointCloud2 from a Velodyne (x y z intensity ring time), Ouster (t in ns as uint32),
/// Hesai/Livox-style (absolute `timestamp` float64) or plain xyz layout. x/y/z may be float32
/// or float64; intensity float32/uint8/uint16; ring uint8/uint16. Points with non-finite
/// coordinates are kept as they are: the input filter counts and drops them.
/// Fails on big-endian data, missing x/y/z, fields that do not fit in point_step, or a data
/// size that disagrees with width x height x point_step.
core::StatusOr<core::LidarScan> FromPointCloud2(const sensor_msgs::PointCloud2& msg);

/// Writes a scan in the Velodyne driver's layout: float32 x y z intensity, uint16 ring,
/// float32 time (offset from header.stamp [s]); dense, one row.
sensor_msgs::PointCloud2 ToPointCloud2(const core::LidarScan& scan, const std::string& frame_id);

/// Writes plain float32 x y z points (submaps, maps, removed dynamic points).
sensor_msgs::PointCloud2 ToPointCloud2(const core::PointVector& points,
                                       const std::string& frame_id, const ros::Time& stamp);

geometry_msgs::Pose ToPoseMsg(const core::Pose3& pose);
/// Fails on non-finite values or a zero quaternion; the quaternion is normalised.
core::StatusOr<core::Pose3> FromPoseMsg(const geometry_msgs::Pose& msg);

ros::Time ToRosTime(double stamp_s);
double ToSeconds(const ros::Time& stamp);

/// LoopCandidate::CANDIDATE / ACCEPTED / REJECTED / UNDEFINED.
std::uint8_t ToLoopStatusMsg(core::LoopStatus status);
/// A loop record as a message; non-finite vote / overlap values become 0, a record without
/// pose gets the identity, a negative history submap (undefined) gets 0.
multisession_mapper::LoopCandidate ToLoopCandidateMsg(const core::LoopRecord& record);

}  // namespace conversions
}  // namespace multisession_mapper
