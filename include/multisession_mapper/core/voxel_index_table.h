// Open-addressing hash table from voxel keys to 32-bit indices, for the per-point voxel look-ups
// of the submap builder (every point of every scan) and the ICP's local map. Linear probing over one flat array of
// {key, index} slots, power-of-two capacity, at most half full. Replaces an
// std::unordered_map<VoxelKey, uint32_t> there: no node allocation per voxel and one cache line
// per probe (benchmark in the issue-5 note: submap building median and profile share).
// Also the voxel index of VoxelHashMap, the odometry's local map, and the voxel occupancy of the
// map update (every point of the map at each merge).
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
  std::pair<std::uint32_t, bool> FindOrInsert(const VoxelKey& key, std::uint32_t index_if_new) {
    return FindOrInsert(key, Hash(key), index_if_new);
  }
  /// The same with `hash` == Hash(key) computed by the caller (e.g. once for Prefetch too).
  std::pair<std::uint32_t, bool> FindOrInsert(const VoxelKey& key, std::size_t hash,
                                              std::uint32_t index_if_new);
  /// The hash of a key; its probe starts at slot hash & (capacity - 1).
  static std::size_t Hash(const VoxelKey& key);
  /// Asks the CPU to load the slot where the probe for `hash` starts, so that a look-up a few
  /// keys later does not wait for memory (a hint only: no effect on any result). The submap
  /// builder's per-point look-ups go to random places of a table of several MB.
  void Prefetch(std::size_t hash) const {
    if (!slots_.empty()) __builtin_prefetch(&slots_[hash & mask_]);
  }
  /// The index of `key`, or kEmpty when absent.
  std::uint32_t Find(const VoxelKey& key) const;

  std::size_t size() const { return size_; }
  bool empty() const { return size_ == 0; }
  /// Frees the slots (capacity 0).
  void Release();
  /// Makes room for `count` keys without growing again (load factor at most 1/2).
  void Reserve(std::size_t count);

 private:
  struct Slot {
    std::int32_t x, y, z;
    std::uint32_t index;
  };
  void Rehash(std::size_t capacity);

  std::vector<Slot> slots_;
  std::size_t mask_ = 0;
  std::size_t size_ = 0;
};

}  // namespace core
}  // namespace multisession_mapper
