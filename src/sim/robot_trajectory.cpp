#include "multisession_mapper/sim/robot_trajectory.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "multisession_mapper/core/se3.h"

namespace multisession_mapper {
namespace sim {
namespace {

// Centred moving average over `half` samples on each side (shrinking at the ends).
std::vector<double> Smooth(const std::vector<double>& x, int half) {
  if (half <= 0 || x.size() < 3) return x;
  std::vector<double> prefix(x.size() + 1, 0.0);
  for (std::size_t i = 0; i < x.size(); ++i) prefix[i + 1] = prefix[i] + x[i];
  std::vector<double> out(x.size());
  const int n = static_cast<int>(x.size());
  for (int i = 0; i < n; ++i) {
    const int h = std::min({half, i, n - 1 - i});
    out[i] = (prefix[i + h + 1] - prefix[i - h]) / (2 * h + 1);
  }
  return out;
}

}  // namespace

core::Status RobotTrajectoryConfig::Validate() const {
  auto positive = [](double v) { return std::isfinite(v) && v > 0.0; };
  if (!positive(cruise_speed_mps) || cruise_speed_mps > 20.0) {
    return core::Status::Error("robot.cruise_speed_mps must be in (0, 20], got " +
                               std::to_string(cruise_speed_mps));
  }
  if (!positive(end_speed_mps) || end_speed_mps > cruise_speed_mps) {
    return core::Status::Error("robot.end_speed_mps must be in (0, cruise_speed_mps]");
  }
  if (!positive(max_accel_mps2) || !positive(max_lateral_accel_mps2)) {
    return core::Status::Error("robot: acceleration limits must be > 0");
  }
  if (!positive(corner_radius_m) || corner_radius_m < std::abs(lane_offset_m) + 1.0) {
    return core::Status::Error("robot.corner_radius_m must exceed |lane_offset_m| + 1 m");
  }
  if (!positive(sensor_height_m) || !positive(wheelbase_m) || !positive(track_m) ||
      !positive(sample_spacing_m) || !std::isfinite(sensor_forward_m) ||
      !(suspension_length_m >= 0.0) || !(speed_smoothing_m >= 0.0)) {
    return core::Status::Error("robot: geometry lengths must be finite and > 0");
  }
  return core::Status::Ok();
}

core::StatusOr<RobotTrajectory> RobotTrajectory::Create(
    const RobotTrajectoryConfig& config, const std::vector<Eigen::Vector2d>& waypoints,
    const Terrain& terrain, double start_stamp_s) {
  core::Status status = config.Validate();
  if (!status.ok()) return status;
  auto path = RoadPath::Create(waypoints, config.corner_radius_m, config.sample_spacing_m);
  if (!path.ok()) return path.status();
  RobotTrajectory traj(config, std::move(path).value());
  const RoadPath& rp = traj.path_;
  const double ds = config.sample_spacing_m;
  const int n = std::max(2, static_cast<int>(std::ceil(rp.length_m() / ds)) + 1);
  const double step = rp.length_m() / (n - 1);
  traj.s_.resize(n);
  std::vector<double> v_limit(n);
  std::vector<Eigen::Vector2d> xy(n);
  std::vector<double> yaw(n);
  for (int i = 0; i < n; ++i) {
    const double s = i * step;
    traj.s_[i] = s;
    Eigen::Vector2d tangent;
    double k = 0.0;
    xy[i] = rp.Point(s, config.lane_offset_m, &tangent, &k);
    yaw[i] = std::atan2(tangent.y(), tangent.x());
    double limit = config.cruise_speed_mps;
    if (std::abs(k) > 1e-9) {
      // Lane radius: outside of a left turn, inside of a right turn.
      const double r = 1.0 / std::abs(k) + (k > 0.0 ? 1.0 : -1.0) * config.lane_offset_m;
      limit = std::min(limit, std::sqrt(config.max_lateral_accel_mps2 * std::max(r, 0.5)));
    }
    v_limit[i] = limit;
  }
  // Distances along the lane (longer than the centreline outside a turn, shorter inside).
  std::vector<double> lane_step(n, step);
  for (int i = 1; i < n; ++i) lane_step[i] = std::max((xy[i] - xy[i - 1]).norm(), 1e-6);
  // Speed profile: acceleration-limited forward/backward passes, then smoothed.
  std::vector<double> v(v_limit);
  v[0] = std::min(v[0], config.end_speed_mps);
  for (int i = 1; i < n; ++i) {
    v[i] = std::min(v[i], std::sqrt(v[i - 1] * v[i - 1] +
                                    2.0 * config.max_accel_mps2 * lane_step[i]));
  }
  v[n - 1] = std::min(v[n - 1], config.end_speed_mps);
  for (int i = n - 2; i >= 0; --i) {
    v[i] = std::min(v[i], std::sqrt(v[i + 1] * v[i + 1] +
                                    2.0 * config.max_accel_mps2 * lane_step[i + 1]));
  }
  v = Smooth(v, static_cast<int>(config.speed_smoothing_m / (2.0 * step)));
  for (double& x : v) x = std::max(x, 0.5 * config.end_speed_mps);
  traj.v_ = v;
  traj.t_.resize(n);
  traj.t_[0] = start_stamp_s;
  for (int i = 1; i < n; ++i) {
    traj.t_[i] = traj.t_[i - 1] + 2.0 * lane_step[i] / (v[i - 1] + v[i]);
  }

  // Terrain following: wheel contact heights give z, pitch and roll.
  std::vector<double> z(n), pitch(n), roll(n);
  const double hl = 0.5 * config.wheelbase_m;
  const double ht = 0.5 * config.track_m;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector2d f(std::cos(yaw[i]), std::sin(yaw[i]));
    const Eigen::Vector2d l(-f.y(), f.x());
    auto h = [&](double a, double b) {
      const Eigen::Vector2d p = xy[i] + f * a + l * b;
      return terrain.Height(p.x(), p.y());
    };
    const double fl = h(hl, ht), fr = h(hl, -ht), rl = h(-hl, ht), rr = h(-hl, -ht);
    z[i] = 0.25 * (fl + fr + rl + rr);
    pitch[i] = std::atan2(0.5 * (rl + rr) - 0.5 * (fl + fr), config.wheelbase_m);
    roll[i] = std::atan2(0.5 * (fl + rl) - 0.5 * (fr + rr), config.track_m);
  }
  const int half = static_cast<int>(config.suspension_length_m / (2.0 * step));
  z = Smooth(z, half);
  pitch = Smooth(pitch, half);
  roll = Smooth(roll, half);
  traj.base_.resize(n);
  for (int i = 0; i < n; ++i) {
    traj.base_[i] = core::se3::FromXyzRpy(xy[i].x(), xy[i].y(), z[i], roll[i], pitch[i], yaw[i]);
  }
  traj.base_sensor_ = core::Pose3::Identity();
  traj.base_sensor_.translation() =
      Eigen::Vector3d(config.sensor_forward_m, 0.0, config.sensor_height_m);
  return traj;
}

std::size_t RobotTrajectory::Segment(double stamp_s, double* alpha) const {
  stamp_s = std::clamp(stamp_s, t_.front(), t_.back());
  std::size_t i = std::upper_bound(t_.begin(), t_.end(), stamp_s) - t_.begin();
  i = std::clamp<std::size_t>(i, 1, t_.size() - 1);
  const double span = t_[i] - t_[i - 1];
  *alpha = span > 0.0 ? (stamp_s - t_[i - 1]) / span : 0.0;
  return i;
}

core::Pose3 RobotTrajectory::BasePose(double stamp_s) const {
  double alpha;
  const std::size_t i = Segment(stamp_s, &alpha);
  return core::se3::Interpolate(base_[i - 1], base_[i], alpha);
}

core::Pose3 RobotTrajectory::SensorPose(double stamp_s) const {
  return BasePose(stamp_s) * base_sensor_;
}

double RobotTrajectory::ArcLength(double stamp_s) const {
  double alpha;
  const std::size_t i = Segment(stamp_s, &alpha);
  return s_[i - 1] + alpha * (s_[i] - s_[i - 1]);
}

double RobotTrajectory::Speed(double stamp_s) const {
  double alpha;
  const std::size_t i = Segment(stamp_s, &alpha);
  return v_[i - 1] + alpha * (v_[i] - v_[i - 1]);
}

}  // namespace sim
}  // namespace multisession_mapper
