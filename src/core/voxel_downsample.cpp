#include "multisession_mapper/core/voxel_downsample.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <tuple>
#include <utility>
#include <vector>

namespace multisession_mapper {
namespace core {
namespace {

// The key of a voxel given by its integer coordinates (floor(p / size), as doubles).
// 21 bits per axis: +-1M voxels, i.e. +-100 km at 0.1 m, far beyond any LiDAR range.
std::uint64_t CellKey(const Eigen::Vector3d& cell) {
  const auto axis = [](double c) {
    return static_cast<std::uint64_t>(static_cast<std::int64_t>(c) + (1 << 20)) & 0x1FFFFFu;
  };
  return (axis(cell.x()) << 42) | (axis(cell.y()) << 21) | axis(cell.z());
}

std::uint64_t VoxelKey(const Eigen::Vector3d& p, double inv_size) {
  return CellKey((p * inv_size).array().floor().matrix());
}

// Minimal open-addressing table of voxel keys sized for the input (at most half full, so a
// probe always ends). Insert gives the key's slot and whether the key was new there; slots
// run from 0 to capacity() - 1, and Key(slot) is kEmpty for a free one.
class FlatKeyTable {
 public:
  static constexpr std::uint64_t kEmpty = ~std::uint64_t{0};  // never a valid 63-bit key

  explicit FlatKeyTable(std::size_t expected) {
    std::size_t capacity = 64;
    while (capacity < expected * 2) capacity <<= 1;
    slots_.assign(capacity, kEmpty);
    mask_ = capacity - 1;
  }
  std::pair<std::size_t, bool> Insert(std::uint64_t key) {
    std::size_t i = Mix(key) & mask_;
    while (true) {
      if (slots_[i] == kEmpty) {
        slots_[i] = key;
        return {i, true};
      }
      if (slots_[i] == key) return {i, false};
      i = (i + 1) & mask_;
    }
  }
  std::size_t capacity() const { return slots_.size(); }
  std::uint64_t Key(std::size_t slot) const { return slots_[slot]; }

 private:
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
  FlatKeyTable seen(points.size());
  PointVector out;
  out.reserve(points.size() / 2);
  for (const Eigen::Vector3d& p : points) {
    if (seen.Insert(VoxelKey(p, inv)).second) out.push_back(p);
  }
  return out;
}

PointVector VoxelDownsampleCentred(const PointVector& points, double voxel_size_m) {
  if (!(voxel_size_m > 0.0)) return points;
  const double inv = 1.0 / voxel_size_m;
  // One pass keeps each voxel's best point so far in its slot; then the winners are sorted by
  // key: a sort of the voxels, not of the points.
  struct Best {
    double distance_sq;  // to the voxel's centre
    std::uint32_t index;
  };
  FlatKeyTable table(points.size());
  std::vector<Best> best(table.capacity());
  const auto better = [&](double d2, std::uint32_t i, const Best& b) {
    if (d2 != b.distance_sq) return d2 < b.distance_sq;
    const Eigen::Vector3d& p = points[i];
    const Eigen::Vector3d& q = points[b.index];
    return std::make_tuple(p.x(), p.y(), p.z()) < std::make_tuple(q.x(), q.y(), q.z());
  };
  std::size_t used = 0;
  for (std::size_t n = 0; n < points.size(); ++n) {
    const Eigen::Vector3d& p = points[n];
    if (!p.allFinite()) continue;  // no voxel
    const Eigen::Vector3d cell = (p * inv).array().floor().matrix();  // key and centre
    const double d2 = (p - (cell.array() + 0.5).matrix() * voxel_size_m).squaredNorm();
    const auto i = static_cast<std::uint32_t>(n);
    const auto [slot, inserted] = table.Insert(CellKey(cell));
    if (inserted || better(d2, i, best[slot])) best[slot] = {d2, i};
    used += inserted;
  }
  std::vector<std::pair<std::uint64_t, std::uint32_t>> winners;
  winners.reserve(used);
  for (std::size_t slot = 0; slot < table.capacity(); ++slot) {
    const std::uint64_t key = table.Key(slot);
    if (key != FlatKeyTable::kEmpty) winners.emplace_back(key, best[slot].index);
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
  FlatKeyTable seen(scan.points.size());
  LidarScan out;
  out.stamp_s = scan.stamp_s;
  out.has_ring = scan.has_ring;
  out.has_time = scan.has_time;
  out.points.reserve(scan.points.size() / 2);
  for (const LidarPoint& p : scan.points) {
    if (seen.Insert(VoxelKey(p.position_m.cast<double>(), inv)).second) out.points.push_back(p);
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
