// Open-addressing hash table from voxel keys to 32-bit indices, for the per-point voxel look-ups
// of the submap builder (every point of every scan). Linear probing over one flat array of
// {key, index} slots, power-of-two capacity, at most half full. Replaces an
// std::unordered_map<VoxelKey, uint32_t> there: no node allocation per voxel and one cache line
// per probe (benchmark in the issue-5 note: submap building median and profile share).
// VoxelHashMap (the odometry's local map) still carries a table of the same kind inline
// (packed 64-bit keys, rebuilt after far voxels are removed); moving it onto this class is
// open work: it needs a rebuild-after-removal operation here and the ICP benchmark.
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include "multisession_mapper/core/voxel_key.h"

namespace multisession_mapper {
namespace core {

class VoxelIndexTable {
 public:
  /// Index values must be below kEmpty (it marks a free slot).
  static constexpr std::uint32_t kEmpty = std::numeric_limits<std::uint32_t>::max();

  VoxelIndexTable() = default;

  /// The index of `key`; when absent, inserts `index_if_new` and returns it. second: inserted.
  std::pair<std::uint32_t, bool> FindOrInsert(const VoxelKey& key, std::uint32_t index_if_new);
  /// The index of `key`, or kEmpty when absent.
  std::uint32_t Find(const VoxelKey& key) const;

  std::size_t size() const { return size_; }
  bool empty() const { return size_ == 0; }
  /// Frees the slots (capacity 0).
  void Release();

 private:
  struct Slot {
    std::int32_t x, y, z;
    std::uint32_t index;
  };
  static std::size_t Mix(const VoxelKey& key);
  void Grow();

  std::vector<Slot> slots_;
  std::size_t mask_ = 0;
  std::size_t size_ = 0;
};

}  // namespace core
}  // namespace multisession_mapper
