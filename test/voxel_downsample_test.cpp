#include "multisession_mapper/core/voxel_downsample.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <random>
#include <set>
#include <tuple>

#include <gtest/gtest.h>

#include "voxel_cell.h"

namespace multisession_mapper {
namespace core {
namespace {

using test::CellOf;

PointVector RandomPoints(int n, unsigned seed, double extent) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-extent, extent);
  PointVector pts;
  for (int i = 0; i < n; ++i) pts.emplace_back(u(rng), u(rng), u(rng) * 0.2);
  return pts;
}

TEST(VoxelDownsampleTest, KeepsFirstPointOfEveryOccupiedVoxel) {
  const PointVector pts = RandomPoints(20000, 1, 30.0);
  const double size = 0.7;
  const PointVector out = VoxelDownsample(pts, size);
  std::set<std::tuple<long, long, long>> expected_keys;
  PointVector expected;
  for (const Eigen::Vector3d& p : pts) {
    if (expected_keys.insert(CellOf(p, size)).second) expected.push_back(p);
  }
  ASSERT_EQ(out.size(), expected.size());
  for (std::size_t i = 0; i < out.size(); ++i) EXPECT_EQ(out[i], expected[i]);
}

TEST(VoxelDownsampleTest, NegativeCoordinatesAndVoxelBordersAreSeparateVoxels) {
  // -0.1 and +0.1 straddle the voxel border at 0: two voxels, not one.
  const PointVector pts = {{-0.1, 0.0, 0.0}, {0.1, 0.0, 0.0}, {0.2, 0.1, 0.1}};
  EXPECT_EQ(VoxelDownsample(pts, 1.0).size(), 2u);
}

TEST(VoxelDownsampleTest, NonPositiveVoxelReturnsInput) {
  const PointVector pts = RandomPoints(100, 2, 5.0);
  EXPECT_EQ(VoxelDownsample(pts, 0.0).size(), pts.size());
  EXPECT_EQ(VoxelDownsample(pts, -1.0).size(), pts.size());
}

TEST(VoxelDownsampleTest, CentredKeepsThePointNearestEachVoxelsCentre) {
  const PointVector pts = RandomPoints(20000, 3, 5.0);  // ~30 points per voxel
  const double size = 0.7;
  std::map<std::tuple<long, long, long>, std::pair<double, Eigen::Vector3d>> best;
  for (const Eigen::Vector3d& p : pts) {
    const auto key = CellOf(p, size);
    const Eigen::Vector3d centre((std::get<0>(key) + 0.5) * size, (std::get<1>(key) + 0.5) * size,
                                 (std::get<2>(key) + 0.5) * size);
    const double d2 = (p - centre).squaredNorm();
    auto it = best.find(key);
    if (it == best.end() || d2 < it->second.first) best[key] = {d2, p};
  }
  const PointVector out = VoxelDownsampleCentred(pts, size);
  ASSERT_EQ(out.size(), best.size());
  std::set<std::tuple<long, long, long>> keys;
  for (const Eigen::Vector3d& p : out) {
    const auto key = CellOf(p, size);
    EXPECT_TRUE(keys.insert(key).second);  // one point per voxel
    EXPECT_EQ(p, best[key].second);
  }
  // The first-point rule picks other points from the same voxels: the rules differ here.
  const PointVector first = VoxelDownsample(pts, size);
  ASSERT_EQ(first.size(), out.size());
  EXPECT_GT(std::count_if(first.begin(), first.end(),
                          [&](const Eigen::Vector3d& p) {
                            return p != best[CellOf(p, size)].second;
                          }),
            static_cast<long>(first.size() / 2));
}

TEST(VoxelDownsampleTest, CentredDoesNotDependOnTheInputOrder) {
  PointVector pts = RandomPoints(5000, 4, 10.0);
  pts.push_back(pts[17]);  // an exact duplicate: a tie
  pts.emplace_back(std::numeric_limits<double>::quiet_NaN(), 0.0, 0.0);  // left out
  const PointVector out = VoxelDownsampleCentred(pts, 0.5);
  std::mt19937 rng(5);
  for (int round = 0; round < 3; ++round) {
    std::shuffle(pts.begin(), pts.end(), rng);
    EXPECT_EQ(VoxelDownsampleCentred(pts, 0.5), out);
  }
  for (const Eigen::Vector3d& p : out) EXPECT_TRUE(p.allFinite());
  EXPECT_EQ(VoxelDownsampleCentred(pts, 0.0).size(), pts.size());
  // Ordered by voxel: each voxel once, in increasing order of its (x, y, z) cell.
  for (std::size_t i = 1; i < out.size(); ++i) {
    EXPECT_LT(CellOf(out[i - 1], 0.5), CellOf(out[i], 0.5));
  }
}

TEST(VoxelDownsampleTest, CentredBreaksATieBetweenTwoPointsByTheirCoordinates) {
  // Mirrored about the centre of voxel (0, 0, 0) of 1 m: the same distance, either order.
  const Eigen::Vector3d low(0.25, 0.5, 0.5), high(0.75, 0.5, 0.5);
  EXPECT_EQ(VoxelDownsampleCentred({high, low}, 1.0), PointVector{low});
  EXPECT_EQ(VoxelDownsampleCentred({low, high}, 1.0), PointVector{low});
}

TEST(VoxelDownsampleTest, ScanVersionKeepsAttributesAndFlags) {
  LidarScan scan;
  scan.stamp_s = 12.5;
  scan.has_time = true;
  scan.has_ring = true;
  for (int i = 0; i < 10; ++i) {
    LidarPoint p;
    p.position_m = Eigen::Vector3f(0.01f * i, 0.0f, 0.0f);  // all in one 1 m voxel
    p.ring = static_cast<std::uint16_t>(i + 3);
    p.time_s = 0.001f * i;
    p.intensity = 7.0f + i;
    scan.points.push_back(p);
  }
  LidarPoint far;
  far.position_m = Eigen::Vector3f(5.0f, 0.0f, 0.0f);
  far.ring = 9;
  scan.points.push_back(far);
  const LidarScan out = VoxelDownsample(scan, 1.0);
  ASSERT_EQ(out.points.size(), 2u);
  EXPECT_EQ(out.points[0].ring, 3);
  EXPECT_FLOAT_EQ(out.points[0].intensity, 7.0f);
  EXPECT_EQ(out.points[1].ring, 9);
  EXPECT_DOUBLE_EQ(out.stamp_s, 12.5);
  EXPECT_TRUE(out.has_time);
  EXPECT_TRUE(out.has_ring);
  EXPECT_EQ(ScanToPointVector(out).size(), 2u);
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
