#include "multisession_mapper/core/ray_voxel_grid.h"

#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

namespace multisession_mapper {
namespace core {
namespace {

TEST(RayVoxelGridTest, RejectsBadGeometry) {
  EXPECT_FALSE(RayVoxelGrid::Create(0.0, Eigen::Vector3d::Zero(), Eigen::Vector3d::Ones()).ok());
  EXPECT_FALSE(RayVoxelGrid::Create(0.1, Eigen::Vector3d::Ones(), Eigen::Vector3d::Zero()).ok());
  EXPECT_FALSE(
      RayVoxelGrid::Create(1e-6, Eigen::Vector3d::Zero(), Eigen::Vector3d::Constant(1e4)).ok());
}

TEST(RayVoxelGridTest, TouchAllocatesAndFindSeesTheSameCell) {
  StatusOr<RayVoxelGrid> grid =
      RayVoxelGrid::Create(0.2, Eigen::Vector3d(-10, -10, -2), Eigen::Vector3d(10, 10, 5));
  ASSERT_TRUE(grid.ok());
  RayVoxelGrid& g = grid.value();
  const Eigen::Vector3i key = g.KeyOf(Eigen::Vector3d(1.05, -3.3, 0.5));
  EXPECT_EQ(g.Find(key), nullptr);
  g.Touch(key)->flags = 5;
  ASSERT_NE(g.Find(key), nullptr);
  EXPECT_EQ(g.Find(key)->flags, 5);
  ASSERT_NE(g.Find(key - Eigen::Vector3i(1, 0, 0)), nullptr);  // same block
  EXPECT_EQ(g.Find(key - Eigen::Vector3i(1, 0, 0))->flags, 0);  // untouched cell
  EXPECT_EQ(g.Touch(Eigen::Vector3i(-1, 0, 0)), nullptr);
  EXPECT_FALSE(g.Contains(Eigen::Vector3d(11.0, 0.0, 0.0)));
  // The centre of the voxel: 1.05 lies in [1.0, 1.2), -3.3 in [-3.4, -3.2), 0.5 in [0.4, 0.6).
  EXPECT_TRUE(g.CentreOf(key).isApprox(Eigen::Vector3d(1.1, -3.3, 0.5), 1e-9));
  EXPECT_EQ(g.KeyOf(g.CentreOf(key + Eigen::Vector3i(0, 0, -3))), key + Eigen::Vector3i(0, 0, -3));
}

// Touches one cell in every block so that the traversal visits every voxel.
void TouchAllBlocks(RayVoxelGrid* g, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  const double step = 8 * g->voxel_size_m();
  for (double x = lo.x(); x <= hi.x() + step; x += step) {
    for (double y = lo.y(); y <= hi.y() + step; y += step) {
      for (double z = lo.z(); z <= hi.z() + step; z += step) {
        g->Touch(g->KeyOf(Eigen::Vector3d(x, y, z)));
      }
    }
  }
}

struct Visit {
  Eigen::Vector3i key;
  double entry_m;
  bool flagged;
};

// Keys of the visited voxels, derived from the entry distances (midpoint of each cut).
std::vector<Visit> Walk(RayVoxelGrid* g, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                        bool dense) {
  std::vector<double> entries;
  std::vector<bool> flagged;
  g->Traverse(a, b, [&](RayVoxelGrid::Cell* cell, double entry_m) {
    EXPECT_TRUE(!dense || cell != nullptr);
    entries.push_back(entry_m);
    flagged.push_back(cell != nullptr && cell->flags == 1);
    return true;
  });
  const double length = (b - a).norm();
  std::vector<Visit> visits;
  for (std::size_t i = 0; i < entries.size(); ++i) {
    const double exit = i + 1 < entries.size() ? entries[i + 1] : length;
    EXPECT_LE(entries[i], exit + 1e-9);
    visits.push_back({g->KeyOf(a + (b - a) * ((entries[i] + exit) / 2.0 / length)), entries[i],
                      flagged[i]});
  }
  return visits;
}

// Every traversal of a fully allocated grid is a face-connected chain of voxels from the
// start voxel to the end voxel with increasing entry distances.
TEST(RayVoxelGridTest, TraversalIsAConnectedChainAlongTheSegment) {
  const Eigen::Vector3d lo(-20, -20, -5), hi(20, 20, 10);
  StatusOr<RayVoxelGrid> grid = RayVoxelGrid::Create(0.25, lo, hi);
  ASSERT_TRUE(grid.ok());
  RayVoxelGrid& g = grid.value();
  TouchAllBlocks(&g, lo, hi);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-15.0, 15.0), uz(-4.0, 9.0);
  for (int trial = 0; trial < 300; ++trial) {
    const Eigen::Vector3d a(u(rng), u(rng), uz(rng)), b(u(rng), u(rng), uz(rng));
    const std::vector<Visit> visits = Walk(&g, a, b, true);
    ASSERT_FALSE(visits.empty());
    EXPECT_EQ(visits.front().key, g.KeyOf(a));
    EXPECT_EQ(visits.back().key, g.KeyOf(b));
    EXPECT_NEAR(visits.front().entry_m, 0.0, 1e-9);
    for (std::size_t i = 1; i < visits.size(); ++i) {
      EXPECT_EQ((visits[i].key - visits[i - 1].key).cwiseAbs().sum(), 1) << "trial " << trial;
    }
    // Voxel count of a 3D DDA: 1 + number of grid planes crossed.
    EXPECT_EQ(static_cast<int>(visits.size()), 1 + (g.KeyOf(b) - g.KeyOf(a)).cwiseAbs().sum());
  }
}

// Skipping the blocks that were never touched finds the same occupied voxels at the same
// distances as the voxel-by-voxel walk.
TEST(RayVoxelGridTest, SkippingEmptyBlocksMissesNoTouchedVoxel) {
  const Eigen::Vector3d lo(-20, -20, -5), hi(20, 20, 10);
  StatusOr<RayVoxelGrid> sparse = RayVoxelGrid::Create(0.25, lo, hi);
  StatusOr<RayVoxelGrid> dense = RayVoxelGrid::Create(0.25, lo, hi);
  ASSERT_TRUE(sparse.ok() && dense.ok());
  TouchAllBlocks(&dense.value(), lo, hi);
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> u(-15.0, 15.0), uz(-4.0, 9.0);
  // Occupied voxels along a few walls, as a scene would have them.
  for (int i = 0; i < 20000; ++i) {
    const Eigen::Vector3d p(u(rng), (i % 4) * 5.0 - 7.5 + 0.05 * u(rng), uz(rng));
    sparse.value().Touch(sparse.value().KeyOf(p))->flags = 1;
    dense.value().Touch(dense.value().KeyOf(p))->flags = 1;
  }
  int flagged_total = 0;
  for (int trial = 0; trial < 300; ++trial) {
    const Eigen::Vector3d a(u(rng), u(rng), uz(rng)), b(u(rng), u(rng), uz(rng));
    std::vector<Visit> from_dense, from_sparse;
    for (const Visit& v : Walk(&dense.value(), a, b, true)) {
      if (v.flagged) from_dense.push_back(v);
    }
    for (const Visit& v : Walk(&sparse.value(), a, b, false)) {
      if (v.flagged) from_sparse.push_back(v);
    }
    ASSERT_EQ(from_sparse.size(), from_dense.size()) << "trial " << trial;
    for (std::size_t i = 0; i < from_dense.size(); ++i) {
      EXPECT_EQ(from_sparse[i].key, from_dense[i].key);
      EXPECT_NEAR(from_sparse[i].entry_m, from_dense[i].entry_m, 1e-6);
    }
    flagged_total += static_cast<int>(from_dense.size());
  }
  EXPECT_GT(flagged_total, 300);  // the walls were really crossed
}

TEST(RayVoxelGridTest, VisitorCanStopAndSeesTouchedCells) {
  StatusOr<RayVoxelGrid> grid =
      RayVoxelGrid::Create(0.5, Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(10, 10, 10));
  ASSERT_TRUE(grid.ok());
  RayVoxelGrid& g = grid.value();
  g.Touch(g.KeyOf(Eigen::Vector3d(5.2, 1.2, 1.2)))->flags = 1;
  double hit_at = -1.0;
  int visited = 0;
  g.Traverse(Eigen::Vector3d(0.2, 1.2, 1.2), Eigen::Vector3d(9.8, 1.2, 1.2),
             [&](RayVoxelGrid::Cell* cell, double entry_m) {
               ++visited;
               if (cell != nullptr && cell->flags == 1) {
                 hit_at = entry_m;
                 return false;
               }
               return true;
             });
  EXPECT_NEAR(hit_at, 4.8, 1e-9);  // voxel [5.0, 5.5) entered 4.8 m from x = 0.2
  // The empty first block (x < 4 m) once, then voxels [4.0, 4.5), [4.5, 5.0), [5.0, 5.5).
  EXPECT_EQ(visited, 4);
  // A segment that starts outside is clipped to the grid; it only crosses the empty block.
  visited = 0;
  g.Traverse(Eigen::Vector3d(-5.0, 1.2, 1.2), Eigen::Vector3d(0.7, 1.2, 1.2),
             [&](RayVoxelGrid::Cell* cell, double entry_m) {
               EXPECT_EQ(cell, nullptr);
               EXPECT_NEAR(entry_m, 5.0, 1e-9);
               ++visited;
               return true;
             });
  EXPECT_EQ(visited, 1);
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
