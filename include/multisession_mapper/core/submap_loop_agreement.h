// Agreement among the inter-session loops of one current submap.
//
// Why: the matcher's sequence-consistency bounds (0.5 m / 0.02 rad plus drift per metre) are
// wide because they compare loops of different submaps, with the session's odometry drift
// between them. Loops of one current submap place that submap alike up to the error of the
// history poses only, so one that lands apart from the others is a misregistration even within
// the group bounds (campus seed 3, s01/17 with the rotation window of 3: loops to s00/49 and
// s00/1 0.04 m / 0.08 deg from the truth, to s00/2 0.39 m / 0.57 deg; 0.31-0.35 m and
// 0.43-0.52 deg from the two others; correct loops of one submap differed by at most
// 0.13 m / 0.25 deg on seeds 1-3).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "multisession_mapper/core/types.h"

namespace multisession_mapper {
namespace core {

/// Where one loop puts its current submap in the map frame.
struct SubmapPlacement {
  std::uint32_t current_submap = 0;
  Pose3 T_map_current = Pose3::Identity();

  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

using SubmapPlacements = std::vector<SubmapPlacement, Eigen::aligned_allocator<SubmapPlacement>>;

/// Indices of the placements that differ from every other placement of their current submap by
/// more than `max_translation_m` [m] (between the two submap origins) or `max_rotation_rad`
/// [rad], in submaps where at least two placements agree with each other within both (a
/// majority to tell the odd one by). Submaps with fewer than three placements have none.
/// Ascending order.
std::vector<std::size_t> OddPlacementsOfOneSubmap(const SubmapPlacements& placements,
                                                  double max_translation_m,
                                                  double max_rotation_rad);

}  // namespace core
}  // namespace multisession_mapper
