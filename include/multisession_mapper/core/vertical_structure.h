// Where "up" is in a submap, from its vertical structure: building facades, walls, hedges and
// the sides of posts are vertical planes, so their normals are horizontal and the vertical is
// the direction perpendicular to all of them. LiDAR-only odometry has no gravity reference and
// its roll / pitch drift slowly (a 0.5 deg pitch error over 100 m is 0.9 m of height); a prior
// per submap on that direction, in the pose graph (PoseGraph::SetVerticalPrior), ties every
// submap's tilt to one common vertical. The ground is not used: roads and terrain slope.
//
// The evidence is an information matrix on the up direction u in the submap frame,
// I = s * sum_i n_i n_i^T over the wall normals n_i (n_i . u = 0 for a vertical wall), scaled
// so that the best-constrained tilt axis has the standard deviation `sigma_rad`. Walls that
// all face one way constrain only the tilt about their normal; the information then says so
// (the other axis gets the small eigenvalue it has), instead of inventing a vertical.
#pragma once

#include <Eigen/Core>

#include "multisession_mapper/core/local_plane.h"
#include "multisession_mapper/core/status.h"
#include "multisession_mapper/core/types.h"

namespace multisession_mapper {
namespace core {

struct VerticalStructureConfig {
  /// false: no evidence is computed and the pose graph gets no vertical priors.
  bool enabled = true;
  /// Only points higher than this above the submap's origin (the sensor) are used [m]. Below
  /// it are parked cars, vans, hedges, low walls and curbs, which stand on the sloping ground
  /// and tilt with it (on the simulated campus they bias the estimate by 1.5-2.5 deg where no
  /// facade is in view); above it are facades, tall walls, posts and trunks. Measured on the
  /// simulator's true points around the `campus` s00 submap origins: weighted error median
  /// 0.15 deg, p90 1.8 deg with every point; 0.08 / 0.15 deg with this gate at 0.5 m (33 of 58
  /// submaps keep enough walls). YAML pose_graph.vertical_min_height_m.
  double min_height_m = 0.5;
  /// The submap's points are thinned to this voxel before the normals [m]. Neighbours per
  /// normal, and their largest distance from the point [m]. 0.4 m / 20 would be 2.6x faster
  /// (68 against 178 ms per `campus` submap median on a loaded machine; the submap thread
  /// runs it once per ~12 s of data) with the same error on the true points (weighted
  /// 0.07 / 0.16 deg median / p90 against 0.08 / 0.15 deg), but through the whole 3-session
  /// pipeline it was worse on both seeds: `campus` ATE 0.41 / 0.35 / 0.87 m against
  /// 0.29 / 0.25 / 0.78 m (seed 1), 0.62 / 0.55 / 0.71 m against 0.55 / 0.53 / 0.61 m (seed 2).
  double voxel_size_m = 0.3;
  int neighbours = 30;
  double max_neighbour_distance_m = 1.5;
  /// Planarity of a wall patch (eigenvalue ratios of its covariance, see LocalPlaneCriteria).
  LocalPlaneCriteria plane{10, 0.05, 0.2, 0.1};
  /// Candidate walls: normal within this angle of the submap frame's horizontal plane [rad]
  /// (the sensor is mounted roughly level; 15 deg).
  double max_wall_tilt_rad = 0.26;
  /// After a first estimate of up, walls whose normal is more than this from horizontal are
  /// dropped and up is estimated again (sloped roofs, car bonnets, curbs on a slope) [rad].
  double inlier_tilt_rad = 0.1;
  /// Fewer wall normals than this give no evidence. YAML pose_graph.vertical_min_wall_points.
  int min_wall_points = 300;
  /// Standard deviation of the submap's tilt about its best-constrained horizontal axis [rad].
  /// On the submaps the SLAM builds of `campus` seed 2 s00 the weighted error against the true
  /// vertical is 0.14 deg median, 0.44 deg p90, larger than on the true points because the
  /// odometry's own tilt drift inside a submap blends differently tilted scans. 0.015 rad
  /// (0.86 deg; was 0.005 until session 40): since the crown filter of the odometry
  /// (OdometryConfig::high_point_min_height_m) the odometry's tilt between submaps is good to
  /// ~0.05 deg per 20 m, so priors as tight as the odometry links (0.29 deg) bent roads that
  /// the odometry had right (seed 1 s01's last 60 s: odometry +0.03 m in height, the graph
  /// -0.12 m). 3-session `campus`, map fit ATE s00 / s01 / s02 and static SA, 0.005 -> 0.015:
  /// seed 1 0.062 / 0.079 / 0.134 m, 98.26 % -> 0.067 / 0.070 / 0.131 m, 98.64 %; seed 3
  /// 0.053 / 0.084 / 0.054 m, 98.36 % -> 0.049 / 0.079 / 0.049 m, 98.91 %; seed 2 0.026 /
  /// 0.052 / 0.030 m, 98.20 % -> 0.025 / 0.028 / 0.023 m, 99.14 %.
  double sigma_rad = 0.015;
  /// Threads of the normal estimation, the calling one included (same result with 1). It
  /// runs on the submap thread when a submap is finished (~5 % of the offline runner's CPU,
  /// session 37 perf), where the odometry's core is often idle. In [1, 64]; YAML
  /// pose_graph.vertical_threads.
  int threads = 2;

  Status Validate() const;
};

struct VerticalEvidence {
  bool valid = false;  ///< false: too few wall normals (information is zero)
  int wall_points = 0;
  /// Estimated up direction, submap frame (unit; z >= 0).
  Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  /// Information on u [rad^-2], symmetric positive semi-definite; u^T I u ~ 0 for the true up.
  Eigen::Matrix3d information = Eigen::Matrix3d::Zero();
  /// Smallest / largest eigenvalue of `information` restricted to the plane perpendicular to
  /// `up` (1: walls in every direction, ~0: all walls parallel).
  double conditioning = 0.0;
};

/// Evidence from the points of a submap (submap frame: the sensor's, so roughly level). Never
/// fails on content: a submap without walls gets `valid == false`.
VerticalEvidence EstimateVerticalEvidence(const PointVector& points,
                                          const VerticalStructureConfig& config);

}  // namespace core
}  // namespace multisession_mapper
