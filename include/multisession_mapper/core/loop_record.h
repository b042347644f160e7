// One loop candidate and its fate, as written to loops/<session>.csv (docs/map_format.md) and
// published as LoopCandidate messages.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "multisession_mapper/core/types.h"

namespace multisession_mapper {
namespace core {

enum class LoopKind { kIntra, kInter, kInterProximity, kInterSequence };
enum class LoopStatus { kCandidate, kAccepted, kRejected, kUndefined };

struct LoopRecord {
  LoopKind kind = LoopKind::kIntra;
  std::string current_session;
  std::uint32_t current_submap = 0;
  std::string history_session;  ///< empty for kUndefined
  std::int64_t history_submap = -1;
  LoopStatus status = LoopStatus::kCandidate;
  double vote_proportion = 0.0;
  double overlap_ratio = 0.0;
  /// Overlap of the source's structure points (walls, trunks, poles) after a registration
  /// without initial guess (GlobalRegistrationResult); 0 for registrations from a prior.
  double structure_overlap_ratio = 0.0;
  bool has_pose = false;
  Pose3 T_history_current = Pose3::Identity();
  std::string reason;

  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

using LoopRecords = std::vector<LoopRecord, Eigen::aligned_allocator<LoopRecord>>;

const char* LoopKindName(LoopKind kind);
const char* LoopStatusName(LoopStatus status);

/// CSV with the header of docs/map_format.md; commas and newlines in `reason` are replaced.
std::string LoopRecordsToCsv(const LoopRecords& records);

}  // namespace core
}  // namespace multisession_mapper
