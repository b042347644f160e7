// Surface normal of a small neighbourhood from its covariance (PCA: the eigenvector of the
// smallest eigenvalue), with a planarity test so that point-to-plane ICP (Chen & Medioni
// 1992) only uses planes, not edges, poles or foliage. Shared by the voxel map and the
// kd-tree registration target.
#pragma once

#include <Eigen/Core>

#include "multisession_mapper/core/status.h"

namespace multisession_mapper {
namespace core {

struct LocalPlaneCriteria {
  /// Fewer neighbours than this give no normal.
  int min_points = 5;
  /// Planar when lambda_min <= max_flatness * lambda_mid (eigenvalues of the covariance):
  /// the spread along the normal is small compared with the spread in the plane.
  double max_flatness = 0.3;
  /// Not a line: lambda_mid >= min_mid_to_max * lambda_max (a line has no defined normal).
  double min_mid_to_max = 0.02;
  /// Not a line either: the standard deviation along the second axis must reach this [m].
  /// One LiDAR ring seen on a wall is a line a few cm thick (noise); without this absolute
  /// test its noise would pass for a plane with a random normal and bias the registration.
  double min_mid_std_m = 0.08;

  Status Validate() const;
};

/// Running sums of a neighbourhood; Add() points, then Normal().
class CovarianceAccumulator {
 public:
  void Add(const Eigen::Vector3d& p) {
    ++count_;
    sum_ += p;
    sum_outer_.noalias() += p * p.transpose();
  }
  int count() const { return count_; }

  /// Unit normal when the neighbourhood passes `criteria`; false otherwise.
  bool Normal(const LocalPlaneCriteria& criteria, Eigen::Vector3d* normal) const;

 private:
  int count_ = 0;
  Eigen::Vector3d sum_ = Eigen::Vector3d::Zero();
  Eigen::Matrix3d sum_outer_ = Eigen::Matrix3d::Zero();
};

}  // namespace core
}  // namespace multisession_mapper
