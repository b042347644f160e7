// Surface normal of a small neighbourhood from its covariance (PCA: the eigenvector of the
// smallest eigenvalue), with a planarity test so that point-to-plane ICP (Chen & Medioni
// 1992) only uses planes, not edges, poles or foliage. Shared by the voxel map and the
// kd-tree registration target.
#pragma once

#include <vector>

#include <Eigen/Core>

#include "multisession_mapper/core/status.h"
#include "multisession_mapper/core/types.h"

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

/// Normals of single-scan points from the scan's own ring structure (range image of a
/// spinning LiDAR: rows = rings, columns = azimuth bins). A neighbourhood always spans the
/// point's ring and its neighbouring rings, so it samples the surface in two directions.
/// Why: in a map built from few scan poses, a neighbourhood of far points is often one ring
/// line whose second-axis spread is depth jitter (facade relief, curbs, porous foliage,
/// range noise); its "normal" is perpendicular to the ring and the beam, i.e. fixed to the
/// sensor's scan pattern, and point-to-plane residuals with it pull the pose towards the pose
/// from which the map's rings were recorded (the ring effect). Normals from two or more rings
/// are normals of the surface.
struct ScanNormalConfig {
  /// Azimuth bins of the range image (VLP-16 at 10 Hz: 1800 columns of 0.2 deg).
  int azimuth_bins = 1800;
  /// Neighbour columns taken on each side of the point, every `column_step` bins (default
  /// +-2 x 5 bins = +-2 deg, comparable to the 2 deg between VLP-16 rings).
  int column_reach = 2;
  int column_step = 5;
  /// Neighbours farther from the point than abs + rel * range are left out [m], [-]:
  /// keeps the patch on one surface while spanning the ring spacing (range * 0.035 rad).
  double max_neighbor_distance_abs_m = 1.0;
  double max_neighbor_distance_rel = 0.06;
  /// Planarity test of the patch; additionally the patch must contain >= 2 rings.
  LocalPlaneCriteria plane;

  Status Validate() const;
};

/// Unit normals for `queries` (points of `scan`, sensor frame, with their ring index), or
/// zero vectors where the patch is not planar or does not span two rings. Without ring
/// indices (has_ring false) or with fewer than 2 rings every normal is zero.
PointVector EstimateScanNormals(const LidarScan& scan, const std::vector<LidarPoint>& queries,
                                const ScanNormalConfig& config);

/// Removes, with their normals, the points higher than `min_height_m` (z, sensor frame) whose
/// normal is not near-horizontal: |normal z| > max_abs_normal_z. Points without a normal (zero
/// vector) stay; point-to-plane leaves them out anyway. `normals` has one entry per point.
/// Why: see OdometryConfig::high_point_min_height_m (porous tree crowns above the sensor).
void DropHighPointsOffWalls(double min_height_m, double max_abs_normal_z, PointVector* points,
                            PointVector* normals);

}  // namespace core
}  // namespace multisession_mapper
