#include "multisession_mapper/core/local_ground.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <limits>
#include <unordered_map>
#include <unordered_set>

namespace multisession_mapper {
namespace core {
namespace {

std::uint64_t CellKey(std::int64_t x, std::int64_t y) {
  return (static_cast<std::uint64_t>(x) << 32) ^ (static_cast<std::uint64_t>(y) & 0xffffffffu);
}

// The horizontal cell of every point (cells of edge 1 / inv).
void CellsOf(const PointVector& points, double inv, std::vector<std::int64_t>* cx,
             std::vector<std::int64_t>* cy) {
  cx->resize(points.size());
  cy->resize(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    (*cx)[i] = static_cast<std::int64_t>(std::floor(points[i].x() * inv));
    (*cy)[i] = static_cast<std::int64_t>(std::floor(points[i].y() * inv));
  }
}

}  // namespace

std::vector<float> HeightsAboveLocalGround(const PointVector& points, double cell_m) {
  std::vector<std::int64_t> cx, cy;
  CellsOf(points, 1.0 / cell_m, &cx, &cy);
  std::unordered_map<std::uint64_t, float> lowest;
  lowest.reserve(points.size() / 8 + 1);
  for (std::size_t i = 0; i < points.size(); ++i) {
    const float z = static_cast<float>(points[i].z());
    auto [it, inserted] = lowest.emplace(CellKey(cx[i], cy[i]), z);
    if (!inserted) it->second = std::min(it->second, z);
  }
  std::unordered_map<std::uint64_t, float> ground;  // the 3 x 3 minimum, per occupied cell
  ground.reserve(lowest.size());
  std::vector<float> heights(points.size(), 0.0f);
  for (std::size_t i = 0; i < points.size(); ++i) {
    auto [it, inserted] = ground.emplace(CellKey(cx[i], cy[i]), 0.0f);
    if (inserted) {
      float g = std::numeric_limits<float>::infinity();
      for (int dx = -1; dx <= 1; ++dx) {
        for (int dy = -1; dy <= 1; ++dy) {
          const auto cell = lowest.find(CellKey(cx[i] + dx, cy[i] + dy));
          if (cell != lowest.end()) g = std::min(g, cell->second);
        }
      }
      it->second = g;
    }
    heights[i] = std::max(0.0f, static_cast<float>(points[i].z()) - it->second);
  }
  return heights;
}

std::vector<std::uint8_t> NearStandingPoints(const PointVector& points,
                                             const std::vector<float>& heights, double cell_m,
                                             double low_m, double high_m) {
  assert(heights.size() == points.size());
  std::vector<std::int64_t> cx, cy;
  CellsOf(points, 1.0 / cell_m, &cx, &cy);
  std::unordered_set<std::uint64_t> standing;
  for (std::size_t i = 0; i < points.size() && i < heights.size(); ++i) {
    if (heights[i] > low_m && heights[i] < high_m) standing.insert(CellKey(cx[i], cy[i]));
  }
  std::vector<std::uint8_t> near(points.size(), 0);
  if (standing.empty()) return near;
  for (std::size_t i = 0; i < points.size(); ++i) {
    for (int dx = -1; dx <= 1 && !near[i]; ++dx) {
      for (int dy = -1; dy <= 1 && !near[i]; ++dy) {
        near[i] = standing.count(CellKey(cx[i] + dx, cy[i] + dy)) > 0;
      }
    }
  }
  return near;
}

}  // namespace core
}  // namespace multisession_mapper
