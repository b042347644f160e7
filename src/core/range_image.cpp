#include "multisession_mapper/core/range_image.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

namespace multisession_mapper {
namespace core {

Status RangeImageConfig::Validate() const {
  if (!(azimuth_resolution_rad > 1e-4 && azimuth_resolution_rad < 0.5)) {
    return Status::Error("range_image.azimuth_resolution_rad must be in (1e-4, 0.5)");
  }
  if (!(elevation_tolerance_rad > 0.0 && elevation_tolerance_rad < 0.2)) {
    return Status::Error("range_image.elevation_tolerance_rad must be in (0, 0.2)");
  }
  if (!(no_return_free_range_m >= 0.0)) {
    return Status::Error("range_image.no_return_free_range_m must be >= 0");
  }
  if (!(max_ring_gap_rad > 0.0 && max_ring_gap_rad < 0.5)) {
    return Status::Error("range_image.max_ring_gap_rad must be in (0, 0.5)");
  }
  if (!(ring_gap_rad > 0.0 && ring_gap_rad < 0.2)) {
    return Status::Error("range_image.ring_gap_rad must be in (0, 0.2)");
  }
  return Status::Ok();
}

namespace {
double Elevation(const Eigen::Vector3f& p) {
  return std::atan2(static_cast<double>(p.z()), std::hypot(p.x(), p.y()));
}
}  // namespace

RangeImage::RangeImage(const LidarScan& scan, const RangeImageConfig& config) : config_(config) {
  columns_ = static_cast<int>(std::ceil(2.0 * M_PI / config_.azimuth_resolution_rad));
  // Ring elevations: a ring's beam is a cone of fixed elevation.
  if (scan.has_ring) {
    std::map<int, std::vector<double>> by_ring;
    for (const LidarPoint& p : scan.points) by_ring[p.ring].push_back(Elevation(p.position_m));
    for (auto& [ring, elevations] : by_ring) {
      std::nth_element(elevations.begin(), elevations.begin() + elevations.size() / 2,
                       elevations.end());
      ring_elevations_rad_.push_back(elevations[elevations.size() / 2]);
    }
    std::sort(ring_elevations_rad_.begin(), ring_elevations_rad_.end());
  } else {
    std::vector<double> elevations;
    elevations.reserve(scan.points.size());
    for (const LidarPoint& p : scan.points) elevations.push_back(Elevation(p.position_m));
    std::sort(elevations.begin(), elevations.end());
    std::size_t start = 0;
    for (std::size_t i = 1; i <= elevations.size(); ++i) {
      if (i == elevations.size() ||
          elevations[i] - elevations[i - 1] > config_.ring_gap_rad) {
        if (i > start) ring_elevations_rad_.push_back(elevations[(start + i - 1) / 2]);
        start = i;
      }
    }
  }
  ranges_m_.assign(ring_elevations_rad_.size() * columns_, 0.0f);
  for (const LidarPoint& p : scan.points) {
    const double elevation = Elevation(p.position_m);
    const int ring = RingOf(elevation);
    if (ring < 0) continue;
    double azimuth = std::atan2(static_cast<double>(p.position_m.y()), p.position_m.x());
    if (azimuth < 0) azimuth += 2.0 * M_PI;
    const int column = std::min(columns_ - 1, static_cast<int>(azimuth / config_.azimuth_resolution_rad));
    float& cell = ranges_m_[static_cast<std::size_t>(ring) * columns_ + column];
    const float range = p.position_m.norm();
    if (cell == 0.0f || range < cell) cell = range;
  }
}

int RangeImage::RingOf(double elevation_rad) const {
  if (ring_elevations_rad_.empty()) return -1;
  const auto it =
      std::lower_bound(ring_elevations_rad_.begin(), ring_elevations_rad_.end(), elevation_rad);
  int best = -1;
  double best_diff = config_.elevation_tolerance_rad;
  for (auto candidate : {it, it == ring_elevations_rad_.begin() ? it : it - 1}) {
    if (candidate == ring_elevations_rad_.end()) continue;
    const double diff = std::abs(*candidate - elevation_rad);
    if (diff <= best_diff) {
      best_diff = diff;
      best = static_cast<int>(candidate - ring_elevations_rad_.begin());
    }
  }
  return best;
}

float RangeImage::MeasuredRange(int ring, int column, double point_range_m) const {
  const float* row = ranges_m_.data() + static_cast<std::size_t>(ring) * columns_;
  const float measured = row[column];
  if (measured > 0.0f) return measured;
  // No return: free space up to no_return_free_range_m when the neighbours are empty too.
  const bool neighbours_empty =
      row[(column + 1) % columns_] <= 0.0f && row[(column + columns_ - 1) % columns_] <= 0.0f;
  if (neighbours_empty && point_range_m < config_.no_return_free_range_m) {
    return std::numeric_limits<float>::infinity();
  }
  return 0.0f;
}

Visibility RangeImage::Check(const Eigen::Vector3d& point_sensor, double margin_m) const {
  if (ring_elevations_rad_.empty()) return Visibility::kUnknown;
  const double horizontal = std::hypot(point_sensor.x(), point_sensor.y());
  const double elevation = std::atan2(point_sensor.z(), horizontal);
  double azimuth = std::atan2(point_sensor.y(), point_sensor.x());
  if (azimuth < 0) azimuth += 2.0 * M_PI;
  const int column =
      std::min(columns_ - 1, static_cast<int>(azimuth / config_.azimuth_resolution_rad));
  const double range = point_sensor.norm();
  auto classify = [&](float measured) {
    if (measured <= 0.0f) return Visibility::kUnknown;
    if (measured > range + margin_m) return Visibility::kSeenThrough;
    if (measured < range - margin_m) return Visibility::kOccluded;
    return Visibility::kConsistent;
  };

  // On a beam: that beam decides.
  const int ring = RingOf(elevation);
  if (ring >= 0) return classify(MeasuredRange(ring, column, range));

  // Between two beams: free only when both passed beyond the point. On ground seen at a
  // grazing angle the lower beam lands in front of the point, so ground is never "free".
  const auto upper =
      std::upper_bound(ring_elevations_rad_.begin(), ring_elevations_rad_.end(), elevation);
  if (upper == ring_elevations_rad_.begin() || upper == ring_elevations_rad_.end()) {
    return Visibility::kUnknown;  // outside the vertical field of view
  }
  const int hi = static_cast<int>(upper - ring_elevations_rad_.begin());
  const int lo = hi - 1;
  if (ring_elevations_rad_[hi] - ring_elevations_rad_[lo] > config_.max_ring_gap_rad) {
    return Visibility::kUnknown;
  }
  const Visibility a = classify(MeasuredRange(lo, column, range));
  const Visibility b = classify(MeasuredRange(hi, column, range));
  if (a == Visibility::kSeenThrough && b == Visibility::kSeenThrough) return Visibility::kSeenThrough;
  // One beam through, the other not: near the ground that is the lower beam landing just in
  // front of the point, which proves nothing either way.
  if (a == Visibility::kSeenThrough || b == Visibility::kSeenThrough) return Visibility::kUnknown;
  if (a == Visibility::kConsistent || b == Visibility::kConsistent) return Visibility::kConsistent;
  if (a == Visibility::kOccluded && b == Visibility::kOccluded) return Visibility::kOccluded;
  return Visibility::kUnknown;
}

}  // namespace core
}  // namespace multisession_mapper
