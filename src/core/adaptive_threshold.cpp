#include "multisession_mapper/core/adaptive_threshold.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "multisession_mapper/core/se3.h"

namespace multisession_mapper {
namespace core {

Status AdaptiveThresholdConfig::Validate() const {
  const auto positive = [](double v) { return std::isfinite(v) && v > 0.0; };
  if (!positive(initial_threshold_m)) {
    return Status::Error("adaptive_threshold.initial_threshold_m must be > 0, got " +
                         std::to_string(initial_threshold_m));
  }
  if (!std::isfinite(min_motion_m) || min_motion_m < 0.0) {
    return Status::Error("adaptive_threshold.min_motion_m must be >= 0, got " +
                         std::to_string(min_motion_m));
  }
  if (!positive(max_range_m)) {
    return Status::Error("adaptive_threshold.max_range_m must be > 0, got " +
                         std::to_string(max_range_m));
  }
  if (!positive(min_threshold_m) || !positive(max_threshold_m) ||
      max_threshold_m < min_threshold_m) {
    return Status::Error(
        "adaptive_threshold: need 0 < min_threshold_m <= max_threshold_m, got " +
        std::to_string(min_threshold_m) + ", " + std::to_string(max_threshold_m));
  }
  return Status::Ok();
}

StatusOr<AdaptiveThreshold> AdaptiveThreshold::Create(const AdaptiveThresholdConfig& config) {
  const Status status = config.Validate();
  if (!status.ok()) return status;
  return AdaptiveThreshold(config);
}

void AdaptiveThreshold::Update(const Pose3& model_deviation, const Pose3& motion) {
  if (se3::TranslationNorm(motion) < config_.min_motion_m) return;
  const double theta = se3::RotationAngleRad(model_deviation);
  const double error_m =
      2.0 * config_.max_range_m * std::sin(theta / 2.0) + se3::TranslationNorm(model_deviation);
  sum_sq_m2_ += error_m * error_m;
  ++num_samples_;
}

double AdaptiveThreshold::Sigma() const {
  // The initial value is deliberately not clamped: the first scans need the wide search.
  if (num_samples_ == 0) return config_.initial_threshold_m;
  const double sigma = std::sqrt(sum_sq_m2_ / static_cast<double>(num_samples_));
  return std::clamp(sigma, config_.min_threshold_m, config_.max_threshold_m);
}

void AdaptiveThreshold::Reset() {
  sum_sq_m2_ = 0.0;
  num_samples_ = 0;
}

}  // namespace core
}  // namespace multisession_mapper
