// A smooth planar path through road waypoints: straight segments joined by circular fillets
// (radius shrunk where segments are short), sampled densely by arc length. The robot, the
// moving cars and the pedestrians all drive/walk along such paths, at a lateral offset (lane or
// sidewalk) from the centreline.
#pragma once

#include <vector>

#include <Eigen/Core>

#include "multisession_mapper/core/status.h"

namespace multisession_mapper {
namespace sim {

class RoadPath {
 public:
  /// `waypoints` (>= 2, consecutive points distinct, no U-turns) are joined by straight lines
  /// whose corners are rounded with `corner_radius_m`; samples every `spacing_m`.
  static core::StatusOr<RoadPath> Create(const std::vector<Eigen::Vector2d>& waypoints,
                                         double corner_radius_m, double spacing_m = 0.05);

  double length_m() const { return s_.back(); }
  /// Point at arc length s (clamped to [0, length]) shifted `right_offset_m` to the right of
  /// the direction of travel; `tangent` (unit) and `curvature` (1/m, left turns positive, of
  /// the centreline) are optional outputs.
  Eigen::Vector2d Point(double s_m, double right_offset_m = 0.0,
                        Eigen::Vector2d* tangent = nullptr, double* curvature = nullptr) const;

 private:
  RoadPath() = default;
  std::vector<double> s_;
  std::vector<Eigen::Vector2d> points_;
  std::vector<Eigen::Vector2d> tangents_;
  std::vector<double> curvatures_;
};

}  // namespace sim
}  // namespace multisession_mapper
