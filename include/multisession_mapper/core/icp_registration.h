// Point-to-plane ICP (Chen & Medioni 1992) with a robust kernel, solved by Gauss-Newton /
// iteratively reweighted least squares on SE(3). Target normals come from the local covariance
// of the target (RegistrationTarget); where a target neighbourhood is not planar the residual
// falls back to point-to-point (Besl & McKay 1992). The robust kernel (Geman-McClure or Cauchy)
// is scaled per call so the odometry can pass KISS-ICP's adaptive threshold (Vizzo et al.
// 2023); the same class aligns submaps (KdTreeTarget) for loop closure and global
// registration.
//
// Own vs PCL, by measurement (`odometry_benchmark`, Release, shared 2-core machine, from
// identity, target 0.2 m / source 0.5 m voxels, median of 5):
//   real fast_gicp pair: own 43 ms (kd-tree + normals included), 2.8 cm / 0.39 deg from
//     relative.txt; pcl::IterativeClosestPoint 124 ms, 4.7 cm / 0.28 deg;
//     pcl::GeneralizedIterativeClosestPoint 104 ms, 1.7 cm / 0.64 deg.
//   synthetic single-scan pair: own 42 ms, 2.2 cm / 0.32 deg; PCL ICP 191 ms, 19 cm / 0.33 deg;
//     PCL GICP 117 ms, 0.8 cm / 0.25 deg.
// The own one is used: 2.5-4x faster, as accurate as PCL GICP within its spread, and it runs
// against the odometry's voxel map (PCL's would need a kd-tree rebuilt every scan). On a
// single sparse scan as target every method is biased by a few tenths of a degree (ring
// structure); against a merged local map the synthetic test recovers 2 cm / 0.1 deg.
//
// Update: delta = (dt, w) in target axes about the source origin c = T.translation(): the
// rotation exp(w) turns about c, then c moves by dt (R <- exp(w) R, t <- t + dt). Residual
// Jacobian [n^T, ((p - c) x n)^T] for point-to-plane and [I, -[p - c]x] for point-to-point,
// p = T * source point. About c and not about the target origin: 300 m from the target
// origin a rotation about it is mostly a translation, the two are strongly coupled and the
// convergence thresholds lose their meaning (campus s02 seed 1, first 2200 scans: 27 % of the
// scan registrations ran into max_iterations, with 2-5 cm translation steps that were
// rotation steps of 1e-4 rad; 18 % after this change, the rest is correspondences that
// switch between iterations). Odometry ATE from the first pose, campus s00 / s01 / s02:
// 2.41 / 6.12 / 27.9 m before, 2.32 / 6.27 / 13.0 m after; small: 0.19 / 0.41 / 0.45 m before,
// 0.14 / 0.39 / 0.44 m after.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include <Eigen/Core>

#include "multisession_mapper/core/registration_target.h"
#include "multisession_mapper/core/status.h"
#include "multisession_mapper/core/types.h"

namespace multisession_mapper {
namespace core {

enum class RobustKernel { kNone, kGemanMcClure, kCauchy };

struct IcpConfig {
  /// Gauss-Newton iterations at most.
  int max_iterations = 30;
  /// Converged when one update moves less than both of these [m], [rad].
  double convergence_translation_m = 1e-4;
  double convergence_rotation_rad = 1e-5;
  /// Pairs farther apart than this are ignored [m]. With a VoxelHashMap target the search
  /// reach is also limited to one voxel edge.
  double max_correspondence_distance_m = 1.0;
  RobustKernel kernel = RobustKernel::kGemanMcClure;
  /// Residual scale of the kernel [m]: residuals well above it get little weight.
  double kernel_scale_m = 0.2;
  /// Pairs whose target neighbourhood is not planar: true uses them point-to-point, false
  /// skips them. Point-to-point pairs on sparse LiDAR rings pull towards the sampled rings,
  /// not the surface, which biases the result on single scans.
  bool point_to_point_fallback = false;
  /// Fewer pairs than this at any iteration is a failure.
  int min_correspondences = 30;
  /// Correspondences are searched again only when the pose moved more than this since the
  /// last search [m], [rad]; in between, Gauss-Newton iterates on the same pairs (their
  /// residuals and plane orientations follow the pose). Convergence is only declared on fresh
  /// pairs. 0 / 0: search at every iteration (classic ICP).
  double reassociate_translation_m = 0.0;
  double reassociate_rotation_rad = 0.0;
  /// Threads of each correspondence search (1: the calling thread only; more: a WorkerPool
  /// of this many, started by Create). Targets that allow it (VoxelHashMap without normals)
  /// split the search; the result is the same as with 1.
  int search_threads = 1;

  Status Validate() const;
};

/// A Gaussian prior on the translation of the result, e.g. the odometry's motion-model
/// prediction: adds weight * |t - prior.translation|^2 to the least squares (rotation free).
/// `weight` is in the Hessian's units (weighted pairs per unit residual, see IcpResult::
/// hessian): a direction that the pairs constrain with an eigenvalue well above it follows
/// the pairs, one constrained much less (a straight road between parallel walls, along the
/// road) keeps the prior's value. Degeneracy-aware estimation after Zhang, Kaess & Singh (ICRA
/// 2016), as a soft prior instead of their hard projection.
struct IcpTranslationPrior {
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();  ///< target frame [m]
  double weight = 0.0;                                    ///< 0: no prior
};

struct IcpResult {
  Pose3 pose = Pose3::Identity();  ///< T_target_source: maps source points into the target
  int iterations = 0;
  int searches = 0;                ///< correspondence searches (<= iterations)
  bool converged = false;          ///< last update under the convergence thresholds
  std::size_t num_source = 0;      ///< source points given
  /// Source points with a target point within max distance; with source normals and no
  /// point_to_point_fallback only points with a normal are searched (the others cannot pair),
  /// so only they count, here and in fitness and rmse_m.
  std::size_t num_inliers = 0;
  double fitness = 0.0;            ///< num_inliers / num_source, in [0, 1]
  double rmse_m = 0.0;             ///< RMS point-to-point distance of the inliers [m]
  /// Mean robust-kernel weight over all source points at the last iteration, in [0, 1]: the
  /// fraction of the source that fits within about the kernel's scale (0 without a kernel
  /// pair).
  double mean_weight = 0.0;
  /// Gauss-Newton Hessian J^T W J at the solution (translation first, then rotation about
  /// the source origin, see the update above), in units of 1/residual^2; scale by 1/sigma^2
  /// of the point noise for an information matrix.
  Eigen::Matrix<double, 6, 6> hessian = Eigen::Matrix<double, 6, 6>::Zero();

  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

/// The correspondences of a registration's last search, carried into the next registration
/// of the same source against the same, unchanged target (the next correspondence distance of
/// a schedule, SubmapRegistration): that registration's first search is then warm-started
/// (RegistrationTarget::FindMatches) instead of cold, with the same results. Empty: a cold
/// start. The next registration may search other points of the same source (other source
/// normals: the odometry's map-ground refinement); the entries follow their source points.
struct IcpSearchMemory {
  std::vector<std::uint8_t> found;
  std::vector<TargetMatch> matches;
  std::vector<std::size_t> searched;  ///< the source index of each entry, ascending

  /// Re-indexes the entries to the points `next_searched` (source indices, ascending): an
  /// entry follows its source point, a point not searched last time gets no hint (found 0
  /// and an empty match: a cold search, no miss memo either). Any hint is safe (a match is a
  /// target point, an upper bound on the nearest distance; a miss memo holds where it
  /// missed), so following the points is for speed: the hint is the point's own, and close.
  /// Entries that do not fit `searched` (never filled) are dropped: a cold start.
  void FollowSourcePoints(const std::vector<std::size_t>& next_searched);
};

class IcpRegistration {
 public:
  static StatusOr<IcpRegistration> Create(const IcpConfig& config);

  /// Aligns `source` (source frame) to `target` from `initial_guess` (T_target_source) with the
  /// configured distance and kernel scale. Fails (naming the reason) when the target is empty,
  /// too few pairs are found, or the solution is not finite.
  StatusOr<IcpResult> Register(const PointVector& source, const RegistrationTarget& target,
                               const Pose3& initial_guess) const;

  /// Same, with the correspondence distance and kernel scale of this call [m] (adaptive
  /// threshold).
  StatusOr<IcpResult> Register(const PointVector& source, const RegistrationTarget& target,
                               const Pose3& initial_guess, double max_correspondence_distance_m,
                               double kernel_scale_m,
                               const IcpTranslationPrior& prior = IcpTranslationPrior()) const;

  /// Same, with the searches' memory of the previous registration of this source against this
  /// target (see IcpSearchMemory); it holds this registration's last search afterwards.
  StatusOr<IcpResult> Register(const PointVector& source, const RegistrationTarget& target,
                               const Pose3& initial_guess, double max_correspondence_distance_m,
                               double kernel_scale_m, IcpSearchMemory* memory) const;

  /// Same, with a normal per source point (source frame; zero = unknown), e.g. from
  /// EstimateScanNormals: each pair's plane is the source point's normal, the target's
  /// normals are not used; a source point without a normal is used point-to-point
  /// (point_to_point_fallback) or not at all. Why: in a target sampled from few scan poses
  /// (odometry start-up, far range) a neighbourhood is often a single scan ring whose
  /// "normal" is fixed to the sensor's scan pattern; such residuals pin the estimate to the
  /// pose the target was recorded from (measured: the odometry stood still on the
  /// simulator's sessions). Normals spanning two rings of the source scan are the surface's.
  /// `memory`: the searches' memory of the previous registration of this source against this
  /// target (see IcpSearchMemory; the odometry's later registrations of one scan), or null.
  StatusOr<IcpResult> Register(const PointVector& source, const PointVector& source_normals,
                               const RegistrationTarget& target, const Pose3& initial_guess,
                               double max_correspondence_distance_m, double kernel_scale_m,
                               const IcpTranslationPrior& prior = IcpTranslationPrior(),
                               IcpSearchMemory* memory = nullptr) const;

  /// A copy that converges at steps under these [m], [rad] (>= 0) or stops after
  /// `max_iterations` (>= 1), and shares this one's search threads (the two then take turns
  /// on them): one configuration, two precisions.
  StatusOr<IcpRegistration> WithConvergence(double translation_m, double rotation_rad,
                                            int max_iterations) const;

  const IcpConfig& config() const { return config_; }

 private:
  explicit IcpRegistration(const IcpConfig& config);
  StatusOr<IcpResult> RegisterImpl(const PointVector& source, const PointVector* source_normals,
                                   const RegistrationTarget& target, const Pose3& initial_guess,
                                   double max_correspondence_distance_m,
                                   double kernel_scale_m, const IcpTranslationPrior& prior,
                                   IcpSearchMemory* memory = nullptr) const;
  IcpConfig config_;
  /// The search threads (null with search_threads 1); copies share it, and their
  /// registrations then take turns on it.
  std::shared_ptr<WorkerPool> pool_;
};

}  // namespace core
}  // namespace multisession_mapper
