#include "multisession_mapper/core/submap.h"

#include <algorithm>

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
