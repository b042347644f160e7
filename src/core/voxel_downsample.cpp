#include "multisession_mapper/core/voxel_downsample.h"

#include <cmath>
#include <cstdint>
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
  static std::size_t Mix(std::uint64_t k) {
    k ^= k >> 33;
    k *= 0xff51afd7ed558ccdULL;
    k ^= k >> 33;
    return static_cast<std::size_t>(k);
  }
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
