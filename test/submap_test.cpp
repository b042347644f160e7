#include "multisession_mapper/core/submap.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <set>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>

#include "voxel_cell.h"

namespace multisession_mapper {
namespace core {
namespace {

Submap WithPoints(int n, bool views) {
  Submap s;
  for (int i = 0; i < n; ++i) {
    s.points.emplace_back(i, 0.0, 0.0);
    if (views) {
      PointViews v;
      v.nearest_scan = static_cast<std::uint32_t>(i);
      v.last_scan = static_cast<std::uint32_t>(10 + i);
      s.views.push_back(v);
    }
  }
  return s;
}

TEST(Submap, DropKeepsEachPointWithItsViews) {
  Submap s = WithPoints(6, true);
  DropSubmapPoints({1, 0, 0, 1, 1, 0}, &s);
  ASSERT_EQ(s.points.size(), 3u);
  ASSERT_EQ(s.views.size(), 3u);
  const int kept[] = {1, 2, 5};
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(s.points[k].x(), kept[k]);
    EXPECT_EQ(s.views[k].nearest_scan, static_cast<std::uint32_t>(kept[k]));
    EXPECT_EQ(s.views[k].last_scan, static_cast<std::uint32_t>(10 + kept[k]));
  }
  // A shorter mask drops nothing beyond its end.
  DropSubmapPoints({1}, &s);
  ASSERT_EQ(s.points.size(), 2u);
  EXPECT_EQ(s.points[0].x(), 2);
  EXPECT_EQ(s.views[1].nearest_scan, 5u);
}

TEST(Submap, DropWithoutViewsLeavesNone) {
  Submap s = WithPoints(4, false);
  DropSubmapPoints({0, 1, 0, 0}, &s);
  EXPECT_EQ(s.points.size(), 3u);
  EXPECT_TRUE(s.views.empty());
}

TEST(Submap, AppendedPointsHaveUnknownViews) {
  Submap s = WithPoints(2, true);
  AppendSubmapPoints({Eigen::Vector3d(7, 7, 7)}, &s);
  ASSERT_EQ(s.points.size(), 3u);
  ASSERT_EQ(s.views.size(), 3u);
  EXPECT_EQ(s.views[1].last_scan, 11u);
  EXPECT_EQ(s.views[2].nearest_scan, PointViews::kUnknownScan);
  EXPECT_EQ(s.views[2].last_scan, PointViews::kUnknownScan);
  // A submap that records no views keeps recording none.
  Submap plain = WithPoints(2, false);
  AppendSubmapPoints({Eigen::Vector3d(1, 2, 3)}, &plain);
  EXPECT_EQ(plain.points.size(), 3u);
  EXPECT_TRUE(plain.views.empty());
}

using test::CellOf;

// Whether every block of `edge_m` holds one contiguous run of the points.
bool BlocksContiguous(const PointVector& points, double edge_m) {
  std::set<std::tuple<long, long, long>> finished;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const auto block = CellOf(points[i], edge_m);
    if (finished.count(block)) return false;  // the block came back after another one
    if (i + 1 < points.size() && CellOf(points[i + 1], edge_m) != block) finished.insert(block);
  }
  return true;
}

TEST(Submap, SpatialOrderKeepsEachPointWithItsViewsAndGroupsEveryBlock) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-30.0, 30.0);
  Submap s;
  for (std::uint32_t i = 0; i < 5000; ++i) {
    s.points.emplace_back(u(rng), u(rng), 0.1 * u(rng));
    PointViews v;
    v.nearest_scan = i;  // the point's index before sorting
    v.last_scan = 2 * i;
    s.views.push_back(v);
  }
  const PointVector before = s.points;
  ASSERT_FALSE(BlocksContiguous(before, 1.6));  // random order: the test below can fail
  SortSubmapPointsSpatially(0.2, &s);
  ASSERT_EQ(s.points.size(), before.size());
  ASSERT_EQ(s.views.size(), before.size());
  std::set<std::uint32_t> seen;
  for (std::size_t k = 0; k < s.points.size(); ++k) {
    const std::uint32_t i = s.views[k].nearest_scan;
    ASSERT_LT(i, before.size());
    EXPECT_EQ(s.points[k], before[i]);
    EXPECT_EQ(s.views[k].last_scan, 2 * i);
    seen.insert(i);
  }
  EXPECT_EQ(seen.size(), before.size());  // a permutation
  // Z-order: every aligned block of 2^k cells (here 1, 8 and 64 cells of 0.2 m on an edge,
  // on both sides of the origin) is one run, so close points sit close in the vector.
  EXPECT_TRUE(BlocksContiguous(s.points, 0.2));
  EXPECT_TRUE(BlocksContiguous(s.points, 1.6));
  EXPECT_TRUE(BlocksContiguous(s.points, 12.8));
  EXPECT_FALSE(BlocksContiguous(s.points, 1.0));  // a block that is not of the grid is not
}

TEST(Submap, SpatialOrderKeepsTheOrderInsideACellAndTakesAnyPoint) {
  Submap s;
  // Two cells of 1 m, interleaved: (0.5, ...) and (-0.5, ...); x = -0.5 comes first.
  for (int i = 0; i < 6; ++i) s.points.emplace_back(i % 2 ? -0.5 : 0.5, 0.1 * i, 0.0);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  s.points.emplace_back(1e9, -1e9, nan);  // far outside the code's range, and not finite
  SortSubmapPointsSpatially(1.0, &s);  // no views: none are made up
  EXPECT_TRUE(s.views.empty());
  ASSERT_EQ(s.points.size(), 7u);
  std::vector<double> cell_a, cell_b;
  for (const Eigen::Vector3d& p : s.points) {
    if (p.x() == -0.5) cell_a.push_back(p.y());
    if (p.x() == 0.5) cell_b.push_back(p.y());
  }
  EXPECT_EQ(cell_a, (std::vector<double>{0.1, 0.30000000000000004, 0.5}));
  EXPECT_EQ(cell_b, (std::vector<double>{0.0, 0.2, 0.4}));
  EXPECT_EQ(std::count_if(s.points.begin(), s.points.end(),
                          [](const Eigen::Vector3d& p) { return p.x() == 1e9; }),
            1);
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
