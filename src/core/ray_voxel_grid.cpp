#include "multisession_mapper/core/ray_voxel_grid.h"

#include <cmath>
#include <string>

namespace multisession_mapper {
namespace core {

StatusOr<RayVoxelGrid> RayVoxelGrid::Create(double voxel_size_m,
                                            const Eigen::Vector3d& min_corner,
                                            const Eigen::Vector3d& max_corner) {
  if (!std::isfinite(voxel_size_m) || voxel_size_m <= 0.0) {
    return Status::Error("ray_voxel_grid: voxel size must be > 0, got " +
                         std::to_string(voxel_size_m));
  }
  if (!min_corner.allFinite() || !max_corner.allFinite() ||
      (max_corner.array() < min_corner.array()).any()) {
    return Status::Error("ray_voxel_grid: empty or non-finite box");
  }
  RayVoxelGrid grid;
  grid.voxel_size_m_ = voxel_size_m;
  grid.inv_voxel_size_ = 1.0 / voxel_size_m;
  grid.origin_ = min_corner;
  double blocks = 1.0;
  for (int i = 0; i < 3; ++i) {
    const double voxels = std::floor((max_corner[i] - min_corner[i]) / voxel_size_m) + 1.0;
    const double block_count = std::ceil(voxels / kBlockEdge);
    blocks *= block_count;
    if (voxels > (1 << 30) || blocks > 2147483647.0) {
      return Status::Error("ray_voxel_grid: box too large for the voxel size");
    }
    grid.block_dims_[i] = static_cast<int>(block_count);
    grid.dims_[i] = grid.block_dims_[i] * kBlockEdge;
  }
  grid.block_index_.assign(static_cast<std::size_t>(blocks), -1);
  return grid;
}

bool RayVoxelGrid::Contains(const Eigen::Vector3d& p) const { return ContainsKey(KeyOf(p)); }

Eigen::Vector3i RayVoxelGrid::KeyOf(const Eigen::Vector3d& p) const {
  const Eigen::Vector3d g = (p - origin_) * inv_voxel_size_;
  return Eigen::Vector3i(static_cast<int>(std::floor(g.x())), static_cast<int>(std::floor(g.y())),
                         static_cast<int>(std::floor(g.z())));
}

Eigen::Vector3d RayVoxelGrid::CentreOf(const Eigen::Vector3i& key) const {
  return origin_ + (key.cast<double>() + Eigen::Vector3d::Constant(0.5)) / inv_voxel_size_;
}

bool RayVoxelGrid::ContainsKey(const Eigen::Vector3i& key) const {
  return (key.array() >= 0).all() && (key.array() < dims_.array()).all();
}

RayVoxelGrid::Cell* RayVoxelGrid::Touch(const Eigen::Vector3i& key) {
  if (!ContainsKey(key)) return nullptr;
  std::int32_t& block = block_index_[static_cast<std::size_t>(BlockSlot(key))];
  if (block < 0) {
    block = static_cast<std::int32_t>(blocks_.size());
    blocks_.emplace_back();
  }
  return &blocks_[static_cast<std::size_t>(block)].cells[CellSlot(key)];
}

RayVoxelGrid::Cell* RayVoxelGrid::Find(const Eigen::Vector3i& key) {
  if (!ContainsKey(key)) return nullptr;
  const std::int32_t block = block_index_[static_cast<std::size_t>(BlockSlot(key))];
  return block < 0 ? nullptr : &blocks_[static_cast<std::size_t>(block)].cells[CellSlot(key)];
}

const RayVoxelGrid::Cell* RayVoxelGrid::Find(const Eigen::Vector3i& key) const {
  return const_cast<RayVoxelGrid*>(this)->Find(key);
}

}  // namespace core
}  // namespace multisession_mapper
