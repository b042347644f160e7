// Test helper (not a test): a synthetic outdoor scene (ground plane + rotated boxes) sampled
// by a simple VLP-16 ray model, with per-point time and motion during the sweep. Shared by the
// registration, de-skew and odometry tests so they all see the same kind of data.
#pragma once

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <random>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "multisession_mapper/core/se3.h"
#include "multisession_mapper/core/types.h"

namespace multisession_mapper {
namespace test {

struct SceneBox {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  Eigen::Vector3d half_size = Eigen::Vector3d::Ones();
  double yaw_rad = 0.0;
  double cos_yaw = 1.0, sin_yaw = 0.0;  // cached: the ray loop is the test's hot spot
  double bound_radius = 0.0;            // radius of the bounding sphere
};

class SyntheticScene {
 public:
  /// Ground at z = 0 plus `num_boxes` random boxes in [-extent, extent]^2, none within
  /// `clear_radius_m` of the points in `keep_clear` (the robot's path).
  SyntheticScene(unsigned seed, int num_boxes, double extent_m,
                 const std::vector<Eigen::Vector2d>& keep_clear, double clear_radius_m) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> pos(-extent_m, extent_m);
    std::uniform_real_distribution<double> size(1.0, 8.0);
    std::uniform_real_distribution<double> height(1.0, 8.0);
    std::uniform_real_distribution<double> yaw(-M_PI, M_PI);
    int attempts = 0;
    while (static_cast<int>(boxes_.size()) < num_boxes && attempts++ < num_boxes * 50) {
      SceneBox box;
      box.half_size = Eigen::Vector3d(size(rng), size(rng) * 0.5, height(rng)) * 0.5;
      box.center = Eigen::Vector3d(pos(rng), pos(rng), box.half_size.z());
      box.yaw_rad = yaw(rng);
      box.cos_yaw = std::cos(box.yaw_rad);
      box.sin_yaw = std::sin(box.yaw_rad);
      box.bound_radius = box.half_size.norm();
      const double reach = box.half_size.head<2>().norm() + clear_radius_m;
      const bool blocks = std::any_of(keep_clear.begin(), keep_clear.end(),
                                      [&](const Eigen::Vector2d& c) {
                                        return (c - box.center.head<2>()).norm() < reach;
                                      });
      if (!blocks) boxes_.push_back(box);
    }
  }

  const std::vector<SceneBox>& boxes() const { return boxes_; }
  /// Replaces the boxes by hand-placed ones (yaw 0 unless set; caches filled here).
  void SetBoxes(std::vector<SceneBox> boxes) {
    for (SceneBox& b : boxes) {
      b.cos_yaw = std::cos(b.yaw_rad);
      b.sin_yaw = std::sin(b.yaw_rad);
      b.bound_radius = b.half_size.norm();
    }
    boxes_ = std::move(boxes);
  }

  /// Distance along the unit ray (origin o, direction d) to the first surface, or +inf.
  double Raycast(const Eigen::Vector3d& o, const Eigen::Vector3d& d) const {
    double best = std::numeric_limits<double>::infinity();
    if (d.z() < -1e-9 && o.z() > 0.0) best = -o.z() / d.z();
    for (const SceneBox& b : boxes_) {
      const double c = b.cos_yaw, s = b.sin_yaw;
      const Eigen::Vector3d rel = o - b.center;
      // Bounding-sphere rejection: the ray misses, or the box is behind / beyond the best hit.
      const double along = -rel.dot(d);
      if (along + b.bound_radius < 0.0 || along - b.bound_radius > best) continue;
      if ((rel + along * d).squaredNorm() > b.bound_radius * b.bound_radius) continue;
      // Into the box frame: rotate by -yaw about z.
      const Eigen::Vector3d lo(c * rel.x() + s * rel.y(), -s * rel.x() + c * rel.y(), rel.z());
      const Eigen::Vector3d ld(c * d.x() + s * d.y(), -s * d.x() + c * d.y(), d.z());
      double t_near = 0.0, t_far = best;
      bool hit = true;
      for (int a = 0; a < 3 && hit; ++a) {
        if (std::abs(ld(a)) < 1e-12) {
          if (std::abs(lo(a)) > b.half_size(a)) hit = false;
          continue;
        }
        double t1 = (-b.half_size(a) - lo(a)) / ld(a);
        double t2 = (b.half_size(a) - lo(a)) / ld(a);
        if (t1 > t2) std::swap(t1, t2);
        t_near = std::max(t_near, t1);
        t_far = std::min(t_far, t2);
        if (t_near > t_far) hit = false;
      }
      if (hit && t_near > 1e-6 && t_near < best) best = t_near;
    }
    return best;
  }

 private:
  std::vector<SceneBox> boxes_;
};

/// VLP-16 ray model: 16 beams from -15 to +15 deg, `columns` azimuth steps per sweep, one
/// sweep of `period_s`. `pose_at(t)` gives T_world_sensor at absolute time t. Points are in
/// the sensor frame at their own firing time (i.e. skewed when the sensor moves), time_s is
/// the offset from `stamp_s`; has_time = `with_time`.
inline core::LidarScan SimulateVlp16(const SyntheticScene& scene,
                                     const std::function<core::Pose3(double)>& pose_at,
                                     double stamp_s, unsigned seed, double range_noise_m = 0.01,
                                     int columns = 900, double period_s = 0.1,
                                     bool with_time = true, double max_range_m = 100.0) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, range_noise_m);
  core::LidarScan scan;
  scan.stamp_s = stamp_s;
  scan.has_ring = true;
  scan.has_time = with_time;
  scan.points.reserve(static_cast<std::size_t>(columns) * 16);
  for (int col = 0; col < columns; ++col) {
    const double t = period_s * col / columns;
    const core::Pose3 pose = pose_at(stamp_s + t);
    const double azimuth = 2.0 * M_PI * col / columns;
    for (int ring = 0; ring < 16; ++ring) {
      const double elevation = (-15.0 + 2.0 * ring) * M_PI / 180.0;
      const Eigen::Vector3d d_s(std::cos(elevation) * std::cos(azimuth),
                                std::cos(elevation) * std::sin(azimuth), std::sin(elevation));
      const Eigen::Vector3d d_w = pose.linear() * d_s;
      const double range = scene.Raycast(pose.translation(), d_w);
      if (!(range < max_range_m)) continue;
      core::LidarPoint p;
      p.position_m = (d_s * (range + (range_noise_m > 0.0 ? noise(rng) : 0.0))).cast<float>();
      p.ring = static_cast<std::uint16_t>(ring);
      p.time_s = with_time ? static_cast<float>(t) : 0.0f;
      p.intensity = 10.0f;
      scan.points.push_back(p);
    }
  }
  return scan;
}

/// A ground vehicle trajectory: constant speed, piecewise-constant target yaw rate reached
/// with a bounded angular acceleration, small roll/pitch sway, sensor 1.8 m above ground.
/// Sampled every 1 ms and interpolated.
class VehicleTrajectory {
 public:
  /// `segments`: (duration [s], target yaw rate [rad/s]) in order; the yaw rate moves towards
  /// the target at `max_yaw_accel` [rad/s^2].
  VehicleTrajectory(double speed_mps, const std::vector<std::pair<double, double>>& segments,
                    double max_yaw_accel = 1e9, double sway_scale = 1.0)
      : sway_scale_(sway_scale) {
    double x = 0.0, y = 0.0, yaw = 0.0, yaw_rate = 0.0;
    samples_.push_back(Eigen::Vector3d(x, y, yaw));
    for (const auto& seg : segments) {
      const int steps = static_cast<int>(std::round(seg.first / kStep));
      for (int i = 0; i < steps; ++i) {
        const double max_change = max_yaw_accel * kStep;
        yaw_rate += std::clamp(seg.second - yaw_rate, -max_change, max_change);
        yaw += yaw_rate * kStep;
        x += speed_mps * kStep * std::cos(yaw);
        y += speed_mps * kStep * std::sin(yaw);
        samples_.push_back(Eigen::Vector3d(x, y, yaw));
      }
    }
  }
  double duration_s() const { return (samples_.size() - 1) * kStep; }

  core::Pose3 PoseAt(double t) const {
    const double f = std::clamp(t / kStep, 0.0, static_cast<double>(samples_.size() - 1));
    const std::size_t i = std::min(static_cast<std::size_t>(f), samples_.size() - 2);
    const double a = f - i;
    const Eigen::Vector3d s = (1.0 - a) * samples_[i] + a * samples_[i + 1];
    const double roll = sway_scale_ * 0.02 * std::sin(2.0 * t);
    const double pitch = sway_scale_ * 0.015 * std::sin(1.3 * t + 0.5);
    return core::se3::FromXyzRpy(s.x(), s.y(), 1.8, roll, pitch, s.z());
  }

  std::vector<Eigen::Vector2d> PathXy(double spacing_s = 0.5) const {
    std::vector<Eigen::Vector2d> out;
    for (double t = 0.0; t <= duration_s(); t += spacing_s) {
      out.push_back(PoseAt(t).translation().head<2>());
    }
    return out;
  }

 private:
  static constexpr double kStep = 1e-3;
  double sway_scale_ = 1.0;
  std::vector<Eigen::Vector3d> samples_;
};

}  // namespace test
}  // namespace multisession_mapper
