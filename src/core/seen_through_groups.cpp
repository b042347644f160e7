#include "multisession_mapper/core/seen_through_groups.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Dense>

#include "multisession_mapper/core/local_ground.h"
#include "multisession_mapper/core/voxel_index_table.h"

namespace multisession_mapper {
namespace core {
namespace {

// Heights above the plane z = a + b x + c y fitted to the near ground voxels (see
// SeenThroughGroupsConfig::plane_min_height_m); empty without a plane.
std::vector<float> HeightsAbovePlane(const SeenThroughGroupsConfig& config,
                                     const std::vector<GroupVoxel>& voxels,
                                     const std::vector<float>& fine_heights) {
  constexpr double kOnGround = 0.05;  // [m] above the fine ground
  constexpr std::size_t kMinPoints = 50;
  constexpr double kMinSpreadSq = 1.0;  // [m^2]: ground at least 1 m wide (std) both ways
  std::vector<std::uint32_t> ground;
  if (config.plane_min_height_m <= 0.0) return {};
  for (std::size_t i = 0; i < voxels.size(); ++i) {
    if (fine_heights[i] < kOnGround && voxels[i].nearest_range_m <= config.plane_fit_max_range_m) {
      ground.push_back(static_cast<std::uint32_t>(i));
    }
  }
  Eigen::Vector3d coef = Eigen::Vector3d::Zero();
  const auto above_plane = [&coef](const Eigen::Vector3d& p) {
    return p.z() - Eigen::Vector3d(1.0, p.x(), p.y()).dot(coef);
  };
  std::vector<double> residuals;
  double bound = std::numeric_limits<double>::infinity();
  for (int round = 0; round < 4; ++round) {  // the fit, then three trimmed fits
    Eigen::Matrix3d normal = Eigen::Matrix3d::Zero();
    Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
    std::size_t used = 0;
    for (const std::uint32_t i : ground) {
      const Eigen::Vector3d& p = voxels[i].point_up;
      if (std::abs(above_plane(p)) > bound) continue;
      const Eigen::Vector3d row(1.0, p.x(), p.y());
      normal += row * row.transpose();
      rhs += row * p.z();
      ++used;
    }
    if (used < kMinPoints) return {};
    // Ground along a line (a narrow strip) leaves the plane's tilt across it undetermined.
    const double n = normal(0, 0);
    const Eigen::Vector2d mean = normal.block<2, 1>(1, 0) / n;
    const Eigen::Matrix2d spread = normal.block<2, 2>(1, 1) / n - mean * mean.transpose();
    if (Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(spread).eigenvalues()(0) <
        kMinSpreadSq) {
      return {};
    }
    coef = normal.ldlt().solve(rhs);
    residuals.clear();
    for (const std::uint32_t i : ground) {
      residuals.push_back(std::abs(above_plane(voxels[i].point_up)));
    }
    std::nth_element(residuals.begin(), residuals.begin() + residuals.size() / 2,
                     residuals.end());
    bound = std::max(0.3, 2.5 * residuals[residuals.size() / 2]);
  }
  if (!coef.allFinite()) return {};
  std::vector<float> heights(voxels.size());
  for (std::size_t i = 0; i < voxels.size(); ++i) {
    heights[i] = static_cast<float>(above_plane(voxels[i].point_up));
  }
  return heights;
}

}  // namespace

Status SeenThroughGroupsConfig::Validate() const {
  if (!(min_seen_through_ratio >= 0.0 && min_seen_through_ratio < 1.0)) {
    return Status::Error("in_session_dynamics.group_min_seen_through_ratio must be in [0, 1)");
  }
  if (!(min_seen_voxel_fraction >= 0.0 && min_seen_voxel_fraction <= 1.0)) {
    return Status::Error("in_session_dynamics.group_min_seen_voxel_fraction must be in [0, 1]");
  }
  if (min_voxels < 1) return Status::Error("in_session_dynamics.group_min_voxels must be >= 1");
  if (!std::isfinite(min_height_m)) {
    return Status::Error("in_session_dynamics.group_min_height_m must be finite");
  }
  if (!(ground_cell_m > 0.0) || !std::isfinite(ground_cell_m)) {
    return Status::Error("in_session_dynamics.group_ground_cell_m must be > 0");
  }
  if (!(coarse_ground_cell_m > 0.0) || !std::isfinite(coarse_ground_cell_m)) {
    return Status::Error("in_session_dynamics.group_coarse_ground_cell_m must be > 0");
  }
  if (!(min_nearest_range_m >= 0.0) || !std::isfinite(min_nearest_range_m)) {
    return Status::Error("in_session_dynamics.group_min_nearest_range_m must be >= 0");
  }
  if (!(plane_min_height_m >= 0.0) || !std::isfinite(plane_min_height_m)) {
    return Status::Error("in_session_dynamics.group_plane_min_height_m must be >= 0 (0: off)");
  }
  if (!(plane_fit_max_range_m > 0.0) || !std::isfinite(plane_fit_max_range_m)) {
    return Status::Error("in_session_dynamics.group_plane_fit_max_range_m must be > 0");
  }
  if (!std::isfinite(coarse_min_height_m)) {
    return Status::Error("in_session_dynamics.group_coarse_min_height_m must be finite");
  }
  return Status::Ok();
}

std::vector<std::uint32_t> SeenThroughGroups(const SeenThroughGroupsConfig& config,
                                             const std::vector<GroupVoxel>& voxels) {
  std::vector<std::uint32_t> drop;
  if (config.min_seen_through_ratio <= 0.0 || voxels.empty()) return drop;
  // Only voxels measured from min_nearest_range_m or farther may join groups; the ground is
  // that of every voxel (the ground measured near the route is the coarse ground of far ones).
  std::size_t far = 0;
  for (const GroupVoxel& v : voxels) far += v.nearest_range_m >= config.min_nearest_range_m;
  if (far == 0) return drop;
  PointVector points;
  points.reserve(voxels.size());
  for (const GroupVoxel& v : voxels) points.push_back(v.point_up);
  const std::vector<float> heights = HeightsAboveLocalGround(points, config.ground_cell_m);
  const std::vector<float> coarse = HeightsAboveLocalGround(points, config.coarse_ground_cell_m);
  const std::vector<float> plane = HeightsAbovePlane(config, voxels, heights);
  const auto may_join = [&](std::size_t i) {
    return voxels[i].nearest_range_m >= config.min_nearest_range_m &&
           (heights[i] > config.min_height_m || coarse[i] > config.coarse_min_height_m ||
            (!plane.empty() && plane[i] > config.plane_min_height_m));
  };

  // The voxels that may form groups, by key (open addressing, as the submap's own voxel index;
  // an std::unordered_map timed the same on the whole session).
  VoxelIndexTable member;
  member.Reserve(far);
  std::vector<std::uint8_t> candidate(voxels.size(), 0);
  for (std::size_t i = 0; i < voxels.size(); ++i) {
    if (!may_join(i)) continue;
    candidate[i] = 1;
    member.FindOrInsert(voxels[i].key, static_cast<std::uint32_t>(i));
  }
  // Connected groups (26-neighbourhood), breadth first; `candidate` is cleared when taken.
  std::vector<std::uint32_t> group;
  for (std::size_t seed = 0; seed < voxels.size(); ++seed) {
    if (!candidate[seed]) continue;
    candidate[seed] = 0;
    group.assign(1, static_cast<std::uint32_t>(seed));
    for (std::size_t next = 0; next < group.size(); ++next) {
      const VoxelKey& key = voxels[group[next]].key;
      for (int dx = -1; dx <= 1; ++dx) {
        for (int dy = -1; dy <= 1; ++dy) {
          for (int dz = -1; dz <= 1; ++dz) {
            const std::uint32_t j =
                member.Find(VoxelKey(key.x() + dx, key.y() + dy, key.z() + dz));
            if (j == VoxelIndexTable::kEmpty || !candidate[j]) continue;
            candidate[j] = 0;
            group.push_back(j);
          }
        }
      }
    }
    if (static_cast<int>(group.size()) < config.min_voxels) continue;
    double seen_through = 0.0;
    double consistent = 0.0;
    std::size_t seen_voxels = 0;
    for (const std::uint32_t i : group) {
      seen_through += voxels[i].seen_through;
      consistent += voxels[i].consistent;
      seen_voxels += voxels[i].seen_through > 0;
    }
    if (seen_through > 0.0 &&
        seen_through >= config.min_seen_through_ratio * (seen_through + consistent) &&
        static_cast<double>(seen_voxels) >=
            config.min_seen_voxel_fraction * static_cast<double>(group.size())) {
      drop.insert(drop.end(), group.begin(), group.end());
    }
  }
  std::sort(drop.begin(), drop.end());
  return drop;
}

}  // namespace core
}  // namespace multisession_mapper
