#include "multisession_mapper/core/scan_context_descriptor.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

namespace multisession_mapper {
namespace core {

Status ScanContextConfig::Validate() const {
  const std::string p = "scan_context.";
  if (num_rings < 1 || num_rings > 1000) {
    return Status::Error(p + "num_rings must be in [1, 1000], got " + std::to_string(num_rings));
  }
  if (num_sectors < 4 || num_sectors > 3600) {
    return Status::Error(p + "num_sectors must be in [4, 3600], got " +
                         std::to_string(num_sectors));
  }
  if (!std::isfinite(min_radius_m) || min_radius_m < 0.0) {
    return Status::Error(p + "min_radius_m must be finite and >= 0");
  }
  if (!std::isfinite(max_radius_m) || max_radius_m <= min_radius_m) {
    return Status::Error(p + "max_radius_m must be finite and > min_radius_m");
  }
  if (!std::isfinite(sensor_height_m)) {
    return Status::Error(p + "sensor_height_m must be finite");
  }
  if (shift_search_radius < 0) {
    return Status::Error(p + "shift_search_radius must be >= 0");
  }
  return Status::Ok();
}

StatusOr<ScanContextDescriptor> ScanContextDescriptor::Create(const ScanContextConfig& config) {
  Status status = config.Validate();
  if (!status.ok()) return status;
  return ScanContextDescriptor(config);
}

PlaceDescriptor ScanContextDescriptor::Compute(const LidarScan& scan) const {
  const int rings = config_.num_rings;
  const int sectors = config_.num_sectors;
  PlaceDescriptor out;
  out.kind = DescriptorKind::kScanContext;
  out.rows = rings;
  out.cols = sectors;
  out.matrix.assign(static_cast<std::size_t>(rings) * sectors, 0.0f);
  const float min_sq = static_cast<float>(config_.min_radius_m * config_.min_radius_m);
  const float max_sq = static_cast<float>(config_.max_radius_m * config_.max_radius_m);
  const float ring_scale = static_cast<float>(rings / config_.max_radius_m);
  const float sector_scale = static_cast<float>(sectors / (2.0 * M_PI));
  const float height = static_cast<float>(config_.sensor_height_m);
  for (const LidarPoint& p : scan.points) {
    const float x = p.position_m.x();
    const float y = p.position_m.y();
    const float z = p.position_m.z();
    const float radius_sq = x * x + y * y;
    if (!(radius_sq >= min_sq && radius_sq <= max_sq) || !std::isfinite(z)) continue;
    const int ring = std::min(static_cast<int>(std::sqrt(radius_sq) * ring_scale), rings - 1);
    const int sector = std::clamp(
        static_cast<int>((std::atan2(y, x) + static_cast<float>(M_PI)) * sector_scale), 0,
        sectors - 1);
    float& cell = out.matrix[static_cast<std::size_t>(ring) * sectors + sector];
    cell = std::max(cell, z + height);  // cells start at 0, so negative heights stay 0
  }
  out.key.assign(static_cast<std::size_t>(rings), 0.0f);
  for (int r = 0; r < rings; ++r) {
    double sum = 0.0;
    for (int s = 0; s < sectors; ++s) sum += out.matrix[static_cast<std::size_t>(r) * sectors + s];
    out.key[static_cast<std::size_t>(r)] = static_cast<float>(sum / sectors);
  }
  return out;
}

ScanContextMatch ScanContextDescriptor::Distance(const PlaceDescriptor& query,
                                                 const PlaceDescriptor& candidate) const {
  const ScanContextMatch no_match;
  const int rings = config_.num_rings;
  const int sectors = config_.num_sectors;
  const std::size_t size = static_cast<std::size_t>(rings) * sectors;
  if (query.rows != rings || query.cols != sectors || candidate.rows != rings ||
      candidate.cols != sectors || query.matrix.size() != size || candidate.matrix.size() != size) {
    return no_match;
  }
  return DistanceRaw(query.matrix.data(), candidate.matrix.data());
}

ScanContextMatch ScanContextDescriptor::DistanceRaw(const float* q, const float* c) const {
  ScanContextMatch best;
  const int rings = config_.num_rings;
  const int sectors = config_.num_sectors;
  // Column norms and sector keys.
  std::vector<double> q_norm(sectors, 0.0), c_norm(sectors, 0.0);
  std::vector<double> q_key(sectors, 0.0), c_key(sectors, 0.0);
  for (int r = 0; r < rings; ++r) {
    for (int s = 0; s < sectors; ++s) {
      const double qv = q[r * sectors + s];
      const double cv = c[r * sectors + s];
      q_norm[s] += qv * qv;
      c_norm[s] += cv * cv;
      q_key[s] += qv;
      c_key[s] += cv;
    }
  }
  for (int s = 0; s < sectors; ++s) {
    q_norm[s] = std::sqrt(q_norm[s]);
    c_norm[s] = std::sqrt(c_norm[s]);
  }
  // Coarse shift from the sector keys (least squares over all shifts).
  int coarse = 0;
  double coarse_cost = std::numeric_limits<double>::max();
  for (int k = 0; k < sectors; ++k) {
    double cost = 0.0;
    for (int s = 0; s < sectors; ++s) {
      const double d = q_key[(s + k) % sectors] - c_key[s];
      cost += d * d;
    }
    if (cost < coarse_cost) {
      coarse_cost = cost;
      coarse = k;
    }
  }
  const int radius = std::min(config_.shift_search_radius, sectors / 2);
  const int first = radius * 2 + 1 >= sectors ? 0 : coarse - radius;
  const int count = radius * 2 + 1 >= sectors ? sectors : radius * 2 + 1;
  double best_distance = std::numeric_limits<double>::max();
  for (int i = 0; i < count; ++i) {
    const int k = ((first + i) % sectors + sectors) % sectors;
    double sum = 0.0;
    int used = 0;
    for (int s = 0; s < sectors; ++s) {
      const int qs = (s + k) % sectors;
      if (q_norm[qs] <= 0.0 || c_norm[s] <= 0.0) continue;
      double dot = 0.0;
      for (int r = 0; r < rings; ++r) dot += double(q[r * sectors + qs]) * c[r * sectors + s];
      sum += 1.0 - dot / (q_norm[qs] * c_norm[s]);
      ++used;
    }
    const double distance = used > 0 ? sum / used : 1.0;
    if (distance < best_distance) {
      best_distance = distance;
      best.shift = k;
    }
  }
  best.distance = static_cast<float>(std::clamp(best_distance, 0.0, 1.0));
  double yaw = -best.shift * 2.0 * M_PI / sectors;
  if (yaw <= -M_PI) yaw += 2.0 * M_PI;
  best.yaw_rad = yaw;
  return best;
}

}  // namespace core
}  // namespace multisession_mapper
