#include "multisession_mapper/core/dependent_loops.h"

#include <string>

#include "multisession_mapper/core/se3.h"

namespace multisession_mapper {
namespace core {

std::vector<std::size_t> RejudgeDependentLoops(
    const std::vector<DependentLoop, Eigen::aligned_allocator<DependentLoop>>& dependent,
    const GraphPlacement& placement, const DependentLoopBounds& bounds, LoopRecords* records) {
  std::vector<std::size_t> accepted;
  for (std::size_t i = 0; i < dependent.size(); ++i) {
    const DependentLoop& d = dependent[i];
    if (d.record >= records->size() || d.reference_record >= records->size()) continue;
    LoopRecord& record = (*records)[d.record];
    const LoopRecord& reference = (*records)[d.reference_record];
    if (record.status != LoopStatus::kRejected || reference.status != LoopStatus::kRejected) {
      continue;
    }
    if (record.current_submap == reference.current_submap) {
      // Two registrations of one submap that disagree, one of them rejected by the graph:
      // the submap itself is suspect (campus seed 2, s02/51 holds one place twice, 1 m apart,
      // after its odometry slid), so its other loop is not taken either.
      record.reason += " (not judged again: the joint pose graph rejected the other loop of "
                       "this submap)";
      continue;
    }
    Pose3 placed = Pose3::Identity();
    if (!placement(d.loop, &placed)) continue;
    const Pose3 difference = placed.inverse() * d.loop.T_history_current;
    const double dt = se3::TranslationNorm(difference);
    const double dr = se3::RotationAngleRad(difference);
    const std::string judged = "the joint pose graph rejected the loop of submap " +
                               std::to_string(reference.current_submap) + " it disagreed with; " +
                               std::to_string(dt) + " m, " + std::to_string(dr) +
                               " rad from the graph's placement";
    if (dt > bounds.max_translation_m || dr > bounds.max_rotation_rad) {
      record.reason += " (judged again: " + judged + ")";
      continue;
    }
    record.status = LoopStatus::kAccepted;
    record.reason = "accepted when judged again: " + judged;
    accepted.push_back(i);
  }
  return accepted;
}

}  // namespace core
}  // namespace multisession_mapper
