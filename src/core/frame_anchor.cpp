#include "multisession_mapper/core/frame_anchor.h"

#include <cmath>

#include "multisession_mapper/core/se3.h"
#include "multisession_mapper/core/voxel_downsample.h"

namespace multisession_mapper {
namespace core {

FrameAnchorConfig::FrameAnchorConfig() {
  // One scan against a map: the scan is sparse, so the source keeps a finer voxel than a
  // submap's, and a point overlaps within half a metre (the reference is downsampled).
  registration.source_voxel_m = 0.3;
  registration.correspondence_schedule_m = {1.0, 0.5, 0.25};
  registration.min_overlap_ratio = 0.3;
  registration.overlap_distance_m = 0.5;
}

Status FrameAnchorConfig::Validate() const {
  if (!std::isfinite(reference_radius_m) || reference_radius_m <= 0.0) {
    return Status::Error("frame_anchor.reference_radius_m must be > 0");
  }
  if (scans < 1) return Status::Error("frame_anchor.scans must be >= 1");
  if (!std::isfinite(max_scan_range_m) || max_scan_range_m <= 0.0) {
    return Status::Error("frame_anchor.max_scan_range_m must be > 0");
  }
  if (!std::isfinite(max_correction_m) || max_correction_m <= 0.0 ||
      !std::isfinite(max_correction_rad) || max_correction_rad <= 0.0) {
    return Status::Error("frame_anchor.max_correction_m and max_correction_rad must be > 0");
  }
  if (!std::isfinite(min_correction_rad) || min_correction_rad < 0.0 ||
      min_correction_rad >= max_correction_rad) {
    return Status::Error("frame_anchor.min_correction_rad must be in [0, max_correction_rad)");
  }
  return registration.Validate();
}

FrameAnchorResult EstimateFirstScanPose(
    const PointVector& first_scan,
    const std::vector<Submap, Eigen::aligned_allocator<Submap>>& submaps,
    std::uint32_t first_submap, const FrameAnchorConfig& config) {
  FrameAnchorResult result;
  result.first_submap = first_submap;
  const Submap* home = nullptr;
  for (const Submap& s : submaps) {
    if (s.id == first_submap) home = &s;
  }
  if (home == nullptr || home->scans.empty()) {
    result.reason = "no first submap";
    return result;
  }
  const Pose3 prior = home->T_map_submap * home->scans.front().T_submap_sensor;
  PointVector reference;
  for (const Submap& s : submaps) {
    if (s.id == first_submap || s.points.empty()) continue;
    if ((s.T_map_submap.translation() - prior.translation()).norm() > config.reference_radius_m) {
      continue;
    }
    ++result.reference_submaps;
    for (const Eigen::Vector3d& p : s.points) reference.push_back(s.T_map_submap * p);
  }
  if (reference.empty()) {
    result.reason = "no other submap within " + std::to_string(config.reference_radius_m) + " m";
    return result;
  }
  PointVector scan;
  const double max_sq = config.max_scan_range_m * config.max_scan_range_m;
  for (const Eigen::Vector3d& p : first_scan) {
    if (p.allFinite() && p.squaredNorm() <= max_sq) scan.push_back(p);
  }
  StatusOr<SubmapTarget> target = SubmapTarget::Create(reference, config.registration);
  StatusOr<SubmapRegistration> registration = SubmapRegistration::Create(config.registration);
  if (!target.ok() || !registration.ok() || scan.empty()) {
    result.reason = !target.ok()         ? target.status().message()
                    : !registration.ok() ? registration.status().message()
                                         : "first scan has no point in range";
    return result;
  }
  const SubmapRegistrationResult r = registration.value().Register(scan, target.value(), prior);
  result.T_session_scan = r.T_target_source;
  result.overlap_ratio = r.overlap_ratio;
  result.correction_m = r.correction_m;
  result.correction_rad = r.correction_rad;
  if (!r.accepted) {
    result.reason = "registration: " + r.reason;
  } else if (r.correction_rad < config.min_correction_rad) {
    result.reason = "correction " + std::to_string(r.correction_rad) +
                    " rad within the registration's error (min_correction_rad)";
  } else if (r.correction_m > config.max_correction_m ||
             r.correction_rad > config.max_correction_rad) {
    result.reason = "correction " + std::to_string(r.correction_m) + " m / " +
                    std::to_string(r.correction_rad) + " rad beyond the bounds";
  } else {
    result.accepted = true;
  }
  return result;
}

void Reanchor(const Pose3& T_session_scan, std::uint32_t first_submap, PoseGraph* graph,
              std::vector<Submap, Eigen::aligned_allocator<Submap>>* submaps) {
  const Pose3 T_new_old = T_session_scan.inverse();
  for (Submap& s : *submaps) {
    if (graph->HasNode(s.id)) graph->SetNodePose(s.id, T_new_old * graph->NodePose(s.id));
    s.T_map_submap = T_new_old * s.T_map_submap;
    if (s.id == first_submap && !s.scans.empty()) {
      // The first scan is the identity of the new frame: its pose in its submap's frame.
      s.scans.front().T_submap_sensor = s.T_map_submap.inverse();
    }
  }
  graph->SetUp(T_new_old.linear() * graph->up());
}

}  // namespace core
}  // namespace multisession_mapper
