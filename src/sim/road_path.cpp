#include "multisession_mapper/sim/road_path.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace multisession_mapper {
namespace sim {
namespace {

double Cross(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return a.x() * b.y() - a.y() * b.x();
}

}  // namespace

core::StatusOr<RoadPath> RoadPath::Create(const std::vector<Eigen::Vector2d>& waypoints,
                                          double corner_radius_m, double spacing_m) {
  if (waypoints.size() < 2) return core::Status::Error("road_path: need at least 2 waypoints");
  if (!(corner_radius_m > 0.0) || !(spacing_m > 0.0)) {
    return core::Status::Error("road_path: corner radius and spacing must be > 0");
  }
  const std::size_t n = waypoints.size();
  std::vector<Eigen::Vector2d> dirs(n - 1);
  std::vector<double> lens(n - 1);
  for (std::size_t i = 0; i + 1 < n; ++i) {
    const Eigen::Vector2d d = waypoints[i + 1] - waypoints[i];
    lens[i] = d.norm();
    if (!(lens[i] > 1e-6)) {
      return core::Status::Error("road_path: waypoints " + std::to_string(i) + " and " +
                                 std::to_string(i + 1) + " coincide");
    }
    dirs[i] = d / lens[i];
  }
  // Fillet at every interior corner: tangent distance d = r tan(theta / 2).
  std::vector<double> cut(n, 0.0);
  std::vector<double> radius(n, corner_radius_m);
  for (std::size_t i = 1; i + 1 < n; ++i) {
    const double cos_turn = std::clamp(dirs[i - 1].dot(dirs[i]), -1.0, 1.0);
    const double theta = std::acos(cos_turn);
    if (theta < 1e-6) continue;
    if (theta > M_PI - 1e-3) return core::Status::Error("road_path: U-turn at a waypoint");
    double d = corner_radius_m * std::tan(0.5 * theta);
    d = std::min(d, 0.45 * std::min(lens[i - 1], lens[i]));
    cut[i] = d;
    radius[i] = d / std::tan(0.5 * theta);
  }
  RoadPath path;
  auto push = [&](const Eigen::Vector2d& p, const Eigen::Vector2d& t, double k) {
    if (!path.points_.empty()) {
      const double ds = (p - path.points_.back()).norm();
      if (ds < 1e-9) return;
      path.s_.push_back(path.s_.back() + ds);
    } else {
      path.s_.push_back(0.0);
    }
    path.points_.push_back(p);
    path.tangents_.push_back(t);
    path.curvatures_.push_back(k);
  };
  for (std::size_t i = 0; i + 1 < n; ++i) {
    // Straight part of segment i.
    const Eigen::Vector2d a = waypoints[i] + dirs[i] * cut[i];
    const Eigen::Vector2d b = waypoints[i + 1] - dirs[i] * cut[i + 1];
    const double len = (b - a).norm();
    const int steps = std::max(1, static_cast<int>(std::ceil(len / spacing_m)));
    for (int k = 0; k <= steps; ++k) {
      push(a + (b - a) * (static_cast<double>(k) / steps), dirs[i], 0.0);
    }
    // Fillet at the next corner.
    if (i + 2 < n && cut[i + 1] > 0.0) {
      const Eigen::Vector2d& din = dirs[i];
      const Eigen::Vector2d& dout = dirs[i + 1];
      const double sign = Cross(din, dout) > 0.0 ? 1.0 : -1.0;  // left turn positive
      const double r = radius[i + 1];
      const Eigen::Vector2d left(-din.y(), din.x());
      const Eigen::Vector2d centre = b + left * sign * r;
      const double theta = std::acos(std::clamp(din.dot(dout), -1.0, 1.0));
      const int arc_steps = std::max(2, static_cast<int>(std::ceil(theta * r / spacing_m)));
      const Eigen::Vector2d start = b - centre;
      for (int k = 1; k < arc_steps; ++k) {
        const double phi = sign * theta * k / arc_steps;
        const Eigen::Vector2d rel(std::cos(phi) * start.x() - std::sin(phi) * start.y(),
                                  std::sin(phi) * start.x() + std::cos(phi) * start.y());
        const double heading = std::atan2(din.y(), din.x()) + phi;
        push(centre + rel, Eigen::Vector2d(std::cos(heading), std::sin(heading)), sign / r);
      }
    }
  }
  if (path.points_.size() < 2) return core::Status::Error("road_path: degenerate path");
  return path;
}

Eigen::Vector2d RoadPath::Point(double s_m, double right_offset_m, Eigen::Vector2d* tangent,
                                double* curvature) const {
  s_m = std::clamp(s_m, 0.0, s_.back());
  std::size_t i = std::upper_bound(s_.begin(), s_.end(), s_m) - s_.begin();
  i = std::clamp<std::size_t>(i, 1, s_.size() - 1);
  const double span = s_[i] - s_[i - 1];
  const double alpha = span > 0.0 ? (s_m - s_[i - 1]) / span : 0.0;
  const Eigen::Vector2d p = points_[i - 1] + alpha * (points_[i] - points_[i - 1]);
  Eigen::Vector2d t = (tangents_[i - 1] + alpha * (tangents_[i] - tangents_[i - 1]));
  t.normalize();
  if (tangent) *tangent = t;
  if (curvature) *curvature = alpha < 0.5 ? curvatures_[i - 1] : curvatures_[i];
  return p + Eigen::Vector2d(t.y(), -t.x()) * right_offset_m;
}

}  // namespace sim
}  // namespace multisession_mapper
