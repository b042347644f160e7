// Second judgement of the inter-session loops that were rejected only for disagreeing with the
// loop that guided or placed their registration (DependentLoop, from InterSessionMatcher).
//
// Why: the matcher judges a sequence-placed registration by the neighbour's loop that placed it.
// When that loop is wrong (campus seed 2, s02/51 -> s01/50, 1 m off), the neighbours' correct
// loops are rejected with it, and the joint pose graph, which rejects the wrong one, never sees
// them. Once the graph has rejected the reference, such a loop is judged against where the
// optimised graph puts its two submaps.
#pragma once

#include <cstddef>
#include <functional>
#include <vector>

#include "multisession_mapper/core/inter_session_matcher.h"
#include "multisession_mapper/core/loop_record.h"
#include "multisession_mapper/core/types.h"

namespace multisession_mapper {
namespace core {

struct DependentLoopBounds {
  /// A loop is accepted when it differs from the graph's placement of its two submaps by at
  /// most this [m] (translation of T_placed^-1 * T_loop) ...
  double max_translation_m = 0.5;
  /// ... and this [rad]. SessionMerger takes both from the sequence-consistency bounds.
  double max_rotation_rad = 0.02;
};

/// T_history_current where the optimised graph puts the loop's two submaps; false when the
/// loop's submaps are not in the graph.
using GraphPlacement = std::function<bool(const InterSessionLoop& loop, Pose3* T_history_current)>;

/// For every dependent loop whose record is still rejected while its reference's record has
/// been rejected too (by the joint graph), and that belongs to another current submap than
/// its reference (placed by it through sequence guidance, not a second candidate of the same
/// submap): accepts the record when the loop agrees with `placement` within `bounds` (the
/// reason says so), otherwise appends the disagreement to the reason. A second candidate of
/// the reference's own submap stays rejected: two registrations of one submap that disagree
/// make the submap suspect (its content may hold one place twice, after a slide of its
/// odometry), whichever of the two the graph kept out. Records of loops whose reference still
/// stands are not touched. Returns the indices into `dependent` of the loops accepted, in
/// order.
std::vector<std::size_t> RejudgeDependentLoops(
    const std::vector<DependentLoop, Eigen::aligned_allocator<DependentLoop>>& dependent,
    const GraphPlacement& placement, const DependentLoopBounds& bounds, LoopRecords* records);

}  // namespace core
}  // namespace multisession_mapper
