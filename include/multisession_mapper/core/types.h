// Plain data types shared by every core module. No ROS, no PCL: points are Eigen/POD so that
// the algorithms stay independent of any framework (as in KISS-ICP's core).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace multisession_mapper {
namespace core {

/// A rigid transform in 3D. Convention: `T_a_b` maps coordinates of frame b into frame a.
using Pose3 = Eigen::Isometry3d;

/// One LiDAR return as recorded by the sensor, in the sensor frame.
struct LidarPoint {
  Eigen::Vector3f position_m = Eigen::Vector3f::Zero();  ///< sensor frame [m]
  float intensity = 0.0f;                                ///< sensor units (0-255 for Velodyne)
  std::uint16_t ring = 0;                                ///< laser index, 0 = lowest beam
  float time_s = 0.0f;  ///< time offset from the scan stamp [s]; >= 0 within the sweep
};

/// One sweep of the sensor. `stamp_s` is the time of the first firing (Velodyne driver
/// convention); each point's absolute time is `stamp_s + point.time_s`.
struct LidarScan {
  double stamp_s = 0.0;
  std::vector<LidarPoint> points;
  bool has_ring = false;  ///< the source carried a per-point ring index
  bool has_time = false;  ///< the source carried a per-point time offset
};

/// A pose at a time, e.g. one row of a TUM trajectory file.
struct StampedPose {
  double stamp_s = 0.0;
  Pose3 pose = Pose3::Identity();

  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

using Trajectory = std::vector<StampedPose, Eigen::aligned_allocator<StampedPose>>;
using PointVector = std::vector<Eigen::Vector3d>;

}  // namespace core
}  // namespace multisession_mapper
