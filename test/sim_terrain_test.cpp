#include "multisession_mapper/sim/terrain.h"

#include <cmath>

#include <gtest/gtest.h>

#include "multisession_mapper/sim/counter_rng.h"

namespace multisession_mapper {
namespace sim {
namespace {

TerrainGrid PlaneGrid(double a, double b, double c) {
  TerrainGrid g;
  g.origin_m = Eigen::Vector2d(-20, -20);
  g.resolution_m = 2.0;
  g.cols = 21;
  g.rows = 21;
  for (int r = 0; r < g.rows; ++r) {
    for (int col = 0; col < g.cols; ++col) {
      const double x = g.origin_m.x() + col * g.resolution_m;
      const double y = g.origin_m.y() + r * g.resolution_m;
      g.heights_m.push_back(static_cast<float>(a * x + b * y + c));
    }
  }
  g.materials.assign(20 * 20, 0);
  g.materials[0] = 1;
  return g;
}

TEST(SimTerrainTest, PlaneIsReproducedExactly) {
  auto terrain = Terrain::Create(PlaneGrid(0.05, -0.03, 1.0));
  ASSERT_TRUE(terrain.ok()) << terrain.status().message();
  CounterRng rng(3);
  for (int k = 0; k < 100; ++k) {
    const double x = rng.Uniform(-19, 19), y = rng.Uniform(-19, 19);
    EXPECT_NEAR(terrain.value().Height(x, y), 0.05 * x - 0.03 * y + 1.0, 1e-5);
  }
  const Eigen::Vector3d n = terrain.value().Normal(3.3, -4.1);
  EXPECT_NEAR(n.x(), -0.05 / std::sqrt(1 + 0.05 * 0.05 + 0.03 * 0.03), 1e-6);
  EXPECT_EQ(terrain.value().Material(-19.5, -19.5), GroundMaterial::kAsphalt);
  EXPECT_EQ(terrain.value().Material(10, 10), GroundMaterial::kGrass);
}

TEST(SimTerrainTest, CellIntersectionAgreesWithHeight) {
  TerrainGrid g = PlaneGrid(0.0, 0.0, 0.0);
  CounterRng rng(5);
  for (float& h : g.heights_m) h = static_cast<float>(rng.Uniform(-0.5, 0.5));
  auto terrain = Terrain::Create(g);
  ASSERT_TRUE(terrain.ok());
  const Terrain& t = terrain.value();
  int hits = 0;
  for (int k = 0; k < 500; ++k) {
    // Straight down onto a random point: the hit lies at Height(x, y).
    const double x = rng.Uniform(-19.9, 19.9), y = rng.Uniform(-19.9, 19.9);
    Ray ray;
    ray.origin = Eigen::Vector3d(x, y, 10.0);
    ray.direction = Eigen::Vector3d(0.01, 0.0, -1.0).normalized();
    const int cx = static_cast<int>(std::floor((x + 20) / 2.0));
    const int cy = static_cast<int>(std::floor((y + 20) / 2.0));
    const double d = t.IntersectCell(cx, cy, ray, 0.0, 100.0);
    if (d < 0.0) continue;  // the slanted ray may leave the cell first
    ++hits;
    const Eigen::Vector3d p = ray.origin + ray.direction * d;
    EXPECT_NEAR(p.z(), t.Height(p.x(), p.y()), 1e-6);
  }
  EXPECT_GT(hits, 400);
}

TEST(SimTerrainTest, RejectsInconsistentGrids) {
  TerrainGrid g = PlaneGrid(0, 0, 0);
  g.heights_m.pop_back();
  EXPECT_FALSE(Terrain::Create(g).ok());
  g = PlaneGrid(0, 0, 0);
  g.resolution_m = 0.0;
  EXPECT_FALSE(Terrain::Create(g).ok());
  g = PlaneGrid(0, 0, 0);
  g.heights_m[3] = std::nanf("");
  EXPECT_FALSE(Terrain::Create(g).ok());
}

}  // namespace
}  // namespace sim
}  // namespace multisession_mapper
