#include "multisession_mapper/core/dynamic_propagation.h"

#include <cmath>
#include <string>
#include <utility>

#include "multisession_mapper/core/parallel_for.h"
#include "multisession_mapper/core/point_index.h"
#include "multisession_mapper/core/voxel_occupancy.h"

namespace multisession_mapper {
namespace core {

StatusOr<std::vector<std::vector<std::uint32_t>>> FindCopiesOfMarked(
    double radius_m, int num_threads, const std::vector<MarkedCloud>& clouds) {
  if (!std::isfinite(radius_m) || radius_m <= 0.0) {
    return Status::Error("propagation radius must be > 0, got " + std::to_string(radius_m));
  }
  std::vector<std::vector<std::uint32_t>> found(clouds.size());
  // The marked points in the map frame, and their voxels (edge radius_m) with their neighbours:
  // a point outside them has no marked point within radius_m and is rejected before the exact
  // kd-tree test, in one look-up.
  PointVector marked_map;
  VoxelOccupancy near_marked(radius_m);
  for (const MarkedCloud& c : clouds) {
    if (c.points == nullptr) return Status::Error("propagation: a cloud without points");
    if (c.marked == nullptr) continue;
    for (std::uint32_t k : *c.marked) {
      if (k >= c.points->size()) continue;
      marked_map.push_back(c.T_map * (*c.points)[k]);
      near_marked.AddWithNeighbours(marked_map.back());
    }
  }
  if (marked_map.empty()) return found;
  StatusOr<PointIndex> index = PointIndex::Create(std::move(marked_map));
  if (!index.ok()) return index.status();
  ParallelFor(clouds.size(), num_threads, [&](std::size_t i) {
    const MarkedCloud& c = clouds[i];
    for (std::size_t k = 0; k < c.points->size(); ++k) {
      const Eigen::Vector3d p = c.T_map * (*c.points)[k];
      if (!near_marked.Occupied(p)) continue;
      if (c.marked != nullptr && c.marked->count(static_cast<std::uint32_t>(k))) continue;
      if (index.value().CountWithin(p, radius_m, 1) > 0) {
        found[i].push_back(static_cast<std::uint32_t>(k));
      }
    }
  });
  return found;
}

}  // namespace core
}  // namespace multisession_mapper
