// Motion compensation of one sweep (de-skewing) under a constant-velocity model, as in
// KISS-ICP / LIO-SAM without IMU: the sensor moves with a constant twist during the sweep, so
// a point measured at time offset t (LidarPoint::time_s) is moved by T_stamp_t = Exp(xi * t)
// (se3::Exp, decoupled: rotation about the sensor origin, straight-line translation).
//
// Output frame: the sensor frame AT THE SCAN STAMP (time offset 0 = first firing, types.h), the
// frame in which the odometry reports the scan pose. A scan without per-point time
// (has_time == false) is returned unchanged and DeskewStats::applied says so.
#pragma once

#include <cstddef>

#include "multisession_mapper/core/se3.h"
#include "multisession_mapper/core/status.h"
#include "multisession_mapper/core/types.h"

namespace multisession_mapper {
namespace core {

struct DeskewConfig {
  /// false: every scan is passed through unchanged.
  bool enabled = true;
  /// Time offsets are clamped to [-max_time_offset_s, max_time_offset_s] [s]. A 10 Hz sweep
  /// lasts 0.1 s; the margin guards against a corrupt time field.
  double max_time_offset_s = 0.2;

  Status Validate() const;
};

struct DeskewStats {
  bool applied = false;        ///< false: scan without time, zero velocity, or disabled
  std::size_t clamped = 0;     ///< points whose time offset was clamped
  double max_time_offset_s = 0.0;
};

class Deskewer {
 public:
  static StatusOr<Deskewer> Create(const DeskewConfig& config);

  /// Twist per second of the sensor in its own frame from the motion `T_prev_curr` between
  /// two scan stamps `dt_s` apart: Log(T_prev_curr) / dt_s. Zero when dt_s <= 0.
  static se3::Vector6d VelocityFromMotion(const Pose3& T_prev_curr, double dt_s);

  /// Scan with every point moved into the sensor frame at the scan stamp; attributes, stamp
  /// and flags are kept (time_s too, so the caller still knows when a point was measured).
  LidarScan Apply(const LidarScan& scan, const se3::Vector6d& velocity,
                  DeskewStats* stats = nullptr) const;

  const DeskewConfig& config() const { return config_; }

 private:
  explicit Deskewer(const DeskewConfig& config) : config_(config) {}
  DeskewConfig config_;
};

}  // namespace core
}  // namespace multisession_mapper
