// First stage of the pipeline: drops returns that no later stage should see. Non-finite and
// zero-range points (how drivers mark "no return"), points outside [min_range_m, max_range_m]
// and points inside a box around the robot body (self hits). Point attributes are kept.
#pragma once

#include <cstddef>

#include <Eigen/Core>

#include "multisession_mapper/core/status.h"
#include "multisession_mapper/core/types.h"

namespace multisession_mapper {
namespace core {

struct InputFilterConfig {
  /// Returns closer than this are dropped [m]. VLP-16 spec minimum is ~0.5 m; 1.0 m also
  /// removes most hits on the robot's own frame.
  double min_range_m = 1.0;
  /// Returns farther than this are dropped [m]. VLP-16 nominal range is 100 m.
  double max_range_m = 100.0;
  /// Self-hit box in the sensor frame [m]; disabled while `self_box_enabled` is false.
  bool self_box_enabled = false;
  Eigen::Vector3d self_box_min_m = Eigen::Vector3d(-0.8, -0.6, -1.5);
  Eigen::Vector3d self_box_max_m = Eigen::Vector3d(0.8, 0.6, 0.2);

  /// OK when every field is finite and consistent; otherwise names the bad field.
  Status Validate() const;
};

/// Counts of what the filter dropped, for logging and the timing/health records.
struct InputFilterStats {
  std::size_t input = 0;
  std::size_t non_finite = 0;
  std::size_t out_of_range = 0;
  std::size_t self_hits = 0;
  std::size_t kept = 0;
};

class InputFilter {
 public:
  /// `config` must be valid (see InputFilterConfig::Validate); Create() checks it.
  static StatusOr<InputFilter> Create(const InputFilterConfig& config);

  /// Returns the filtered copy of `scan`; stamps and flags are kept.
  LidarScan Apply(const LidarScan& scan, InputFilterStats* stats = nullptr) const;

  const InputFilterConfig& config() const { return config_; }

 private:
  explicit InputFilter(const InputFilterConfig& config) : config_(config) {}
  InputFilterConfig config_;
};

}  // namespace core
}  // namespace multisession_mapper
