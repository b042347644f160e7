#include "multisession_mapper/core/submap.h"

#include <algorithm>
#include <cmath>
#include <utility>

namespace multisession_mapper {
namespace core {

const char* SubmapStateName(SubmapState state) {
  switch (state) {
    case SubmapState::kActive:
      return "active";
    case SubmapState::kFused:
      return "fused";
  }
  return "unknown";
}

void AppendScanPoses(const Submap& submap, Trajectory* out) {
  for (const SubmapScanRecord& scan : submap.scans) {
    StampedPose sp;
    sp.stamp_s = scan.stamp_s;
    sp.pose = submap.T_map_submap * scan.T_submap_sensor;
    out->push_back(sp);
  }
}

void SortTrajectory(Trajectory* trajectory) {
  std::stable_sort(trajectory->begin(), trajectory->end(),
                   [](const StampedPose& a, const StampedPose& b) { return a.stamp_s < b.stamp_s; });
  trajectory->erase(std::unique(trajectory->begin(), trajectory->end(),
                                [](const StampedPose& a, const StampedPose& b) {
                                  return a.stamp_s == b.stamp_s;
                                }),
                    trajectory->end());
}

Trajectory ScanTrajectory(const std::vector<Submap, Eigen::aligned_allocator<Submap>>& submaps) {
  Trajectory trajectory;
  for (const Submap& submap : submaps) AppendScanPoses(submap, &trajectory);
  SortTrajectory(&trajectory);
  return trajectory;
}

void DropSubmapPoints(const std::vector<std::uint8_t>& drop, Submap* submap) {
  PointVector& points = submap->points;
  std::vector<PointViews>& views = submap->views;
  const bool has_views = views.size() == points.size();
  std::size_t kept = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (i < drop.size() && drop[i]) continue;
    if (has_views) views[kept] = views[i];
    points[kept++] = points[i];
  }
  points.resize(kept);
  if (has_views) {
    views.resize(kept);
  } else {
    views.clear();
  }
}

void DropSubmapPointsAt(const std::set<std::uint32_t>& indices, Submap* submap) {
  std::vector<std::uint8_t> drop(submap->points.size(), 0);
  for (std::uint32_t k : indices) {
    if (k < drop.size()) drop[k] = 1;
  }
  DropSubmapPoints(drop, submap);
}

namespace {

// The 21 low bits of v spread to every third bit (bit k moves to bit 3k).
std::uint64_t SpreadBits3(std::uint64_t v) {
  v &= 0x1fffffULL;
  v = (v | (v << 32)) & 0x1f00000000ffffULL;
  v = (v | (v << 16)) & 0x1f0000ff0000ffULL;
  v = (v | (v << 8)) & 0x100f00f00f00f00fULL;
  v = (v | (v << 4)) & 0x10c30c30c30c30c3ULL;
  v = (v | (v << 2)) & 0x1249249249249249ULL;
  return v;
}

std::uint64_t MortonCode(const Eigen::Vector3d& p, double inv_cell) {
  constexpr double kHalf = 1 << 20;  // cell 0 sits at the middle of the 21-bit range
  std::uint64_t code = 0;
  for (int axis = 0; axis < 3; ++axis) {
    const double c = std::floor(p[axis] * inv_cell) + kHalf;
    const double clamped = std::isfinite(c) ? std::min(std::max(c, 0.0), 2.0 * kHalf - 1.0) : 0.0;
    code |= SpreadBits3(static_cast<std::uint64_t>(clamped)) << axis;
  }
  return code;
}

}  // namespace

void SortSubmapPointsSpatially(double cell_m, Submap* submap) {
  PointVector& points = submap->points;
  std::vector<PointViews>& views = submap->views;
  const bool has_views = views.size() == points.size();
  const double inv_cell = 1.0 / cell_m;
  std::vector<std::pair<std::uint64_t, std::uint32_t>> order(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    order[i] = {MortonCode(points[i], inv_cell), static_cast<std::uint32_t>(i)};
  }
  // (code, index) pairs are unique: std::sort keeps the points of one cell in their order.
  std::sort(order.begin(), order.end());
  PointVector sorted_points;
  sorted_points.reserve(points.size());
  std::vector<PointViews> sorted_views;
  if (has_views) sorted_views.reserve(points.size());
  for (const auto& entry : order) {
    sorted_points.push_back(points[entry.second]);
    if (has_views) sorted_views.push_back(views[entry.second]);
  }
  points = std::move(sorted_points);
  if (has_views) {
    views = std::move(sorted_views);
  } else {
    views.clear();
  }
}

void SortSubmapPointsInVoxelBlocks(double voxel_m, Submap* submap) {
  SortSubmapPointsSpatially(kSpatialOrderBlockVoxels * voxel_m, submap);
}

void AppendSubmapPoints(const PointVector& points, Submap* submap) {
  const bool has_views = submap->views.size() == submap->points.size();
  submap->points.insert(submap->points.end(), points.begin(), points.end());
  if (has_views) {
    submap->views.resize(submap->points.size(), PointViews());
  } else {
    submap->views.clear();
  }
}

}  // namespace core
}  // namespace multisession_mapper
