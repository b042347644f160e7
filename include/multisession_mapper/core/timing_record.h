// The per-session timing record (timing/<session>.yaml in the map, docs/map_format.md):
// medians and 95th percentiles of the per-stage samples, wall time, real-time factor inputs.
#pragma once

#include <string>
#include <vector>

#include "multisession_mapper/core/session_mapper.h"

namespace multisession_mapper {
namespace core {

struct TimingSummary {
  double median = 0.0;
  double p95 = 0.0;
  std::size_t samples = 0;
};

/// Median and 95th percentile (nearest rank); zeros for no samples.
TimingSummary Summarize(std::vector<double> samples);

struct SessionRunInfo {
  double wall_time_s = 0.0;     ///< reading the bag to the saved map
  double bag_duration_s = 0.0;  ///< first to last scan stamp
  double peak_rss_mb = 0.0;
  double merge_s = 0.0;         ///< joint optimisation, dynamics, update and save
  double merge_matching_s = 0.0;      ///< voting, global registration, consistency [s]
  double merge_optimisation_s = 0.0;  ///< joint graph and the proximity loop search [s]
  double merge_update_s = 0.0;        ///< dynamic detection and map update [s]
  /// Parts of merge_update_s [s] (MergeReport::update_*_s).
  double merge_update_dynamics_s = 0.0;
  double merge_update_fusion_s = 0.0;
  double merge_update_database_s = 0.0;
};

std::string TimingYaml(const SessionTimings& timings, const SessionRunInfo& run);

/// Peak resident set size of this process so far [MB] (getrusage; in a nodelet manager: the
/// whole manager process, all nodelets).
double ProcessPeakRssMb();

}  // namespace core
}  // namespace multisession_mapper
