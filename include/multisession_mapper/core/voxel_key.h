// Integer voxel coordinates and their hash, shared by the voxel structures of the core.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <unordered_map>

#include <Eigen/Core>

namespace multisession_mapper {
namespace core {

using VoxelKey = Eigen::Vector3i;

/// Voxel of edge `voxel_size_m` containing `point` (floor, so negative coordinates work).
inline VoxelKey ToVoxelKey(const Eigen::Vector3d& point, double voxel_size_m) {
  return VoxelKey(static_cast<int>(std::floor(point.x() / voxel_size_m)),
                  static_cast<int>(std::floor(point.y() / voxel_size_m)),
                  static_cast<int>(std::floor(point.z() / voxel_size_m)));
}

/// Spatial hash of Teschner et al. 2003 (large primes, xor).
struct VoxelKeyHash {
  std::size_t operator()(const VoxelKey& key) const {
    return (static_cast<std::size_t>(static_cast<std::uint32_t>(key.x())) * 73856093u) ^
           (static_cast<std::size_t>(static_cast<std::uint32_t>(key.y())) * 19349669u) ^
           (static_cast<std::size_t>(static_cast<std::uint32_t>(key.z())) * 83492791u);
  }
};

template <typename T>
using VoxelMap = std::unordered_map<VoxelKey, T, VoxelKeyHash>;

}  // namespace core
}  // namespace multisession_mapper
