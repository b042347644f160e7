// Velodyne VLP-16 sensor model (VLP-16 user manual, rev. E, 2019): 16 lasers at -15..+15 deg
// every 2 deg, fired in the interleaved order -15, +1, -13, +3, ... (2.304 us apart) once per
// column, 1800 columns per revolution at 10 Hz (0.2 deg), rotating clockwise seen from above,
// 100 m range. Each column is fired from the sensor pose at its own time, so a sweep taken
// while the robot moves is motion-distorted exactly as a real one; points are reported in the
// sensor frame at their firing time with the driver's fields (x y z intensity ring time).
// Range noise is Gaussian; intensity follows the hit material's reflectivity and the incidence
// angle (Lambertian). Nothing returns from the sky or beyond max range.
#pragma once

#include <cmath>
#include <cstdint>
#include <functional>
#include <vector>

#include <Eigen/Core>

#include "multisession_mapper/core/status.h"
#include "multisession_mapper/core/types.h"
#include "multisession_mapper/sim/ray_caster.h"
#include "multisession_mapper/sim/world.h"

namespace multisession_mapper {
namespace sim {

struct Vlp16Config {
  int num_columns = 1800;              ///< firings per revolution (0.2 deg at 10 Hz)
  double rate_hz = 10.0;               ///< revolutions per second
  double max_range_m = 100.0;          ///< no return beyond [m]
  double min_range_m = 0.5;            ///< no return closer than [m]
  double range_noise_sigma_m = 0.025;  ///< Gaussian range noise [m] (VLP-16: +-3 cm typical)
  double intensity_noise = 2.0;        ///< Gaussian intensity noise [sensor units, 0-255]
  double start_azimuth_rad = M_PI;     ///< azimuth of the first column (sensor frame; behind)

  core::Status Validate() const;
};

/// Ground truth of one return: exact (noise-free) hit in the world frame and what was hit.
struct TruthPoint {
  Eigen::Vector3f position_m = Eigen::Vector3f::Zero();
  ObjectClass label = ObjectClass::kTerrain;
  std::uint32_t object_id = 0;
  /// True range from the sensor at which this return was measured [m]; in a LabelCloud the
  /// smallest range of all returns of its voxel (0: unknown, e.g. read from an old file).
  float range_m = 0.0f;
};

struct SimulatedScan {
  core::LidarScan scan;             ///< what the sensor reports (sensor frame, distorted)
  std::vector<TruthPoint> truth;    ///< same order as scan.points
  core::Pose3 pose_at_stamp = core::Pose3::Identity();  ///< T_world_sensor at scan.stamp_s
};

class Vlp16 {
 public:
  static constexpr int kNumLasers = 16;

  static core::StatusOr<Vlp16> Create(const Vlp16Config& config);

  /// Elevation of laser `laser` (firing order) [rad] and its ring (0 = lowest beam).
  static double LaserElevationRad(int laser);
  static int LaserRing(int laser);
  /// Time of column `column` from the scan start [s].
  double ColumnTimeS(int column) const;
  double period_s() const { return 1.0 / config_.rate_hz; }

  /// One revolution starting at `stamp_s`. `sensor_pose(t)` gives T_world_sensor at absolute
  /// time t; `movers` are the moving objects to consider (those absent at a time are skipped);
  /// `key` seeds every random draw of this scan (noise, leaves).
  SimulatedScan Simulate(const RayCaster& caster, const std::vector<const WorldObject*>& movers,
                         const std::function<core::Pose3(double)>& sensor_pose, int session,
                         double stamp_s, std::uint64_t key) const;

  const Vlp16Config& config() const { return config_; }

 private:
  explicit Vlp16(const Vlp16Config& config);
  Vlp16Config config_;
  std::vector<Eigen::Vector3d> directions_;  ///< [column * 16 + laser], sensor frame
};

}  // namespace sim
}  // namespace multisession_mapper
