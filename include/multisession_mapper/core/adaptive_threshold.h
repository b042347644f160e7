// Adaptive correspondence threshold of KISS-ICP (Vizzo et al. 2023, Sec. III-C): the spread of
// the deviation between the constant-velocity prediction and the ICP result, measured in
// metres at the sensor's range (a rotation error theta moves a point at range r by
// 2 r sin(theta / 2)). The odometry uses 3 sigma as the correspondence distance and sigma / 3
// as the robust-kernel scale, so the search shrinks on smooth motion and grows on jerks.
#pragma once

#include <cstddef>

#include "multisession_mapper/core/status.h"
#include "multisession_mapper/core/types.h"

namespace multisession_mapper {
namespace core {

struct AdaptiveThresholdConfig {
  /// sigma before any sample was taken [m] (the first scans: no motion statistics yet).
  double initial_threshold_m = 2.0;
  /// A scan adds a sample only when the robot moved at least this much since the previous
  /// one [m]: standing still says nothing about the model error.
  double min_motion_m = 0.1;
  /// Range at which a rotation error is converted to metres [m]; the sensor's max range.
  double max_range_m = 100.0;
  /// Floor and ceiling of sigma [m]: keeps the search usable after long smooth stretches and
  /// the robust kernel tight in turns (KISS-ICP has neither). Measured on the synthetic 3 m/s
  /// sequence of odometry_test: a ceiling of 0.6 m instead of 3 m cut the peak error in sharp
  /// turns from ~0.6 m to ~0.4 m; a floor of 0.2 m instead of 0.1 m avoids losing track when
  /// a turn starts after a long straight.
  double min_threshold_m = 0.2;
  double max_threshold_m = 0.6;

  Status Validate() const;
};

class AdaptiveThreshold {
 public:
  static StatusOr<AdaptiveThreshold> Create(const AdaptiveThresholdConfig& config);

  /// Records one scan: `model_deviation` = prediction^-1 * estimate, `motion` = the estimated
  /// motion since the previous scan (only its size is used).
  void Update(const Pose3& model_deviation, const Pose3& motion);
  /// sigma [m]: sqrt of the mean squared model error, clamped to [min, max];
  /// initial_threshold_m (unclamped) before the first sample.
  double Sigma() const;
  std::size_t num_samples() const { return num_samples_; }
  void Reset();

 private:
  explicit AdaptiveThreshold(const AdaptiveThresholdConfig& config) : config_(config) {}
  AdaptiveThresholdConfig config_;
  double sum_sq_m2_ = 0.0;
  std::size_t num_samples_ = 0;
};

}  // namespace core
}  // namespace multisession_mapper
