#include "multisession_mapper/core/local_plane.h"

#include <cmath>
#include <string>

#include <Eigen/Eigenvalues>

namespace multisession_mapper {
namespace core {

Status LocalPlaneCriteria::Validate() const {
  if (min_points < 3) {
    return Status::Error("local_plane.min_points must be >= 3, got " +
                         std::to_string(min_points));
  }
  if (!std::isfinite(max_flatness) || max_flatness <= 0.0 || max_flatness > 1.0) {
    return Status::Error("local_plane.max_flatness must be in (0, 1], got " +
                         std::to_string(max_flatness));
  }
  if (!std::isfinite(min_mid_to_max) || min_mid_to_max < 0.0 || min_mid_to_max > 1.0) {
    return Status::Error("local_plane.min_mid_to_max must be in [0, 1], got " +
                         std::to_string(min_mid_to_max));
  }
  if (!std::isfinite(min_mid_std_m) || min_mid_std_m < 0.0) {
    return Status::Error("local_plane.min_mid_std_m must be >= 0, got " +
                         std::to_string(min_mid_std_m));
  }
  return Status::Ok();
}

bool CovarianceAccumulator::Normal(const LocalPlaneCriteria& criteria,
                                   Eigen::Vector3d* normal) const {
  if (count_ < criteria.min_points || count_ < 3) return false;
  const double inv_n = 1.0 / count_;
  const Eigen::Vector3d mean = sum_ * inv_n;
  const Eigen::Matrix3d cov = sum_outer_ * inv_n - mean * mean.transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver;
  solver.computeDirect(cov);  // closed form: ~10x faster than the iterative solver for 3x3
  const Eigen::Vector3d& ev = solver.eigenvalues();  // ascending
  if (!(ev(2) > 0.0)) return false;
  if (ev(1) < criteria.min_mid_to_max * ev(2)) return false;
  if (ev(1) < criteria.min_mid_std_m * criteria.min_mid_std_m) return false;
  if (ev(0) > criteria.max_flatness * ev(1)) return false;
  *normal = solver.eigenvectors().col(0).normalized();
  return normal->allFinite();
}

}  // namespace core
}  // namespace multisession_mapper
