// A bounded, sparsely allocated voxel grid with a few bytes per voxel (flags and two
// saturating counters) and exact voxel traversal of line segments (Amanatides & Woo 1987,
// "A Fast Voxel Traversal Algorithm for Ray Tracing"). Built for the free-space ray casting of
// the dynamic detection: voxels are grouped in 8^3 blocks that are allocated when first
// touched, so a segment through empty space costs one array lookup per voxel.
//
// Own implementation instead of OctoMap, measured with `dynamic_detection_benchmark
// --compare-octomap` (simulated `small` sessions s00/s01, first submap pair, voxel 0.2 m, each
// point ray-cast from its nearest scan origin, shared 2-core machine under load): OcTree
// computeRayKeys + search per key 1087 ms vs Traverse() 121 ms for 32,569 rays of s00/0, and
// 300 ms vs 38 ms for 12,820 rays of s01/0 (same occupied voxels found up to the key
// discretisation). The detection also needs per-voxel counters for two sessions, which OcTree
// nodes do not hold.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "multisession_mapper/core/status.h"

namespace multisession_mapper {
namespace core {

class RayVoxelGrid {
 public:
  struct Cell {
    std::uint8_t flags = 0;
    std::uint8_t count[2] = {0, 0};  ///< saturating at 255
  };

  /// A grid of cubic voxels of edge `voxel_size_m` covering the box [min_corner, max_corner]
  /// [m]. Fails on a bad size or an empty or too large box (more than 2^31 blocks).
  static StatusOr<RayVoxelGrid> Create(double voxel_size_m, const Eigen::Vector3d& min_corner,
                                       const Eigen::Vector3d& max_corner);

  bool Contains(const Eigen::Vector3d& p) const;
  /// Voxel coordinates of `p` (grid-local, may be outside the grid for outside points).
  Eigen::Vector3i KeyOf(const Eigen::Vector3d& p) const;
  /// Centre of the voxel with coordinates `key` [m].
  Eigen::Vector3d CentreOf(const Eigen::Vector3i& key) const;
  bool ContainsKey(const Eigen::Vector3i& key) const;
  /// The cell, allocating its block when absent; null outside the grid. Allocation may move
  /// the blocks: cell pointers are valid until the next Touch().
  Cell* Touch(const Eigen::Vector3i& key);
  /// The cell or null when its block was never touched or it lies outside the grid.
  Cell* Find(const Eigen::Vector3i& key);
  const Cell* Find(const Eigen::Vector3i& key) const;

  /// Visits the voxels crossed by the segment from `from` to `to` (clipped to the grid) in
  /// order: `visit(Cell* cell_or_null, double entry_distance_m)` returns false to stop.
  /// `entry_distance_m` is the distance from `from` at which the segment enters the voxel.
  /// A stretch through a block that was never touched is visited once, with a null cell and
  /// the distance at which it enters that block (empty space costs one visit per block).
  template <typename Visit>
  void Traverse(const Eigen::Vector3d& from, const Eigen::Vector3d& to, Visit&& visit);

  double voxel_size_m() const { return voxel_size_m_; }
  std::size_t num_blocks() const { return blocks_.size(); }

 private:
  static constexpr int kBlockBits = 3;  // 8^3 voxels per block
  static constexpr int kBlockEdge = 1 << kBlockBits;
  static constexpr int kBlockMask = kBlockEdge - 1;
  struct Block {
    Cell cells[kBlockEdge * kBlockEdge * kBlockEdge];
  };

  RayVoxelGrid() = default;
  long BlockSlot(const Eigen::Vector3i& key) const {
    return (static_cast<long>(key.z() >> kBlockBits) * block_dims_.y() +
            (key.y() >> kBlockBits)) * block_dims_.x() + (key.x() >> kBlockBits);
  }
  static int CellSlot(const Eigen::Vector3i& key) {
    return ((key.z() & kBlockMask) << (2 * kBlockBits)) | ((key.y() & kBlockMask) << kBlockBits) |
           (key.x() & kBlockMask);
  }

  double voxel_size_m_ = 1.0;
  double inv_voxel_size_ = 1.0;
  Eigen::Vector3d origin_ = Eigen::Vector3d::Zero();  // min corner of voxel (0, 0, 0)
  Eigen::Vector3i dims_ = Eigen::Vector3i::Zero();    // voxels per axis
  Eigen::Vector3i block_dims_ = Eigen::Vector3i::Zero();
  std::vector<std::int32_t> block_index_;  // block slot -> index into blocks_ or -1
  std::vector<Block> blocks_;
};

template <typename Visit>
void RayVoxelGrid::Traverse(const Eigen::Vector3d& from, const Eigen::Vector3d& to,
                            Visit&& visit) {
  const Eigen::Vector3d a = (from - origin_) * inv_voxel_size_;  // grid units
  const Eigen::Vector3d d = (to - origin_) * inv_voxel_size_ - a;
  // Clip the segment to the grid box [0, dims] (slab test); t is the fraction of the segment.
  double t0 = 0.0, t1 = 1.0;
  for (int i = 0; i < 3; ++i) {
    if (d[i] == 0.0) {
      if (a[i] < 0.0 || a[i] >= dims_[i]) return;
      continue;
    }
    double ta = (0.0 - a[i]) / d[i];
    double tb = (dims_[i] - a[i]) / d[i];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
    if (t0 > t1) return;
  }
  const double to_metres = d.norm() * voxel_size_m_;
  if (to_metres <= 0.0) return;
  int step[3];
  double t_delta[3];
  for (int i = 0; i < 3; ++i) {
    step[i] = d[i] > 0.0 ? 1 : (d[i] < 0.0 ? -1 : 0);
    t_delta[i] = d[i] != 0.0 ? std::abs(1.0 / d[i]) : 2.0;
  }
  Eigen::Vector3i key;
  double t_max[3];
  // (Re)starts the walk in the voxel that contains the point at fraction t.
  auto start_at = [&](double t) {
    const Eigen::Vector3d p = a + t * d;
    for (int i = 0; i < 3; ++i) {
      key[i] = std::min(std::max(static_cast<int>(std::floor(p[i])), 0), dims_[i] - 1);
      t_max[i] = step[i] > 0   ? (key[i] + 1 - a[i]) / d[i]
                 : step[i] < 0 ? (key[i] - a[i]) / d[i]
                               : 2.0;
    }
  };
  start_at(t0);
  double t_entry = t0;
  while (true) {
    const std::int32_t block = block_index_[static_cast<std::size_t>(BlockSlot(key))];
    if (block < 0) {
      // Empty block: one visit, then jump to where the segment leaves the block.
      if (!visit(static_cast<Cell*>(nullptr), t_entry * to_metres)) return;
      double t_exit = 2.0;
      for (int i = 0; i < 3; ++i) {
        if (step[i] == 0) continue;
        const int edge = step[i] > 0 ? ((key[i] >> kBlockBits) + 1) << kBlockBits
                                     : (key[i] >> kBlockBits) << kBlockBits;
        t_exit = std::min(t_exit, (edge - a[i]) / d[i]);
      }
      if (t_exit > t1) return;
      const Eigen::Vector3i block_key(key.x() >> kBlockBits, key.y() >> kBlockBits,
                                      key.z() >> kBlockBits);
      // Step just past the boundary, then make sure the walk really left the block.
      start_at(std::min(t_exit + 1e-9, t1));
      t_entry = t_exit;
      bool outside = false;
      while (Eigen::Vector3i(key.x() >> kBlockBits, key.y() >> kBlockBits,
                             key.z() >> kBlockBits) == block_key) {
        const int axis = t_max[0] < t_max[1] ? (t_max[0] < t_max[2] ? 0 : 2)
                                             : (t_max[1] < t_max[2] ? 1 : 2);
        if (t_max[axis] > t1) return;
        t_entry = t_max[axis];
        key[axis] += step[axis];
        if (key[axis] < 0 || key[axis] >= dims_[axis]) {
          outside = true;
          break;
        }
        t_max[axis] += t_delta[axis];
      }
      if (outside) return;
      continue;
    }
    Cell* cell = &blocks_[static_cast<std::size_t>(block)].cells[CellSlot(key)];
    if (!visit(cell, t_entry * to_metres)) return;
    const int axis =
        t_max[0] < t_max[1] ? (t_max[0] < t_max[2] ? 0 : 2) : (t_max[1] < t_max[2] ? 1 : 2);
    if (t_max[axis] > t1) return;
    t_entry = t_max[axis];
    key[axis] += step[axis];
    if (key[axis] < 0 || key[axis] >= dims_[axis]) return;
    t_max[axis] += t_delta[axis];
  }
}

}  // namespace core
}  // namespace multisession_mapper
