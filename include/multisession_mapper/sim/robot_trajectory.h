// Ground-truth motion of the simulated four-wheel robot: it follows a RoadPath in the right-hand
// lane with a speed profile limited by longitudinal and lateral acceleration (then smoothed so
// that the acceleration itself is continuous), and its z/pitch/roll follow the terrain under
// its four wheels, low-pass filtered over a suspension length. The sensor pose at any time is
// interpolated from a dense table, so points fired during a sweep see the exact motion.
#pragma once

#include <vector>

#include <Eigen/Core>

#include "multisession_mapper/core/status.h"
#include "multisession_mapper/core/types.h"
#include "multisession_mapper/sim/road_path.h"
#include "multisession_mapper/sim/terrain.h"

namespace multisession_mapper {
namespace sim {

struct RobotTrajectoryConfig {
  double cruise_speed_mps = 1.8;        ///< speed on straight road [m/s], 1-3 for this robot
  double end_speed_mps = 0.2;           ///< speed at the start and the end of the route [m/s]
  double max_accel_mps2 = 0.5;          ///< longitudinal acceleration limit [m/s^2]
  double max_lateral_accel_mps2 = 0.8;  ///< limits the speed in turns [m/s^2]
  double corner_radius_m = 6.0;         ///< fillet radius of road corners (centreline) [m]
  double lane_offset_m = 1.5;           ///< drive this far right of the road centreline [m]
  double sensor_height_m = 1.5;         ///< sensor origin above the ground contact [m]
  double sensor_forward_m = 0.2;        ///< sensor ahead of the robot centre [m]
  double wheelbase_m = 0.9;             ///< front-rear wheel distance [m]
  double track_m = 0.7;                 ///< left-right wheel distance [m]
  double suspension_length_m = 0.8;     ///< smoothing length of z/pitch/roll [m]
  double speed_smoothing_m = 2.0;       ///< smoothing length of the speed profile [m]
  double sample_spacing_m = 0.05;       ///< spacing of the pose table [m]

  core::Status Validate() const;
};

class RobotTrajectory {
 public:
  static core::StatusOr<RobotTrajectory> Create(const RobotTrajectoryConfig& config,
                                                const std::vector<Eigen::Vector2d>& waypoints,
                                                const Terrain& terrain, double start_stamp_s);

  double start_stamp_s() const { return t_.front(); }
  double end_stamp_s() const { return t_.back(); }
  double length_m() const { return path_.length_m(); }
  const RoadPath& path() const { return path_; }
  const RobotTrajectoryConfig& config() const { return config_; }

  /// T_world_sensor at `stamp_s` (clamped to the trajectory's time span).
  core::Pose3 SensorPose(double stamp_s) const;
  /// T_world_base (robot centre on the ground) at `stamp_s`.
  core::Pose3 BasePose(double stamp_s) const;
  /// Distance travelled along the road centreline at `stamp_s` [m].
  double ArcLength(double stamp_s) const;
  /// Speed at `stamp_s` [m/s].
  double Speed(double stamp_s) const;

 private:
  RobotTrajectory(const RobotTrajectoryConfig& config, RoadPath path)
      : config_(config), path_(std::move(path)) {}
  std::size_t Segment(double stamp_s, double* alpha) const;

  RobotTrajectoryConfig config_;
  RoadPath path_;
  std::vector<double> t_;
  std::vector<double> s_;
  std::vector<double> v_;
  std::vector<core::Pose3, Eigen::aligned_allocator<core::Pose3>> base_;
  core::Pose3 base_sensor_ = core::Pose3::Identity();
};

}  // namespace sim
}  // namespace multisession_mapper
