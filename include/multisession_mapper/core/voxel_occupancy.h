// Occupied voxels of a point set, for "is there a point within about one voxel" tests (the map
// update's overlap and fusion tests, the search for copies of dynamic points). Open addressing
// (VoxelIndexTable): every point of the map goes in at each merge, and the tested points look
// up to 27 voxels each (their own first: most tested points lie in an occupied voxel). For
// few occupied points tested against many (the copies of dynamic points: every point of the
// map tested), AddWithNeighbours() stores the 27 voxels once and Occupied() is the Near() test
// in one look-up (the merge's propagation went from 27 look-ups per map point to 1).
#pragma once

#include <Eigen/Core>

#include "multisession_mapper/core/voxel_index_table.h"
#include "multisession_mapper/core/voxel_key.h"

namespace multisession_mapper {
namespace core {

class VoxelOccupancy {
 public:
  /// voxel_m must be > 0 (the callers' configs check it).
  explicit VoxelOccupancy(double voxel_m) : voxel_m_(voxel_m) {}
  void Add(const Eigen::Vector3d& p) { voxels_.FindOrInsert(ToVoxelKey(p, voxel_m_), 0); }
  /// Adds the point's voxel and its 26 neighbours: then Occupied(q) holds exactly when Near(q)
  /// would hold for a set built with Add(). Do not mix with Add() in one set.
  void AddWithNeighbours(const Eigen::Vector3d& p) {
    const VoxelKey k = ToVoxelKey(p, voxel_m_);
    for (int dx = -1; dx <= 1; ++dx) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dz = -1; dz <= 1; ++dz) {
          voxels_.FindOrInsert(VoxelKey(k.x() + dx, k.y() + dy, k.z() + dz), 0);
        }
      }
    }
  }
  /// The point's own voxel is occupied.
  bool Occupied(const Eigen::Vector3d& p) const { return Contains(ToVoxelKey(p, voxel_m_)); }
  /// The point's voxel or one of its 26 neighbours is occupied.
  bool Near(const Eigen::Vector3d& p) const {
    const VoxelKey k = ToVoxelKey(p, voxel_m_);
    if (Contains(k)) return true;
    for (int dx = -1; dx <= 1; ++dx) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dz = -1; dz <= 1; ++dz) {
          if ((dx | dy | dz) == 0) continue;
          if (Contains(VoxelKey(k.x() + dx, k.y() + dy, k.z() + dz))) return true;
        }
      }
    }
    return false;
  }

 private:
  bool Contains(const VoxelKey& key) const {
    return voxels_.Find(key) != VoxelIndexTable::kEmpty;
  }
  double voxel_m_;
  VoxelIndexTable voxels_;
};

}  // namespace core
}  // namespace multisession_mapper
