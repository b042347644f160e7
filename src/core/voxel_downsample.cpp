#include "multisession_mapper/core/voxel_downsample.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <tuple>
#include <vector>

namespace multisession_mapper {
namespace core {
namespace {

// 21 bits per axis: +-1M voxels, i.e. +-100 km at 0.1 m, far beyond any LiDAR range.
std::uint64_t VoxelKey(const Eigen::Vector3d& p, double inv_size) {
  const auto axis = [inv_size](double v) {
    return static_cast<std::uint64_t>(static_cast<std::int64_t>(std::floor(v * inv_size)) +
                                      (1 << 20)) &
           0x1FFFFFu;
  };
  return (axis(p.x()) << 42) | (axis(p.y()) << 21) | axis(p.z());
}

std::size_t Mix(std::uint64_t k) {
  k ^= k >> 33;
  k *= 0xff51afd7ed558ccdULL;
  k ^= k >> 33;
  return static_cast<std::size_t>(k);
}

// Minimal open-addressing set of voxel keys sized for the input; returns true on first insert.
class FlatKeySet {
 public:
  explicit FlatKeySet(std::size_t expected) {
    std::size_t capacity = 64;
    while (capacity < expected * 2) capacity <<= 1;
    slots_.assign(capacity, kEmpty);
    mask_ = capacity - 1;
  }
  bool Insert(std::uint64_t key) {
    std::size_t i = Mix(key) & mask_;
    while (true) {
      if (slots_[i] == kEmpty) {
        slots_[i] = key;
        return true;
      }
      if (slots_[i] == key) return false;
      i = (i + 1) & mask_;
    }
  }

 private:
  static constexpr std::uint64_t kEmpty = ~std::uint64_t{0};  // never a valid 63-bit key
  std::vector<std::uint64_t> slots_;
  std::size_t mask_ = 0;
};

}  // namespace

PointVector VoxelDownsample(const PointVector& points, double voxel_size_m) {
  if (!(voxel_size_m > 0.0)) return points;
  const double inv = 1.0 / voxel_size_m;
  FlatKeySet seen(points.size());
  PointVector out;
  out.reserve(points.size() / 2);
  for (const Eigen::Vector3d& p : points) {
    if (seen.Insert(VoxelKey(p, inv))) out.push_back(p);
  }
  return out;
}

PointVector VoxelDownsampleCentred(const PointVector& points, double voxel_size_m) {
  if (!(voxel_size_m > 0.0)) return points;
  const double inv = 1.0 / voxel_size_m;
  // Open addressing from voxel key to the best point so far (one pass), then the winners
  // sorted by key: a sort of the voxels, not of the points.
  struct Slot {
    std::uint64_t key;
    double distance_sq;  // of the best point to the voxel's centre
    std::uint32_t index;
  };
  constexpr std::uint64_t kEmpty = ~std::uint64_t{0};  // never a valid 63-bit key
  std::size_t capacity = 64;
  while (capacity < points.size() * 2) capacity <<= 1;
  const std::size_t mask = capacity - 1;
  std::vector<Slot> slots(capacity, Slot{kEmpty, 0.0, 0});
  const auto better = [&](double d2, std::uint32_t i, const Slot& slot) {
    if (d2 != slot.distance_sq) return d2 < slot.distance_sq;
    const Eigen::Vector3d& a = points[i];
    const Eigen::Vector3d& b = points[slot.index];
    return std::make_tuple(a.x(), a.y(), a.z()) < std::make_tuple(b.x(), b.y(), b.z());
  };
  std::size_t used = 0;
  for (std::size_t n = 0; n < points.size(); ++n) {
    const Eigen::Vector3d& p = points[n];
    if (!p.allFinite()) continue;  // no voxel
    const std::uint64_t key = VoxelKey(p, inv);
    const Eigen::Vector3d centre = ((p * inv).array().floor() + 0.5).matrix() * voxel_size_m;
    const double d2 = (p - centre).squaredNorm();
    const auto i = static_cast<std::uint32_t>(n);
    std::size_t s = Mix(key) & mask;
    while (slots[s].key != kEmpty && slots[s].key != key) s = (s + 1) & mask;
    if (slots[s].key == kEmpty) {
      slots[s] = {key, d2, i};
      ++used;
    } else if (better(d2, i, slots[s])) {
      slots[s].distance_sq = d2;
      slots[s].index = i;
    }
  }
  std::vector<std::pair<std::uint64_t, std::uint32_t>> winners;
  winners.reserve(used);
  for (const Slot& slot : slots) {
    if (slot.key != kEmpty) winners.emplace_back(slot.key, slot.index);
  }
  std::sort(winners.begin(), winners.end());
  PointVector out;
  out.reserve(winners.size());
  for (const auto& winner : winners) out.push_back(points[winner.second]);
  return out;
}

LidarScan VoxelDownsample(const LidarScan& scan, double voxel_size_m) {
  if (!(voxel_size_m > 0.0)) return scan;
  const double inv = 1.0 / voxel_size_m;
  FlatKeySet seen(scan.points.size());
  LidarScan out;
  out.stamp_s = scan.stamp_s;
  out.has_ring = scan.has_ring;
  out.has_time = scan.has_time;
  out.points.reserve(scan.points.size() / 2);
  for (const LidarPoint& p : scan.points) {
    if (seen.Insert(VoxelKey(p.position_m.cast<double>(), inv))) out.points.push_back(p);
  }
  return out;
}

PointVector ScanToPointVector(const LidarScan& scan) {
  PointVector out;
  out.reserve(scan.points.size());
  for (const LidarPoint& p : scan.points) out.push_back(p.position_m.cast<double>());
  return out;
}

}  // namespace core
}  // namespace multisession_mapper
