#include "multisession_mapper/core/voxel_occupancy.h"

#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

namespace multisession_mapper {
namespace core {
namespace {

TEST(VoxelOccupancy, OccupiedIsTheOwnVoxelOnly) {
  VoxelOccupancy grid(0.5);
  grid.Add(Eigen::Vector3d(0.1, 0.1, 0.1));
  EXPECT_TRUE(grid.Occupied(Eigen::Vector3d(0.4, 0.2, 0.49)));
  EXPECT_FALSE(grid.Occupied(Eigen::Vector3d(0.6, 0.1, 0.1)));
  EXPECT_FALSE(grid.Occupied(Eigen::Vector3d(-0.1, 0.1, 0.1)));
}

TEST(VoxelOccupancy, NearReachesTheNeighbourVoxelsAndNoFurther) {
  VoxelOccupancy grid(0.5);
  grid.Add(Eigen::Vector3d(0.1, 0.1, 0.1));  // voxel (0, 0, 0)
  EXPECT_TRUE(grid.Near(Eigen::Vector3d(0.2, 0.2, 0.2)));
  EXPECT_TRUE(grid.Near(Eigen::Vector3d(0.9, -0.4, 0.9)));   // voxel (1, -1, 1)
  EXPECT_FALSE(grid.Near(Eigen::Vector3d(1.1, 0.1, 0.1)));   // voxel (2, 0, 0)
  EXPECT_FALSE(grid.Near(Eigen::Vector3d(0.1, -0.6, 0.1)));  // voxel (0, -2, 0)
}

// The propagation of dynamic points relies on this: a set built with AddWithNeighbours answers
// Occupied() exactly as a set built with Add() answers Near(), for every query.
TEST(VoxelOccupancy, DilatedSetAnswersOccupiedAsNear) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> coord(-3.0, 3.0);
  VoxelOccupancy plain(0.2), dilated(0.2);
  for (int i = 0; i < 200; ++i) {
    const Eigen::Vector3d p(coord(rng), coord(rng), coord(rng));
    plain.Add(p);
    dilated.AddWithNeighbours(p);
  }
  int near = 0;
  for (int i = 0; i < 20000; ++i) {
    const Eigen::Vector3d q(coord(rng), coord(rng), coord(rng));
    const bool expected = plain.Near(q);
    near += expected;
    ASSERT_EQ(dilated.Occupied(q), expected) << q.transpose();
  }
  // Both outcomes were exercised.
  EXPECT_GT(near, 1000);
  EXPECT_LT(near, 19000);
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
