// Registration of one submap against another from a prior relative pose, with the validation
// of the reference paper (section IV): the result must agree with the prior within bounds and
// the overlap ratio after alignment (fraction of source points with a target point within
// `overlap_distance_m`) must be high enough. Used for intra-session loops, for the second,
// proximity-based inter-session search, and as the fine stage after global registration.
#pragma once

#include <memory>
#include <string>

#include "multisession_mapper/core/icp_registration.h"
#include "multisession_mapper/core/kdtree_target.h"
#include "multisession_mapper/core/pose_graph.h"
#include "multisession_mapper/core/status.h"
#include "multisession_mapper/core/types.h"

namespace multisession_mapper {
namespace core {

struct SubmapRegistrationConfig {
  SubmapRegistrationConfig();

  /// Source points are downsampled to this voxel before ICP [m].
  double source_voxel_m = 0.5;
  /// Target points are downsampled to this voxel before building the kd-tree [m]; normals
  /// need neighbourhoods that span several rings.
  double target_voxel_m = 0.3;
  /// Coarse-to-fine correspondence distances [m]: ICP runs once per entry.
  std::vector<double> correspondence_schedule_m = {2.0, 1.0, 0.5};
  /// Re-associates only after 2 cm / 0.002 rad of motion (set in the constructor): on a
  /// campus s00 map, global_registration_benchmark (20 overlapping + 20 mirrored pairs, same
  /// run) took 41 s instead of 51 s, median 0.96 instead of 1.08 s per pair, with the same
  /// errors on every pair.
  IcpConfig icp;
  KdTreeTargetConfig target;
  /// A source point overlaps when a target point lies within this distance [m].
  double overlap_distance_m = 0.4;
  /// Accept only with at least this overlap ratio, in [0, 1].
  double min_overlap_ratio = 0.4;
  /// Accept only when the result moves the prior by less than these [m], [rad].
  double max_correction_m = 3.0;
  double max_correction_rad = 0.2;
  /// Standard deviations for the information matrix of an accepted loop [m], [rad].
  double loop_sigma_translation_m = 0.1;
  double loop_sigma_rotation_rad = 0.01;

  Status Validate() const;
};

struct SubmapRegistrationResult {
  bool accepted = false;
  std::string reason;                     ///< why it was rejected (empty when accepted)
  Pose3 T_target_source = Pose3::Identity();
  double overlap_ratio = 0.0;
  double correction_m = 0.0;              ///< translation between prior and result [m]
  double correction_rad = 0.0;
  IcpResult icp;
  Information6 information = Information6::Identity();

  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

/// A submap prepared as a registration target (downsampled, kd-tree, normals); build once,
/// register many sources against it.
class SubmapTarget {
 public:
  static StatusOr<SubmapTarget> Create(const PointVector& points,
                                       const SubmapRegistrationConfig& config);
  const KdTreeTarget& tree() const { return *tree_; }
  /// Create() of the same points with `config` would build this very target (same target
  /// voxel and normal settings): a target built by one stage can serve another.
  bool BuiltLike(const SubmapRegistrationConfig& config) const;

 private:
  SubmapTarget(std::shared_ptr<KdTreeTarget> tree, double voxel_m, const KdTreeTargetConfig& built)
      : tree_(std::move(tree)), voxel_m_(voxel_m), built_(built) {}
  std::shared_ptr<KdTreeTarget> tree_;
  double voxel_m_ = 0.0;
  KdTreeTargetConfig built_;
};

class SubmapRegistration {
 public:
  static StatusOr<SubmapRegistration> Create(const SubmapRegistrationConfig& config);

  /// Registers `source_points` (source submap frame) to `target` starting at `prior`
  /// (T_target_source). An ICP failure is a rejection with its reason, not an error.
  SubmapRegistrationResult Register(const PointVector& source_points, const SubmapTarget& target,
                                    const Pose3& prior) const;

  /// Fraction of `source_points` (moved by T_target_source) with a target point within the
  /// configured overlap distance.
  double OverlapRatio(const PointVector& source_points, const SubmapTarget& target,
                      const Pose3& T_target_source) const;

  const SubmapRegistrationConfig& config() const { return config_; }

 private:
  SubmapRegistration(const SubmapRegistrationConfig& config, IcpRegistration icp)
      : config_(config), icp_(std::move(icp)) {}
  SubmapRegistrationConfig config_;
  IcpRegistration icp_;
};

}  // namespace core
}  // namespace multisession_mapper
