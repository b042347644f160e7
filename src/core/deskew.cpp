#include "multisession_mapper/core/deskew.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace multisession_mapper {
namespace core {

Status DeskewConfig::Validate() const {
  if (!std::isfinite(max_time_offset_s) || max_time_offset_s <= 0.0) {
    return Status::Error("deskew.max_time_offset_s must be > 0, got " +
                         std::to_string(max_time_offset_s));
  }
  return Status::Ok();
}

StatusOr<Deskewer> Deskewer::Create(const DeskewConfig& config) {
  const Status status = config.Validate();
  if (!status.ok()) return status;
  return Deskewer(config);
}

se3::Vector6d Deskewer::VelocityFromMotion(const Pose3& T_prev_curr, double dt_s) {
  if (!(dt_s > 0.0) || !std::isfinite(dt_s)) return se3::Vector6d::Zero();
  return se3::Log(T_prev_curr) / dt_s;
}

LidarScan Deskewer::Apply(const LidarScan& scan, const se3::Vector6d& velocity,
                          DeskewStats* stats) const {
  DeskewStats local;
  if (!config_.enabled || !scan.has_time || !velocity.allFinite() || velocity.isZero(0.0)) {
    if (stats != nullptr) *stats = local;
    return scan;
  }
  local.applied = true;
  LidarScan out = scan;
  const Eigen::Vector3d v = velocity.head<3>();
  const Eigen::Vector3d w = velocity.tail<3>();
  const double w_norm = w.norm();
  const Eigen::Vector3d axis =
      w_norm > 1e-12 ? Eigen::Vector3d(w / w_norm) : Eigen::Vector3d::UnitZ();
  // Points come in firing order and share time stamps in blocks, so reuse the last rotation.
  float last_t = std::numeric_limits<float>::quiet_NaN();
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t_m = Eigen::Vector3d::Zero();
  const double max_t = config_.max_time_offset_s;
  for (LidarPoint& p : out.points) {
    if (p.time_s > max_t || p.time_s < -max_t) ++local.clamped;
    if (p.time_s != last_t) {
      last_t = p.time_s;
      const double t = std::clamp(static_cast<double>(p.time_s), -max_t, max_t);
      local.max_time_offset_s = std::max(local.max_time_offset_s, std::abs(t));
      R = Eigen::AngleAxisd(w_norm * t, axis).toRotationMatrix();
      t_m = v * t;
    }
    p.position_m = (R * p.position_m.cast<double>() + t_m).cast<float>();
  }
  if (stats != nullptr) *stats = local;
  return out;
}

}  // namespace core
}  // namespace multisession_mapper
