#include "multisession_mapper/core/icp_registration.h"

#include <cmath>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Cholesky>

#include "multisession_mapper/core/se3.h"
#include "multisession_mapper/core/worker_pool.h"

namespace multisession_mapper {
namespace core {

Status IcpConfig::Validate() const {
  if (max_iterations < 1) {
    return Status::Error("icp.max_iterations must be >= 1, got " + std::to_string(max_iterations));
  }
  if (!std::isfinite(convergence_translation_m) || convergence_translation_m < 0.0 ||
      !std::isfinite(convergence_rotation_rad) || convergence_rotation_rad < 0.0) {
    return Status::Error("icp.convergence_translation_m / convergence_rotation_rad must be >= 0");
  }
  if (!std::isfinite(max_correspondence_distance_m) || max_correspondence_distance_m <= 0.0) {
    return Status::Error("icp.max_correspondence_distance_m must be > 0, got " +
                         std::to_string(max_correspondence_distance_m));
  }
  if (kernel != RobustKernel::kNone && (!std::isfinite(kernel_scale_m) || kernel_scale_m <= 0.0)) {
    return Status::Error("icp.kernel_scale_m must be > 0 with a robust kernel, got " +
                         std::to_string(kernel_scale_m));
  }
  if (!std::isfinite(reassociate_translation_m) || reassociate_translation_m < 0.0 ||
      !std::isfinite(reassociate_rotation_rad) || reassociate_rotation_rad < 0.0) {
    return Status::Error("icp.reassociate_translation_m / reassociate_rotation_rad must be >= 0");
  }
  if (search_threads < 1) {
    return Status::Error("icp.search_threads must be >= 1, got " +
                         std::to_string(search_threads));
  }
  if (min_correspondences < 6) {
    return Status::Error("icp.min_correspondences must be >= 6 (6 unknowns), got " +
                         std::to_string(min_correspondences));
  }
  return Status::Ok();
}

IcpRegistration::IcpRegistration(const IcpConfig& config)
    : config_(config),
      pool_(config.search_threads > 1 ? std::make_shared<WorkerPool>(config.search_threads)
                                      : nullptr) {}

StatusOr<IcpRegistration> IcpRegistration::Create(const IcpConfig& config) {
  const Status status = config.Validate();
  if (!status.ok()) return status;
  return IcpRegistration(config);
}

StatusOr<IcpRegistration> IcpRegistration::WithConvergence(double translation_m,
                                                          double rotation_rad,
                                                          int max_iterations) const {
  IcpConfig config = config_;
  config.convergence_translation_m = translation_m;
  config.convergence_rotation_rad = rotation_rad;
  config.max_iterations = max_iterations;
  const Status status = config.Validate();
  if (!status.ok()) return status;
  IcpRegistration copy = *this;  // shares pool_
  copy.config_ = config;
  return copy;
}

StatusOr<IcpResult> IcpRegistration::Register(const PointVector& source,
                                              const RegistrationTarget& target,
                                              const Pose3& initial_guess) const {
  return Register(source, target, initial_guess, config_.max_correspondence_distance_m,
                  config_.kernel_scale_m);
}

namespace {

// IRLS weight w(r) = rho'(r) / r for the squared residual r2.
double KernelWeight(RobustKernel kernel, double scale_sq, double r2) {
  switch (kernel) {
    case RobustKernel::kGemanMcClure: {
      const double a = scale_sq / (scale_sq + r2);
      return a * a;
    }
    case RobustKernel::kCauchy:
      return 1.0 / (1.0 + r2 / scale_sq);
    case RobustKernel::kNone:
    default:
      return 1.0;
  }
}

Eigen::Matrix3d Skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return m;
}

}  // namespace

void IcpSearchMemory::FollowSourcePoints(const std::vector<std::size_t>& next_searched) {
  if (searched == next_searched) return;
  const std::size_t n = searched.size();
  if (found.size() != n || matches.size() != n) {
    found.clear();  // not of this source's points (or never filled): a cold start
    matches.clear();
    searched = next_searched;
    return;
  }
  std::vector<std::uint8_t> next_found(next_searched.size(), 0);
  std::vector<TargetMatch> next_matches(next_searched.size());
  std::size_t old = 0;
  for (std::size_t k = 0; k < next_searched.size(); ++k) {
    while (old < n && searched[old] < next_searched[k]) ++old;
    if (old < n && searched[old] == next_searched[k]) {
      next_found[k] = found[old];
      next_matches[k] = matches[old];
    }
  }
  found = std::move(next_found);
  matches = std::move(next_matches);
  searched = next_searched;
}

StatusOr<IcpResult> IcpRegistration::Register(const PointVector& source,
                                              const RegistrationTarget& target,
                                              const Pose3& initial_guess,
                                              double max_correspondence_distance_m,
                                              double kernel_scale_m,
                                              const IcpTranslationPrior& prior) const {
  return RegisterImpl(source, nullptr, target, initial_guess, max_correspondence_distance_m,
                      kernel_scale_m, prior);
}

StatusOr<IcpResult> IcpRegistration::Register(const PointVector& source,
                                              const RegistrationTarget& target,
                                              const Pose3& initial_guess,
                                              double max_correspondence_distance_m,
                                              double kernel_scale_m,
                                              IcpSearchMemory* memory) const {
  return RegisterImpl(source, nullptr, target, initial_guess, max_correspondence_distance_m,
                      kernel_scale_m, IcpTranslationPrior(), memory);
}

StatusOr<IcpResult> IcpRegistration::Register(const PointVector& source,
                                              const PointVector& source_normals,
                                              const RegistrationTarget& target,
                                              const Pose3& initial_guess,
                                              double max_correspondence_distance_m,
                                              double kernel_scale_m,
                                              const IcpTranslationPrior& prior,
                                              IcpSearchMemory* memory) const {
  if (source_normals.size() != source.size()) {
    return Status::Error("icp: " + std::to_string(source_normals.size()) + " normals for " +
                         std::to_string(source.size()) + " source points");
  }
  return RegisterImpl(source, &source_normals, target, initial_guess,
                      max_correspondence_distance_m, kernel_scale_m, prior, memory);
}

StatusOr<IcpResult> IcpRegistration::RegisterImpl(const PointVector& source,
                                                  const PointVector* source_normals,
                                                  const RegistrationTarget& target,
                                                  const Pose3& initial_guess,
                                                  double max_correspondence_distance_m,
                                                  double kernel_scale_m,
                                                  const IcpTranslationPrior& prior,
                                                  IcpSearchMemory* memory) const {
  if (target.empty()) return Status::Error("icp: the target is empty");
  if (!(prior.weight >= 0.0) || !std::isfinite(prior.weight) || !prior.translation.allFinite()) {
    return Status::Error("icp: the translation prior needs a finite position and weight >= 0");
  }
  if (source.size() < static_cast<std::size_t>(config_.min_correspondences)) {
    return Status::Error("icp: only " + std::to_string(source.size()) +
                         " source points, need at least " +
                         std::to_string(config_.min_correspondences));
  }
  if (!se3::IsValid(initial_guess, 1e-4)) return Status::Error("icp: invalid initial guess");
  if (!(max_correspondence_distance_m > 0.0) || !std::isfinite(max_correspondence_distance_m)) {
    return Status::Error("icp: max correspondence distance must be > 0");
  }
  const double scale_sq =
      (kernel_scale_m > 0.0 && std::isfinite(kernel_scale_m)) ? kernel_scale_m * kernel_scale_m
                                                                : 1.0;
  const RobustKernel kernel = kernel_scale_m > 0.0 ? config_.kernel : RobustKernel::kNone;

  IcpResult result;
  result.num_source = source.size();
  Pose3 pose = se3::Normalized(initial_guess);
  // Pairs of the last search: index into `searched` and its target match.
  struct Pair {
    std::size_t index;
    TargetMatch match;
  };
  std::vector<Pair> pairs_found;
  pairs_found.reserve(source.size());
  PointVector moved_source;          // the searched points at the pose of a search
  // Per searched point (k of `searched`): a match in reach, and the match when found; in the
  // caller's memory when given (the previous registration's last search: a warm first search).
  IcpSearchMemory local;
  IcpSearchMemory& memo = memory != nullptr ? *memory : local;
  std::vector<std::uint8_t>& found = memo.found;
  std::vector<TargetMatch>& matches = memo.matches;
  // The points that can pair: with point-to-plane on the source's own normals and no
  // point-to-point fallback, a point without a normal never enters the least squares, so it
  // is not searched either (the same pairs in the same order, so the same poses).
  std::vector<std::size_t> searched;
  const bool normals_only = source_normals != nullptr && !config_.point_to_point_fallback;
  for (std::size_t i = 0; i < source.size(); ++i) {
    if (!normals_only || !(*source_normals)[i].isZero(0.0)) searched.push_back(i);
  }
  if (memory != nullptr) memory->FollowSourcePoints(searched);
  Pose3 searched_pose = pose;
  bool must_search = true;
  const bool every_iteration =
      config_.reassociate_translation_m == 0.0 && config_.reassociate_rotation_rad == 0.0;
  using Matrix6d = Eigen::Matrix<double, 6, 6>;
  using Vector6d = Eigen::Matrix<double, 6, 1>;
  for (int iteration = 1; iteration <= config_.max_iterations; ++iteration) {
    const Pose3 moved = se3::Between(searched_pose, pose);
    const bool search = must_search || every_iteration ||
                        se3::TranslationNorm(moved) > config_.reassociate_translation_m ||
                        se3::RotationAngleRad(moved) > config_.reassociate_rotation_rad;
    if (search) {
      moved_source.resize(searched.size());
      for (std::size_t k = 0; k < searched.size(); ++k) {
        moved_source[k] = pose * source[searched[k]];
      }
      // From the second search on (or with a memory), the last search's matches bound this
      // one (same pairs).
      target.FindMatches(moved_source, max_correspondence_distance_m,
                         result.searches > 0 || memory != nullptr, pool_.get(), &found, &matches);
      pairs_found.clear();
      for (std::size_t k = 0; k < searched.size(); ++k) {
        if (found[k] != 0) pairs_found.push_back({k, matches[k]});
      }
      searched_pose = pose;
      must_search = false;
      ++result.searches;
    }
    Matrix6d H = Matrix6d::Zero();
    Vector6d g = Vector6d::Zero();
    const std::size_t inliers = pairs_found.size();
    std::size_t pairs = 0;  // inliers that entered the least squares
    double sum_dist_sq = 0.0;
    double sum_weight = 0.0;
    // Rotation about the source origin's current position, not the target origin: far from
    // the target origin (a robot 300 m into its map) a rotation about the target origin is
    // mostly a translation, the two are coupled, and the convergence thresholds mean nothing.
    const Eigen::Vector3d center = pose.translation();
    for (Pair& pair : pairs_found) {
      TargetMatch& m = pair.match;
      // On a search iteration the pose is the searched one: its points are already moved.
      const Eigen::Vector3d p =
          search ? moved_source[pair.index] : pose * source[searched[pair.index]];
      const Eigen::Vector3d diff = p - m.point;
      sum_dist_sq += search ? m.distance_sq : diff.squaredNorm();
      if (source_normals != nullptr) {
        // The plane is the source point's own (ring-based) surface normal: target normals
        // of single-ring neighbourhoods are sampling artefacts (see the header).
        const Eigen::Vector3d& n_source = (*source_normals)[searched[pair.index]];
        m.has_normal = !n_source.isZero(0.0);
        if (m.has_normal) m.normal = pose.linear() * n_source;
      }
      if (!m.has_normal && !config_.point_to_point_fallback) continue;
      ++pairs;
      if (m.has_normal) {
        const double r = m.normal.dot(diff);
        Vector6d J;
        J.head<3>() = m.normal;
        J.tail<3>() = (p - center).cross(m.normal);
        const double w = KernelWeight(kernel, scale_sq, r * r);
        sum_weight += w;
        H.selfadjointView<Eigen::Upper>().rankUpdate(J, w);  // upper triangle only
        g.noalias() += (w * r) * J;
      } else {
        Eigen::Matrix<double, 3, 6> J;
        J.leftCols<3>().setIdentity();
        J.rightCols<3>() = -Skew(p - center);
        const double w = KernelWeight(kernel, scale_sq, diff.squaredNorm());
        sum_weight += w;
        H.noalias() += w * J.transpose() * J;
        g.noalias() += w * J.transpose() * diff;
      }
    }
    H.triangularView<Eigen::StrictlyLower>() = H.transpose().eval();  // no aliasing
    result.iterations = iteration;
    result.num_inliers = inliers;
    result.rmse_m = inliers > 0 ? std::sqrt(sum_dist_sq / static_cast<double>(inliers)) : 0.0;
    result.mean_weight = sum_weight / static_cast<double>(source.size());
    result.hessian = H;  // the pairs' information only, without the prior
    if (prior.weight > 0.0) {
      // d/d(dt) of weight * |t + dt - prior|^2 / 2 at dt = 0; the rotation about the source
      // origin leaves t where it is.
      H.topLeftCorner<3, 3>().diagonal().array() += prior.weight;
      g.head<3>() += prior.weight * (pose.translation() - prior.translation);
    }
    if (pairs < static_cast<std::size_t>(config_.min_correspondences)) {
      return Status::Error("icp: only " + std::to_string(pairs) +
                           " correspondences within " +
                           std::to_string(max_correspondence_distance_m) + " m at iteration " +
                           std::to_string(iteration));
    }
    // A tiny Levenberg term keeps degenerate directions (long corridors) from blowing up.
    const double damping = 1e-9 * H.diagonal().maxCoeff() + 1e-12;
    const Vector6d delta = -(H + damping * Matrix6d::Identity()).ldlt().solve(g);
    if (!delta.allFinite()) return Status::Error("icp: non-finite Gauss-Newton update");
    // p' = center + exp(w) (p - center) + dt: the rotation turns about the source origin and
    // leaves it where it is, the translation moves it.
    const Pose3 step = se3::Exp(delta);
    pose.linear() = step.linear() * pose.linear();
    pose.translation() += step.translation();
    if (delta.head<3>().norm() < config_.convergence_translation_m &&
        delta.tail<3>().norm() < config_.convergence_rotation_rad) {
      // Converged on fresh pairs, or on pairs searched so close to the solution (a tenth of
      // the re-association distance) that searching again would give nearly the same ones.
      const Pose3 since_search = se3::Between(searched_pose, pose);
      if (search ||
          (se3::TranslationNorm(since_search) < 0.1 * config_.reassociate_translation_m &&
           se3::RotationAngleRad(since_search) < 0.1 * config_.reassociate_rotation_rad)) {
        result.converged = true;
        break;
      }
      must_search = true;  // converged on old pairs: confirm with fresh ones
    }
  }
  result.pose = se3::Normalized(pose);
  result.fitness = static_cast<double>(result.num_inliers) / static_cast<double>(source.size());
  if (!se3::IsValid(result.pose, 1e-6)) return Status::Error("icp: invalid resulting pose");
  return result;
}

}  // namespace core
}  // namespace multisession_mapper
