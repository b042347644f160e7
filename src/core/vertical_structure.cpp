#include "multisession_mapper/core/vertical_structure.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Eigenvalues>

#include "multisession_mapper/core/point_index.h"
#include "multisession_mapper/core/voxel_downsample.h"
#include "multisession_mapper/core/worker_pool.h"

namespace multisession_mapper {
namespace core {
namespace {

// Up = the direction least seen by the normals: eigenvector of the smallest eigenvalue of
// sum n n^T, signed to point along the frame's z.
Eigen::Vector3d LeastSeenDirection(const Eigen::Matrix3d& scatter) {
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(scatter);
  Eigen::Vector3d up = solver.eigenvectors().col(0).normalized();
  return up.z() < 0.0 ? Eigen::Vector3d(-up) : up;
}

// Sum of n n^T over the normals within max_cos of perpendicular to `up`, and their number.
struct Scatter {
  Eigen::Matrix3d matrix = Eigen::Matrix3d::Zero();
  int count = 0;
};

Scatter WallScatter(const PointVector& normals, const Eigen::Vector3d& up, double max_cos) {
  Scatter scatter;
  for (const Eigen::Vector3d& n : normals) {
    if (std::abs(n.dot(up)) > max_cos) continue;
    scatter.matrix.noalias() += n * n.transpose();
    ++scatter.count;
  }
  return scatter;
}

}  // namespace

Status VerticalStructureConfig::Validate() const {
  Status status = plane.Validate();
  if (!status.ok()) return status;
  if (!std::isfinite(min_height_m)) {
    return Status::Error("vertical_structure.min_height_m must be finite");
  }
  if (!std::isfinite(voxel_size_m) || voxel_size_m <= 0.0) {
    return Status::Error("vertical_structure.voxel_size_m must be > 0, got " +
                         std::to_string(voxel_size_m));
  }
  if (neighbours < 3) {
    return Status::Error("vertical_structure.neighbours must be >= 3, got " +
                         std::to_string(neighbours));
  }
  if (!std::isfinite(max_neighbour_distance_m) || max_neighbour_distance_m <= 0.0) {
    return Status::Error("vertical_structure.max_neighbour_distance_m must be > 0");
  }
  if (!(max_wall_tilt_rad > 0.0 && max_wall_tilt_rad < M_PI / 2) ||
      !(inlier_tilt_rad > 0.0 && inlier_tilt_rad < M_PI / 2)) {
    return Status::Error(
        "vertical_structure.max_wall_tilt_rad / inlier_tilt_rad must be in (0, pi/2)");
  }
  if (min_wall_points < 3) {
    return Status::Error("vertical_structure.min_wall_points must be >= 3, got " +
                         std::to_string(min_wall_points));
  }
  if (threads < 1 || threads > 64) {
    return Status::Error("vertical_structure.threads must be in [1, 64], got " +
                         std::to_string(threads));
  }
  if (!std::isfinite(sigma_rad) || sigma_rad <= 0.0) {
    return Status::Error("vertical_structure.sigma_rad must be > 0, got " +
                         std::to_string(sigma_rad));
  }
  return Status::Ok();
}

VerticalEvidence EstimateVerticalEvidence(const PointVector& points,
                                          const VerticalStructureConfig& config) {
  VerticalEvidence evidence;
  if (!config.enabled || points.size() < 3) return evidence;
  PointVector high;
  for (const Eigen::Vector3d& p : points) {
    if (p.z() > config.min_height_m) high.push_back(p);
  }
  StatusOr<PointIndex> index =
      PointIndex::Create(VoxelDownsampleCentred(high, config.voxel_size_m));
  if (!index.ok()) return evidence;  // (the sampling leaves out non-finite points; a guard)
  const PointVector& thinned = index.value().points();

  // Normals of planar patches that are roughly vertical in the submap frame, computed in
  // blocks on the threads and gathered in point order (the scatter sums below depend on it).
  const double candidate_cos = std::sin(config.max_wall_tilt_rad);
  PointVector normals(thinned.size());
  std::vector<std::uint8_t> is_wall(thinned.size(), 0);
  constexpr std::size_t kBlock = 512;
  const auto estimate = [&](std::size_t begin, std::size_t end) {
    std::vector<std::uint32_t> neighbours;
    for (std::size_t k = begin; k < end; ++k) {
      const Eigen::Vector3d& p = thinned[k];
      index.value().Nearest(p, static_cast<std::size_t>(config.neighbours),
                            config.max_neighbour_distance_m, &neighbours);
      CovarianceAccumulator accumulator;
      for (std::uint32_t i : neighbours) accumulator.Add(thinned[i] - p);  // centred: precise
      if (!accumulator.Normal(config.plane, &normals[k])) continue;
      is_wall[k] = std::abs(normals[k].z()) <= candidate_cos ? 1 : 0;
    }
  };
  std::unique_ptr<WorkerPool> pool;  // a thread start per submap: negligible
  if (config.threads > 1 && thinned.size() > kBlock) {
    pool = std::make_unique<WorkerPool>(config.threads);
  }
  WorkerPool::RunBlocks(pool.get(), 0, thinned.size(), kBlock, estimate);
  PointVector walls;
  for (std::size_t k = 0; k < thinned.size(); ++k) {
    if (is_wall[k] != 0) walls.push_back(normals[k]);
  }
  if (static_cast<int>(walls.size()) < config.min_wall_points) return evidence;

  // Estimate, drop the walls that are not vertical by that estimate, estimate again (twice).
  const double inlier_cos = std::sin(config.inlier_tilt_rad);
  Eigen::Vector3d up =
      LeastSeenDirection(WallScatter(walls, Eigen::Vector3d::UnitZ(), candidate_cos).matrix);
  for (int round = 0; round < 2; ++round) {
    up = LeastSeenDirection(WallScatter(walls, up, inlier_cos).matrix);
  }
  const Scatter inliers = WallScatter(walls, up, inlier_cos);
  evidence.wall_points = inliers.count;
  if (inliers.count < config.min_wall_points) return evidence;

  // Information: the scatter's eigen-structure, scaled so that its largest eigenvalue is
  // 1 / sigma^2. The eigenvalue along up itself (~0) is dropped so that it carries nothing.
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(inliers.matrix);
  const Eigen::Vector3d values = solver.eigenvalues();  // ascending
  if (!(values(2) > 0.0)) return evidence;
  const double scale = 1.0 / (config.sigma_rad * config.sigma_rad * values(2));
  Eigen::Matrix3d information = Eigen::Matrix3d::Zero();
  for (int k = 1; k < 3; ++k) {
    const Eigen::Vector3d v = solver.eigenvectors().col(k);
    information.noalias() += scale * values(k) * v * v.transpose();
  }
  evidence.valid = information.allFinite();
  if (!evidence.valid) return evidence;
  evidence.up = LeastSeenDirection(inliers.matrix);
  evidence.information = information;
  evidence.conditioning = values(1) / values(2);
  return evidence;
}

}  // namespace core
}  // namespace multisession_mapper
