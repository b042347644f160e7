// A submap: scans of one session accumulated over at most ~20 m / 0.7 rad (reference paper,
// section IV), stored in its own frame with the poses of its scans' sensor origins (needed to
// ray-cast free space when detecting dynamics between sessions).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "multisession_mapper/core/types.h"

namespace multisession_mapper {
namespace core {

struct SubmapScanRecord {
  double stamp_s = 0.0;
  Pose3 T_submap_sensor = Pose3::Identity();  ///< sensor origin of the scan, submap frame

  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

enum class SubmapState {
  kActive,  ///< part of the map
  kFused,   ///< replaced by an overlapping submap of a later session; kept for the record
};

struct Submap {
  std::string session;
  std::uint32_t id = 0;
  Pose3 T_map_submap = Pose3::Identity();  ///< origin: sensor pose of the first scan, map frame
  std::vector<SubmapScanRecord, Eigen::aligned_allocator<SubmapScanRecord>> scans;
  PointVector points;  ///< downsampled, dynamic-filtered points in the submap frame [m]
  SubmapState state = SubmapState::kActive;
  double length_m = 0.0;  ///< distance driven while the submap was built [m]
  /// The odometry jump [m] at which the submap started (SubmapBuilderConfig::break_on_jump_m),
  /// 0 when it started normally. Only while the session is built: the weak odometry edge to the
  /// previous submap (SessionMapper) is what the map keeps of it.
  double started_at_jump_m = 0.0;

  double first_stamp_s() const { return scans.empty() ? 0.0 : scans.front().stamp_s; }
  double last_stamp_s() const { return scans.empty() ? 0.0 : scans.back().stamp_s; }

  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

const char* SubmapStateName(SubmapState state);

/// Appends the sensor pose of every scan of `submap` (T_map_submap * T_submap_sensor).
void AppendScanPoses(const Submap& submap, Trajectory* out);
/// Sorts by stamp and keeps one pose per stamp (a scan can belong to two overlapping submaps).
void SortTrajectory(Trajectory* trajectory);
/// The scan poses of all `submaps`, sorted by stamp, one per stamp (the two calls above).
Trajectory ScanTrajectory(const std::vector<Submap, Eigen::aligned_allocator<Submap>>& submaps);

}  // namespace core
}  // namespace multisession_mapper
