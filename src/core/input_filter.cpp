#include "multisession_mapper/core/input_filter.h"

#include <cmath>
#include <string>

namespace multisession_mapper {
namespace core {

Status InputFilterConfig::Validate() const {
  if (!std::isfinite(min_range_m) || min_range_m < 0.0) {
    return Status::Error("input_filter.min_range_m must be finite and >= 0, got " +
                         std::to_string(min_range_m));
  }
  if (!std::isfinite(max_range_m) || max_range_m <= min_range_m) {
    return Status::Error("input_filter.max_range_m must be finite and > min_range_m, got " +
                         std::to_string(max_range_m));
  }
  if (self_box_enabled) {
    if (!self_box_min_m.allFinite() || !self_box_max_m.allFinite() ||
        (self_box_max_m.array() <= self_box_min_m.array()).any()) {
      return Status::Error("input_filter.self_box: max must exceed min on every axis");
    }
  }
  return Status::Ok();
}

StatusOr<InputFilter> InputFilter::Create(const InputFilterConfig& config) {
  Status status = config.Validate();
  if (!status.ok()) return status;
  return InputFilter(config);
}

LidarScan InputFilter::Apply(const LidarScan& scan, InputFilterStats* stats) const {
  InputFilterStats local;
  local.input = scan.points.size();
  LidarScan out;
  out.stamp_s = scan.stamp_s;
  out.has_ring = scan.has_ring;
  out.has_time = scan.has_time;
  out.points.reserve(scan.points.size());
  const double min_sq = config_.min_range_m * config_.min_range_m;
  const double max_sq = config_.max_range_m * config_.max_range_m;
  const Eigen::Vector3f box_min = config_.self_box_min_m.cast<float>();
  const Eigen::Vector3f box_max = config_.self_box_max_m.cast<float>();
  for (const LidarPoint& p : scan.points) {
    if (!p.position_m.allFinite() || !std::isfinite(p.time_s)) {
      ++local.non_finite;
      continue;
    }
    const double range_sq = p.position_m.cast<double>().squaredNorm();
    if (range_sq <= 0.0 || range_sq < min_sq || range_sq > max_sq) {
      ++local.out_of_range;
      continue;
    }
    if (config_.self_box_enabled && (p.position_m.array() >= box_min.array()).all() &&
        (p.position_m.array() <= box_max.array()).all()) {
      ++local.self_hits;
      continue;
    }
    out.points.push_back(p);
  }
  local.kept = out.points.size();
  if (stats != nullptr) *stats = local;
  return out;
}

}  // namespace core
}  // namespace multisession_mapper
