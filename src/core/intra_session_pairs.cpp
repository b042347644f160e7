#include "multisession_mapper/core/intra_session_pairs.h"

#include <algorithm>
#include <string>
#include <utility>

#include "multisession_mapper/core/parallel_for.h"
#include "multisession_mapper/core/point_index_pool.h"

namespace multisession_mapper {
namespace core {

Status IntraSessionPairsConfig::Validate() const {
  if (neighbours < 1 || neighbours > 8) {
    return Status::Error("intra-session pairs: neighbours must be in [1, 8], got " +
                         std::to_string(neighbours));
  }
  if (!(max_dynamic_fraction > 0.0 && max_dynamic_fraction <= 1.0)) {
    return Status::Error("intra-session pairs: max_dynamic_fraction must be in (0, 1], got " +
                         std::to_string(max_dynamic_fraction));
  }
  if (num_threads < 1 || num_threads > 64) {
    return Status::Error("intra-session pairs: num_threads must be in [1, 64], got " +
                         std::to_string(num_threads));
  }
  return DetectionConfig().Validate();
}

DynamicDetectionConfig IntraSessionPairsConfig::DetectionConfig() const {
  DynamicDetectionConfig c = detection;
  c.rays_from_viewing_scans = rays_from_viewing_scans;
  c.min_pass_incidence_rad = min_pass_incidence_rad;
  c.min_cluster_coarse_fraction = min_cluster_coarse_fraction;
  c.own_ground_max_gap_m = own_ground_max_gap_m;
  c.changed_objects_enabled = changed_objects_enabled;
  c.far_range_m = far_range_m;
  return c;
}

StatusOr<IntraSessionPairsStats> RemoveDynamicsBetweenSubmaps(
    const IntraSessionPairsConfig& config,
    std::vector<Submap, Eigen::aligned_allocator<Submap>>* submaps) {
  Status valid = config.Validate();
  if (!valid.ok()) return valid;
  StatusOr<DynamicDetector> detector = DynamicDetector::Create(config.DetectionConfig());
  if (!detector.ok()) return detector.status();
  std::vector<Submap, Eigen::aligned_allocator<Submap>>& maps = *submaps;
  struct Pair {
    std::size_t earlier, later;
  };
  IntraSessionPairsStats stats;
  std::vector<Pair> pairs;
  std::vector<int> uses(maps.size(), 0);
  for (std::size_t i = 0; i < maps.size(); ++i) {
    if (maps[i].points.empty() || maps[i].scans.empty()) continue;
    for (std::size_t j = i + 1; j < maps.size() && j <= i + config.neighbours; ++j) {
      // Not across a jump of the odometry (Submap::started_at_jump_m): the two sides of a
      // jump are placed only by a weak link unless a loop corrected it, and a misplaced pair
      // passes for change.
      if (maps[j].started_at_jump_m > 0.0) {
        stats.pairs_across_jumps += std::min(maps.size() - 1, i + config.neighbours) - j + 1;
        break;
      }
      if (maps[j].points.empty() || maps[j].scans.empty()) continue;
      pairs.push_back({i, j});
      ++uses[i];
      ++uses[j];
    }
  }
  // Each submap's neighbour index is built once (in its own frame) and shared by its pairs.
  PointIndexPool indices(std::move(uses),
                         [&](std::size_t k) -> const PointVector& { return maps[k].points; });
  std::vector<StatusOr<DynamicDetectionResult>> detections(pairs.size(),
                                                           Status::Error("not run"));
  ParallelFor(pairs.size(), config.num_threads, [&](std::size_t i) {
    const Pair& p = pairs[i];
    const Pose3 T_later_earlier =
        maps[p.later].T_map_submap.inverse() * maps[p.earlier].T_map_submap;
    detections[i] = detector.value().Detect(maps[p.earlier], maps[p.later], T_later_earlier,
                                            &indices, p.earlier, &indices, p.later);
  });
  stats.pairs = pairs.size();
  std::vector<std::vector<std::uint8_t>> dynamic(maps.size());
  for (std::size_t k = 0; k < maps.size(); ++k) dynamic[k].assign(maps[k].points.size(), 0);
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    if (!detections[i].ok()) {
      ++stats.skipped_pairs;
      continue;
    }
    const DynamicDetectionResult& d = detections[i].value();
    stats.pair_s.push_back(d.time_s);
    stats.stage_s.Add(d.stage);
    const Pair& p = pairs[i];
    if (d.MarksMoreThan(config.max_dynamic_fraction, maps[p.earlier].points.size(),
                        maps[p.later].points.size())) {
      ++stats.skipped_pairs;
      continue;
    }
    for (std::uint32_t k : d.history_dynamic) {
      if (k < dynamic[p.earlier].size()) dynamic[p.earlier][k] = 1;
    }
    for (std::uint32_t k : d.current_dynamic) {
      if (k < dynamic[p.later].size()) dynamic[p.later][k] = 1;
    }
  }
  for (std::size_t k = 0; k < maps.size(); ++k) {
    const std::size_t before = maps[k].points.size();
    DropSubmapPoints(dynamic[k], &maps[k]);
    stats.points_removed += before - maps[k].points.size();
  }
  return stats;
}

}  // namespace core
}  // namespace multisession_mapper
