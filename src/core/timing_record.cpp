#include "multisession_mapper/core/timing_record.h"

#include <sys/resource.h>

#include <algorithm>
#include <cmath>

#include <yaml-cpp/yaml.h>

namespace multisession_mapper {
namespace core {

TimingSummary Summarize(std::vector<double> samples) {
  TimingSummary summary;
  summary.samples = samples.size();
  if (samples.empty()) return summary;
  std::sort(samples.begin(), samples.end());
  const std::size_t n = samples.size();
  summary.median = n % 2 ? samples[n / 2] : 0.5 * (samples[n / 2 - 1] + samples[n / 2]);
  const std::size_t rank = static_cast<std::size_t>(std::ceil(0.95 * n));
  summary.p95 = samples[std::min(n - 1, rank == 0 ? 0 : rank - 1)];
  return summary;
}

namespace {
void Emit(YAML::Emitter* out, const char* name, const std::vector<double>& samples) {
  const TimingSummary s = Summarize(samples);
  *out << YAML::Key << name << YAML::Value << YAML::Flow << YAML::BeginMap << YAML::Key
       << "median" << YAML::Value << s.median << YAML::Key << "p95" << YAML::Value << s.p95
       << YAML::Key << "samples" << YAML::Value << s.samples << YAML::EndMap;
}
}  // namespace

std::string TimingYaml(const SessionTimings& timings, const SessionRunInfo& run) {
  YAML::Emitter out;
  out.SetDoublePrecision(6);
  out << YAML::BeginMap;
  out << YAML::Key << "wall_time_s" << YAML::Value << run.wall_time_s;
  out << YAML::Key << "bag_duration_s" << YAML::Value << run.bag_duration_s;
  out << YAML::Key << "realtime_factor" << YAML::Value
      << (run.wall_time_s > 0.0 ? run.bag_duration_s / run.wall_time_s : 0.0);
  out << YAML::Key << "peak_rss_mb" << YAML::Value << run.peak_rss_mb;
  out << YAML::Key << "per_scan_ms" << YAML::Value << YAML::BeginMap;
  Emit(&out, "deskew_odometry", timings.odometry_ms);
  Emit(&out, "submap_building", timings.submap_building_ms);
  Emit(&out, "descriptor", timings.descriptor_ms);
  Emit(&out, "query", timings.query_ms);
  out << YAML::EndMap;
  out << YAML::Key << "odometry_stages_ms" << YAML::Value << YAML::BeginMap;
  Emit(&out, "filter", timings.odometry_filter_ms);
  Emit(&out, "deskew", timings.odometry_deskew_ms);
  Emit(&out, "downsample_normals", timings.odometry_downsample_ms);
  Emit(&out, "registration", timings.odometry_registration_ms);
  Emit(&out, "map_ground", timings.odometry_map_ground_ms);
  Emit(&out, "map_update", timings.odometry_map_update_ms);
  out << YAML::EndMap;
  out << YAML::Key << "odometry_icp_per_scan" << YAML::Value << YAML::BeginMap;
  Emit(&out, "registrations", timings.odometry_registrations);
  Emit(&out, "iterations", timings.odometry_icp_iterations);
  Emit(&out, "searches", timings.odometry_icp_searches);
  out << YAML::EndMap;
  out << YAML::Key << "per_submap_s" << YAML::Value << YAML::BeginMap;
  Emit(&out, "intra_loop", timings.intra_loop_s);
  Emit(&out, "optimisation", timings.optimisation_s);
  out << YAML::EndMap;
  out << YAML::Key << "per_pair_s" << YAML::Value << YAML::BeginMap;
  Emit(&out, "global_registration", timings.global_registration_s);
  Emit(&out, "guided_registration", timings.guided_registration_s);
  Emit(&out, "dynamic_detection", timings.dynamic_detection_s);
  Emit(&out, "intra_pair_detection", timings.intra_pair_detection_s);
  out << YAML::EndMap;
  out << YAML::Key << "merge_s" << YAML::Value << run.merge_s;
  out << YAML::Key << "merge_stages_s" << YAML::Value << YAML::Flow << YAML::BeginMap
      << YAML::Key << "matching" << YAML::Value << run.merge_matching_s << YAML::Key
      << "optimisation" << YAML::Value << run.merge_optimisation_s << YAML::Key << "update"
      << YAML::Value << run.merge_update_s << YAML::Key << "update_dynamics" << YAML::Value
      << run.merge_update_dynamics_s << YAML::Key << "update_fusion" << YAML::Value
      << run.merge_update_fusion_s << YAML::Key << "update_database" << YAML::Value
      << run.merge_update_database_s << YAML::EndMap;
  out << YAML::EndMap;
  return std::string(out.c_str()) + "\n";
}

double ProcessPeakRssMb() {
  struct rusage usage {};
  if (getrusage(RUSAGE_SELF, &usage) != 0) return 0.0;
  return usage.ru_maxrss / 1024.0;  // Linux: KiB
}

}  // namespace core
}  // namespace multisession_mapper
