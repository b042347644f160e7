#include "multisession_mapper/core/submap_registration.h"

#include <cmath>

#include "multisession_mapper/core/se3.h"
#include "multisession_mapper/core/voxel_downsample.h"

namespace multisession_mapper {
namespace core {

SubmapRegistrationConfig::SubmapRegistrationConfig() {
  icp.reassociate_translation_m = 0.02;
  icp.reassociate_rotation_rad = 0.002;
}

Status SubmapRegistrationConfig::Validate() const {
  if (!(source_voxel_m > 0.0) || !(target_voxel_m > 0.0)) {
    return Status::Error("submap_registration voxel sizes must be > 0");
  }
  if (correspondence_schedule_m.empty()) {
    return Status::Error("submap_registration.correspondence_schedule_m must not be empty");
  }
  for (double d : correspondence_schedule_m) {
    if (!(d > 0.0)) return Status::Error("submap_registration correspondence distances must be > 0");
  }
  if (!(overlap_distance_m > 0.0)) return Status::Error("submap_registration.overlap_distance_m must be > 0");
  if (!(min_overlap_ratio >= 0.0 && min_overlap_ratio <= 1.0)) {
    return Status::Error("submap_registration.min_overlap_ratio must be in [0, 1]");
  }
  if (!(max_correction_m > 0.0) || !(max_correction_rad > 0.0)) {
    return Status::Error("submap_registration max corrections must be > 0");
  }
  if (!(loop_sigma_translation_m > 0.0) || !(loop_sigma_rotation_rad > 0.0)) {
    return Status::Error("submap_registration loop sigmas must be > 0");
  }
  Status s = icp.Validate();
  if (!s.ok()) return s;
  return target.Validate();
}

StatusOr<SubmapTarget> SubmapTarget::Create(const PointVector& points,
                                            const SubmapRegistrationConfig& config) {
  StatusOr<KdTreeTarget> tree =
      KdTreeTarget::Create(VoxelDownsampleCentred(points, config.target_voxel_m), config.target);
  if (!tree.ok()) return tree.status();
  return SubmapTarget(std::make_shared<KdTreeTarget>(std::move(tree.value())),
                      config.target_voxel_m, config.target);
}

bool SubmapTarget::BuiltLike(const SubmapRegistrationConfig& config) const {
  const KdTreeTargetConfig& t = config.target;
  return voxel_m_ == config.target_voxel_m && built_.normal_neighbors == t.normal_neighbors &&
         built_.max_normal_radius_m == t.max_normal_radius_m &&
         built_.plane.min_points == t.plane.min_points &&
         built_.plane.max_flatness == t.plane.max_flatness &&
         built_.plane.min_mid_to_max == t.plane.min_mid_to_max &&
         built_.plane.min_mid_std_m == t.plane.min_mid_std_m;
}

StatusOr<SubmapRegistration> SubmapRegistration::Create(const SubmapRegistrationConfig& config) {
  Status s = config.Validate();
  if (!s.ok()) return s;
  StatusOr<IcpRegistration> icp = IcpRegistration::Create(config.icp);
  if (!icp.ok()) return icp.status();
  return SubmapRegistration(config, std::move(icp.value()));
}

double SubmapRegistration::OverlapRatio(const PointVector& source_points,
                                        const SubmapTarget& target,
                                        const Pose3& T_target_source) const {
  if (source_points.empty()) return 0.0;
  std::size_t overlapping = 0;
  for (const Eigen::Vector3d& p : source_points) {
    std::size_t index;
    double distance_sq;
    overlapping += target.tree().NearestWithin(T_target_source * p, config_.overlap_distance_m,
                                               &index, &distance_sq);
  }
  return static_cast<double>(overlapping) / source_points.size();
}

SubmapRegistrationResult SubmapRegistration::Register(const PointVector& source_points,
                                                      const SubmapTarget& target,
                                                      const Pose3& prior) const {
  SubmapRegistrationResult result;
  const PointVector source = VoxelDownsampleCentred(source_points, config_.source_voxel_m);
  Pose3 estimate = prior;
  // Each distance's first search starts from the last one's matches (same results).
  IcpSearchMemory memory;
  for (double distance : config_.correspondence_schedule_m) {
    StatusOr<IcpResult> icp = icp_.Register(source, target.tree(), estimate, distance,
                                            std::min(config_.icp.kernel_scale_m, distance / 3.0),
                                            &memory);
    if (!icp.ok()) {
      result.reason = "icp failed: " + icp.status().message();
      return result;
    }
    estimate = icp.value().pose;
    result.icp = icp.value();
  }
  result.T_target_source = estimate;
  const Pose3 correction = se3::Between(prior, estimate);
  result.correction_m = se3::TranslationNorm(correction);
  result.correction_rad = se3::RotationAngleRad(correction);
  result.overlap_ratio = OverlapRatio(source_points, target, estimate);
  result.information.setZero();
  result.information.diagonal() << Eigen::Vector3d::Constant(
      1.0 / (config_.loop_sigma_translation_m * config_.loop_sigma_translation_m)),
      Eigen::Vector3d::Constant(
          1.0 / (config_.loop_sigma_rotation_rad * config_.loop_sigma_rotation_rad));
  if (result.correction_m > config_.max_correction_m ||
      result.correction_rad > config_.max_correction_rad) {
    result.reason = "disagrees with the prior (" + std::to_string(result.correction_m) + " m, " +
                    std::to_string(result.correction_rad) + " rad)";
    return result;
  }
  if (result.overlap_ratio < config_.min_overlap_ratio) {
    result.reason = "overlap " + std::to_string(result.overlap_ratio) + " below " +
                    std::to_string(config_.min_overlap_ratio);
    return result;
  }
  result.accepted = true;
  return result;
}

}  // namespace core
}  // namespace multisession_mapper
