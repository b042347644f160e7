#include "multisession_mapper/core/range_image.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

#include "multisession_mapper/core/fast_atan2.h"

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
  if (edge_guard_columns < 0 || edge_guard_columns > 8) {
    return Status::Error("range_image.edge_guard_columns must be in [0, 8]");
  }
  if (!(ring_gap_rad > 0.0 && ring_gap_rad < 0.2)) {
    return Status::Error("range_image.ring_gap_rad must be in (0, 0.2)");
  }
  if (!(angular_uncertainty_rad >= 0.0 && angular_uncertainty_rad < 0.1)) {
    return Status::Error("range_image.angular_uncertainty_rad must be in [0, 0.1)");
  }
  return Status::Ok();
}

namespace {
// tan(elevation) of a point: monotone in the elevation, so ring lookups compare tangents and
// need no atan per point. NaN straight above or below the sensor (no ring there).
double ElevationTangent(double x, double y, double z) {
  const double horizontal = std::sqrt(x * x + y * y);
  return horizontal > 1e-9 ? z / horizontal : std::numeric_limits<double>::quiet_NaN();
}
double ElevationTangent(const Eigen::Vector3f& p) { return ElevationTangent(p.x(), p.y(), p.z()); }
double TanClamped(double angle_rad) {
  const double limit = M_PI_2 - 1e-6;
  return std::tan(std::max(-limit, std::min(limit, angle_rad)));
}
}  // namespace

RangeImage::RangeImage(const LidarScan& scan, const RangeImageConfig& config)
    : config_(config), inv_azimuth_resolution_(1.0 / config.azimuth_resolution_rad) {
  columns_ = static_cast<int>(std::ceil(2.0 * M_PI / config_.azimuth_resolution_rad));
  // Ring elevations: a ring's beam is a cone of fixed elevation. The median of the tangents
  // is the tangent of the median elevation.
  // Row of each ring id (has_ring), by ascending elevation.
  std::map<int, int> row_of_ring;
  if (scan.has_ring) {
    std::map<int, std::vector<double>> by_ring;
    for (const LidarPoint& p : scan.points) {
      const double t = ElevationTangent(p.position_m);
      if (std::isfinite(t)) by_ring[p.ring].push_back(t);
    }
    std::vector<std::pair<double, int>> elevation_ring;
    for (auto& [ring, tangents] : by_ring) {
      std::nth_element(tangents.begin(), tangents.begin() + tangents.size() / 2, tangents.end());
      elevation_ring.emplace_back(std::atan(tangents[tangents.size() / 2]), ring);
    }
    std::sort(elevation_ring.begin(), elevation_ring.end());
    for (const auto& [elevation, ring] : elevation_ring) {
      row_of_ring[ring] = static_cast<int>(ring_elevations_rad_.size());
      ring_elevations_rad_.push_back(elevation);
    }
  } else {
    std::vector<double> elevations;
    elevations.reserve(scan.points.size());
    for (const LidarPoint& p : scan.points) {
      const double t = ElevationTangent(p.position_m);
      if (std::isfinite(t)) elevations.push_back(std::atan(t));
    }
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
  for (const double elevation : ring_elevations_rad_) {
    ring_tangents_.push_back(std::tan(elevation));
    gate_low_tangents_.push_back(TanClamped(elevation - config_.elevation_tolerance_rad));
    gate_high_tangents_.push_back(TanClamped(elevation + config_.elevation_tolerance_rad));
  }
  if (!ring_tangents_.empty()) {
    // 2048 entries over the rings' tangents and a margin: a few hundredths of a degree each.
    constexpr int kEntries = 2048;
    const double margin = 0.05;
    lut_low_tangent_ = ring_tangents_.front() - margin;
    const double step =
        (ring_tangents_.back() + margin - lut_low_tangent_) / static_cast<double>(kEntries);
    lut_inv_step_ = 1.0 / step;
    lut_first_ring_.resize(kEntries);
    std::size_t ring = 0;  // entries ascend, so the answer only moves up: one sweep
    for (int b = 0; b < kEntries; ++b) {
      const double t = lut_low_tangent_ + b * step;
      while (ring < ring_tangents_.size() && ring_tangents_[ring] < t) ++ring;
      lut_first_ring_[b] = static_cast<std::uint16_t>(ring);
    }
  }
  ranges_m_.assign(ring_elevations_rad_.size() * columns_, 0.0f);
  // With a ring field every point goes into its own ring's row. A de-skewed point is no
  // longer exactly on its beam's cone (0.3 m of motion during the sweep moves ground 10 m
  // ahead by 0.3 deg), so gating it by elevation would leave pixels empty, and an empty
  // pixel reads as free space: ground 10-15 m away was then removed as "seen through".
  for (const LidarPoint& p : scan.points) {
    int ring = -1;
    if (scan.has_ring) {
      const auto found = row_of_ring.find(p.ring);
      if (found != row_of_ring.end() && std::isfinite(ElevationTangent(p.position_m))) {
        ring = found->second;
      }
    } else {
      ring = RingOfTangent(ElevationTangent(p.position_m));
    }
    if (ring < 0) continue;
    float& cell = ranges_m_[static_cast<std::size_t>(ring) * columns_ +
                            ColumnOf(p.position_m.x(), p.position_m.y())];
    const float range = p.position_m.norm();
    if (cell == 0.0f || range < cell) cell = range;
  }
}

int RangeImage::ColumnOf(double x, double y) const {
  double azimuth = FastAtan2(y, x);
  if (azimuth < 0) azimuth += 2.0 * M_PI;
  return std::min(columns_ - 1, static_cast<int>(azimuth * inv_azimuth_resolution_));
}

int RangeImage::FirstRingAtOrAbove(double tangent) const {
  const double entry = (tangent - lut_low_tangent_) * lut_inv_step_;
  const int last = static_cast<int>(lut_first_ring_.size()) - 1;
  const int b = entry <= 0.0 ? 0 : (entry >= last ? last : static_cast<int>(entry));
  // The table's answer is that of the entry's lower edge; step to the exact one (also when
  // rounding put the tangent into a neighbouring entry).
  int ring = lut_first_ring_[b];
  const int rings = static_cast<int>(ring_tangents_.size());
  while (ring > 0 && ring_tangents_[ring - 1] >= tangent) --ring;
  while (ring < rings && ring_tangents_[ring] < tangent) ++ring;
  return ring;
}

int RangeImage::RingOfTangent(double tangent) const {
  if (ring_tangents_.empty() || !std::isfinite(tangent)) return -1;
  return RingOfTangent(tangent, FirstRingAtOrAbove(tangent));
}

int RangeImage::RingOfTangent(double tangent, int above) const {
  // The nearest ring below or above, if the tangent is inside its elevation gate.
  int best = -1;
  double best_diff = std::numeric_limits<double>::infinity();
  for (const int ring : {above, above - 1}) {
    if (ring < 0 || ring >= static_cast<int>(ring_tangents_.size())) continue;
    if (tangent < gate_low_tangents_[ring] || tangent > gate_high_tangents_[ring]) continue;
    const double diff = std::abs(ring_tangents_[ring] - tangent);
    if (diff < best_diff) {
      best_diff = diff;
      best = ring;
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
  if (!neighbours_empty || point_range_m >= config_.no_return_free_range_m) return 0.0f;
  // A beam that passed over a surface without returning is free space only in front of that
  // surface: not beyond what the nearest lower ring with a return measured in this column.
  // Without this cap, ground seen at a grazing angle from a slightly tilted pose, or behind
  // a crest, lies under beams that returned nothing and was removed as "seen through".
  for (int below = ring - 1; below >= 0; --below) {
    const float measured_below = ranges_m_[static_cast<std::size_t>(below) * columns_ + column];
    if (measured_below > 0.0f) {
      return point_range_m < measured_below ? std::numeric_limits<float>::infinity() : 0.0f;
    }
  }
  return std::numeric_limits<float>::infinity();
}

double RangeImage::RangeSlope(int ring, int column) const {
  const float here = ranges_m_[static_cast<std::size_t>(ring) * columns_ + column];
  if (!(here > 0.0f) || !std::isfinite(here)) return 0.0;
  double slope = std::numeric_limits<double>::infinity();
  for (const int other : {ring - 1, ring + 1}) {
    if (other < 0 || other >= static_cast<int>(ring_elevations_rad_.size())) continue;
    const double gap = std::abs(ring_elevations_rad_[other] - ring_elevations_rad_[ring]);
    if (gap > config_.max_ring_gap_rad || gap <= 0.0) continue;
    const float there = ranges_m_[static_cast<std::size_t>(other) * columns_ + column];
    if (!(there > 0.0f) || !std::isfinite(there)) continue;
    slope = std::min(slope, std::abs(static_cast<double>(there) - here) / gap);
  }
  return std::isfinite(slope) ? slope : 0.0;
}

bool RangeImage::BesideASurface(int ring, int column, double range, double margin_m) const {
  const float* row = ranges_m_.data() + static_cast<std::size_t>(ring) * columns_;
  for (int offset = 1; offset <= config_.edge_guard_columns; ++offset) {
    for (const int c : {(column + offset) % columns_, (column + columns_ - offset) % columns_}) {
      if (row[c] > 0.0f && std::abs(row[c] - range) <= margin_m) return true;
    }
  }
  return false;
}

Visibility RangeImage::Check(const Eigen::Vector3d& point_sensor, double margin_m) const {
  return Check(point_sensor, point_sensor.norm(), margin_m);
}

Visibility RangeImage::Check(const Eigen::Vector3d& point_sensor, double range,
                             double margin_m) const {
  if (ring_tangents_.empty()) return Visibility::kUnknown;
  const double tangent = ElevationTangent(point_sensor.x(), point_sensor.y(), point_sensor.z());
  if (!std::isfinite(tangent)) return Visibility::kUnknown;
  return Classify(range, tangent, ColumnOf(point_sensor.x(), point_sensor.y()), margin_m);
}

namespace {
// CheckMany's pass 1: sensor-frame range, elevation tangent and azimuth column of m points,
// and whether each is judged at all (within the range, not straight above or below). No
// branches and no calls (selects only) and restrict pointers, so that GCC vectorises it; that
// also needs -fno-math-errno and -fno-trapping-math for this file (CMakeLists.txt), which
// change no result: every operation is the same IEEE one, only errno and FP traps are not kept.
struct BatchDirections {
  float r[9];  // R_sensor_frame, row-major
  float t[3];
  float max_range_sq;
  float inv_resolution;
  int last_column;
};
void Directions(const BatchDirections& d, const float* __restrict x, const float* __restrict y,
                const float* __restrict z, std::size_t m, float* __restrict range,
                float* __restrict tangent, int* __restrict column, int* __restrict judged) {
  constexpr float kMinHorizontal = 1e-6f;  // straight above or below: no ring there
  constexpr float kPi = static_cast<float>(M_PI);
  for (std::size_t i = 0; i < m; ++i) {
    const float px = d.r[0] * x[i] + d.r[1] * y[i] + d.r[2] * z[i] + d.t[0];
    const float py = d.r[3] * x[i] + d.r[4] * y[i] + d.r[5] * z[i] + d.t[1];
    const float pz = d.r[6] * x[i] + d.r[7] * y[i] + d.r[8] * z[i] + d.t[2];
    const float horizontal_sq = px * px + py * py;
    const float range_sq = horizontal_sq + pz * pz;
    const float horizontal = std::sqrt(horizontal_sq);
    range[i] = std::sqrt(range_sq);
    tangent[i] = pz / (horizontal > kMinHorizontal ? horizontal : 1.0f);
    judged[i] = (horizontal > kMinHorizontal) & (range_sq <= d.max_range_sq);
    // The azimuth in [0, 2 pi] as ColumnOf gets it from FastAtan2 (in float, just below 2 pi
    // can round to 2 pi: the clamp to the last column takes it), then its column.
    const float ax = std::fabs(px), ay = std::fabs(py);
    const float big = ax > ay ? ax : ay;
    const float small = ax > ay ? ay : ax;
    float angle = AtanUnitF(small / (big > 0.0f ? big : 1.0f));
    angle = ay > ax ? 0.5f * kPi - angle : angle;
    angle = px < 0.0f ? kPi - angle : angle;
    angle = py < 0.0f ? 2.0f * kPi - angle : angle;
    angle = angle < 7.0f ? angle : 0.0f;  // a NaN (never judged) must not reach the cast
    const int c = static_cast<int>(angle * d.inv_resolution);
    column[i] = c < d.last_column ? c : d.last_column;
  }
}
}  // namespace

void RangeImage::CheckMany(const Batch& batch, const float* x, const float* y, const float* z,
                           std::size_t n, Visibility* out, float* range_out) const {
  BatchDirections d;
  for (int row = 0; row < 3; ++row) {
    for (int col = 0; col < 3; ++col) d.r[3 * row + col] = batch.R_sensor_frame(row, col);
    d.t[row] = batch.t_sensor_frame[row];
  }
  d.max_range_sq = static_cast<float>(
      std::min(batch.max_range_m * batch.max_range_m,
               static_cast<double>(std::numeric_limits<float>::max())));
  d.inv_resolution = static_cast<float>(inv_azimuth_resolution_);
  d.last_column = columns_ - 1;
  // Blocks small enough for the stack and the L1 cache: the directions of a block, then its
  // look-ups.
  constexpr std::size_t kBlock = 256;
  float tangent[kBlock];
  int column[kBlock];
  int judged[kBlock];
  for (std::size_t first = 0; first < n; first += kBlock) {
    const std::size_t m = std::min(kBlock, n - first);
    float* ranges = range_out + first;
    Directions(d, x + first, y + first, z + first, m, ranges, tangent, column, judged);
    for (std::size_t i = 0; i < m; ++i) {
      const double range = ranges[i];
      out[first + i] = judged[i] && !ring_tangents_.empty()
                           ? Classify(range, tangent[i], column[i],
                                      batch.margin_base_m + batch.margin_per_m * range)
                           : Visibility::kUnknown;
    }
  }
}

Visibility RangeImage::Classify(double range, double tangent, int column,
                                double margin_m) const {
  auto classify = [&](float measured, double margin) {
    if (measured <= 0.0f) return Visibility::kUnknown;
    if (measured > range + margin) return Visibility::kSeenThrough;
    if (measured < range - margin) return Visibility::kOccluded;
    return Visibility::kConsistent;
  };

  // On a beam: that beam decides. The margin grows where the measured surface is seen at a
  // grazing angle, by its range slope times the direction uncertainty plus the point's
  // elevation offset from the beam (see RangeImageConfig::angular_uncertainty_rad).
  const int above = FirstRingAtOrAbove(tangent);  // for both cases below
  const int ring = RingOfTangent(tangent, above);
  if (ring >= 0) {
    const float measured = MeasuredRange(ring, column, range);
    double margin = margin_m;
    if (config_.angular_uncertainty_rad > 0.0 && measured > 0.0f && std::isfinite(measured)) {
      // atan only here: most checks never need the elevation itself.
      margin += RangeSlope(ring, column) * (config_.angular_uncertainty_rad +
                                            std::abs(std::atan(tangent) - ring_elevations_rad_[ring]));
    }
    const Visibility vis = classify(measured, margin);
    if (vis == Visibility::kSeenThrough && BesideASurface(ring, column, range, margin_m)) {
      return Visibility::kUnknown;
    }
    return vis;
  }

  // Between two beams: free only when both passed beyond the point. On ground seen at a
  // grazing angle the lower beam lands in front of the point, so ground is never "free".
  int hi = above;  // then the first ring strictly above
  const int rings = static_cast<int>(ring_tangents_.size());
  while (hi < rings && ring_tangents_[hi] <= tangent) ++hi;
  if (hi == 0 || hi == rings) return Visibility::kUnknown;  // outside the vertical field of view
  const int lo = hi - 1;
  if (ring_elevations_rad_[hi] - ring_elevations_rad_[lo] > config_.max_ring_gap_rad) {
    return Visibility::kUnknown;
  }
  const float measured_lo = MeasuredRange(lo, column, range);
  const float measured_hi = MeasuredRange(hi, column, range);
  const Visibility a = classify(measured_lo, margin_m);
  const Visibility b = classify(measured_hi, margin_m);
  if (a == Visibility::kSeenThrough && b == Visibility::kSeenThrough) {
    // Both passed beyond. When both hit something, the surface between the two hits, taken
    // as continuous, must also lie beyond the point at the point's elevation, by the margin
    // plus its range slope times the direction uncertainty: ground seen at a grazing angle
    // from a slightly tilted pose passes the first test but not this one.
    if (config_.angular_uncertainty_rad > 0.0 && std::isfinite(measured_lo) &&
        std::isfinite(measured_hi)) {
      const double gap = ring_elevations_rad_[hi] - ring_elevations_rad_[lo];
      const double slope = (static_cast<double>(measured_hi) - measured_lo) / gap;
      const double interpolated =
          measured_lo + slope * (std::atan(tangent) - ring_elevations_rad_[lo]);
      if (interpolated <= range + margin_m + std::abs(slope) * config_.angular_uncertainty_rad) {
        return Visibility::kUnknown;
      }
    }
    return Visibility::kSeenThrough;
  }
  // One beam through, the other not: near the ground that is the lower beam landing just in
  // front of the point, which proves nothing either way.
  if (a == Visibility::kSeenThrough || b == Visibility::kSeenThrough) return Visibility::kUnknown;
  if (a == Visibility::kConsistent || b == Visibility::kConsistent) return Visibility::kConsistent;
  if (a == Visibility::kOccluded && b == Visibility::kOccluded) return Visibility::kOccluded;
  return Visibility::kUnknown;
}

}  // namespace core
}  // namespace multisession_mapper
