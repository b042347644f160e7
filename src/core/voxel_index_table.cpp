#include "multisession_mapper/core/voxel_index_table.h"

namespace multisession_mapper {
namespace core {

std::size_t VoxelIndexTable::Hash(const VoxelKey& key) {
  // The three coordinates packed into 64 bits (21 bits each, wrapping) and mixed by the
  // splitmix64 finaliser, so that neighbouring voxels spread over the power-of-two table.
  std::uint64_t h = (static_cast<std::uint64_t>(static_cast<std::uint32_t>(key.x())) & 0x1FFFFFu) |
                    ((static_cast<std::uint64_t>(static_cast<std::uint32_t>(key.y())) & 0x1FFFFFu)
                     << 21) |
                    ((static_cast<std::uint64_t>(static_cast<std::uint32_t>(key.z())) & 0x1FFFFFu)
                     << 42);
  h ^= h >> 30;
  h *= 0xBF58476D1CE4E5B9ull;
  h ^= h >> 27;
  h *= 0x94D049BB133111EBull;
  h ^= h >> 31;
  return static_cast<std::size_t>(h);
}

void VoxelIndexTable::Rehash(std::size_t capacity) {
  std::vector<Slot> old;
  old.swap(slots_);
  slots_.assign(capacity, Slot{0, 0, 0, kEmpty});
  mask_ = capacity - 1;
  for (const Slot& s : old) {
    if (s.index == kEmpty) continue;
    std::size_t i = Hash(VoxelKey(s.x, s.y, s.z)) & mask_;
    while (slots_[i].index != kEmpty) i = (i + 1) & mask_;
    slots_[i] = s;
  }
}

void VoxelIndexTable::Reserve(std::size_t count) {
  std::size_t capacity = slots_.empty() ? 1024 : slots_.size();
  while (capacity < 2 * count) capacity <<= 1;
  if (capacity != slots_.size()) Rehash(capacity);
}

std::pair<std::uint32_t, bool> VoxelIndexTable::FindOrInsert(const VoxelKey& key,
                                                             std::size_t hash,
                                                             std::uint32_t index_if_new) {
  if (2 * (size_ + 1) > slots_.size()) Reserve(size_ + 1);
  std::size_t i = hash & mask_;
  while (true) {
    Slot& s = slots_[i];
    if (s.index == kEmpty) {
      s = Slot{key.x(), key.y(), key.z(), index_if_new};
      ++size_;
      return {index_if_new, true};
    }
    if (s.x == key.x() && s.y == key.y() && s.z == key.z()) return {s.index, false};
    i = (i + 1) & mask_;
  }
}

std::uint32_t VoxelIndexTable::Find(const VoxelKey& key) const {
  if (slots_.empty()) return kEmpty;
  std::size_t i = Hash(key) & mask_;
  while (true) {
    const Slot& s = slots_[i];
    if (s.index == kEmpty) return kEmpty;
    if (s.x == key.x() && s.y == key.y() && s.z == key.z()) return s.index;
    i = (i + 1) & mask_;
  }
}

void VoxelIndexTable::Release() {
  slots_ = std::vector<Slot>();
  mask_ = 0;
  size_ = 0;
}

}  // namespace core
}  // namespace multisession_mapper
