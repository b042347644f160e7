// Copies of dynamic points in other submaps (issue 7, map update). The low-dynamic detection
// examines submap pairs, and within a pair only the points near the other session's scan
// origins. A parked car is also held, sparsely, by the submaps that saw it from farther away
// and by submaps the loops did not pair; those copies would stay in the map after the car was
// found and removed in the pair. After the detections of a merge, every point of any submap
// within `radius_m` (map frame) of a point found dynamic is a copy of it.
#pragma once

#include <cstdint>
#include <set>
#include <vector>

#include "multisession_mapper/core/status.h"
#include "multisession_mapper/core/types.h"

namespace multisession_mapper {
namespace core {

/// A submap's points, their map pose and the points already found dynamic (null: none).
struct MarkedCloud {
  const PointVector* points = nullptr;
  Pose3 T_map = Pose3::Identity();
  const std::set<std::uint32_t>* marked = nullptr;
};

/// Per cloud, in index order, the points not marked yet that lie within radius_m of a marked
/// point of any cloud (one pass: copies of copies are not followed). radius_m must be > 0.
/// Runs the clouds on num_threads threads.
StatusOr<std::vector<std::vector<std::uint32_t>>> FindCopiesOfMarked(
    double radius_m, int num_threads, const std::vector<MarkedCloud>& clouds);

}  // namespace core
}  // namespace multisession_mapper
