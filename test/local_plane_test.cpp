#include "multisession_mapper/core/local_plane.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "multisession_mapper/core/se3.h"
#include "synthetic_lidar_scene.h"

namespace multisession_mapper {
namespace core {
namespace {

TEST(LocalPlaneTest, TiltedPlaneGivesItsNormal) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-0.5, 0.5);
  std::normal_distribution<double> noise(0.0, 0.005);
  const Eigen::Vector3d n = Eigen::Vector3d(0.3, -0.2, 1.0).normalized();
  const Eigen::Vector3d e1 = n.unitOrthogonal();
  const Eigen::Vector3d e2 = n.cross(e1);
  CovarianceAccumulator acc;
  for (int i = 0; i < 30; ++i) acc.Add(u(rng) * e1 + u(rng) * e2 + noise(rng) * n);
  Eigen::Vector3d normal;
  ASSERT_TRUE(acc.Normal(LocalPlaneCriteria(), &normal));
  EXPECT_GT(std::abs(normal.dot(n)), 0.999);
}

TEST(LocalPlaneTest, LineBlobAndTooFewPointsGiveNoNormal) {
  Eigen::Vector3d normal;
  CovarianceAccumulator line;
  for (int i = 0; i < 20; ++i) line.Add(Eigen::Vector3d(0.1 * i, 0.0, 0.001 * (i % 2)));
  EXPECT_FALSE(line.Normal(LocalPlaneCriteria(), &normal));

  std::mt19937 rng(4);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  CovarianceAccumulator blob;
  for (int i = 0; i < 200; ++i) blob.Add(Eigen::Vector3d(u(rng), u(rng), u(rng)));
  EXPECT_FALSE(blob.Normal(LocalPlaneCriteria(), &normal));

  CovarianceAccumulator few;
  few.Add(Eigen::Vector3d(0, 0, 0));
  few.Add(Eigen::Vector3d(1, 0, 0));
  few.Add(Eigen::Vector3d(0, 1, 0));
  EXPECT_FALSE(few.Normal(LocalPlaneCriteria(), &normal));  // min_points = 5
}

TEST(LocalPlaneTest, ValidateRejectsBadCriteria) {
  LocalPlaneCriteria c;
  EXPECT_TRUE(c.Validate().ok());
  c.min_points = 2;
  EXPECT_FALSE(c.Validate().ok());
  c = LocalPlaneCriteria();
  c.max_flatness = 0.0;
  EXPECT_FALSE(c.Validate().ok());
}


// Ring-based scan normals: ground and wall patches get their surface normal; a point whose
// ring has no neighbouring ring in the scan (one ring line with depth relief) gets none.
TEST(ScanNormalsTest, SurfaceNormalsFromNeighbouringRingsOnly) {
  test::SyntheticScene scene(1, 0, 1.0, {}, 0.0);
  test::SceneBox wall;
  wall.center = Eigen::Vector3d(20.0, 0.0, 5.0);
  wall.half_size = Eigen::Vector3d(0.5, 30.0, 5.0);
  scene.SetBoxes({wall});
  const auto pose_at = [](double) { return se3::FromXyzRpy(0.0, 0.0, 1.5, 0.0, 0.0, 0.0); };
  const LidarScan scan = test::SimulateVlp16(scene, pose_at, 0.0, 3, 0.025, 1800);
  const ScanNormalConfig config;
  const PointVector normals = EstimateScanNormals(scan, scan.points, config);
  ASSERT_EQ(normals.size(), scan.points.size());
  int ground = 0, ground_ok = 0, on_wall = 0, wall_ok = 0;
  for (std::size_t i = 0; i < scan.points.size(); ++i) {
    const Eigen::Vector3f& p = scan.points[i].position_m;
    if (normals[i].isZero(0.0)) continue;
    if (p.z() < -1.4 && p.head<2>().norm() < 12.0) {
      ++ground;
      ground_ok += std::abs(normals[i].z()) > std::cos(3.0 * M_PI / 180.0) ? 1 : 0;
    } else if (p.x() > 19.0 && p.z() > -1.0) {
      ++on_wall;
      wall_ok += std::abs(normals[i].x()) > std::cos(5.0 * M_PI / 180.0) ? 1 : 0;
    }
  }
  EXPECT_GT(ground, 1000);
  EXPECT_GT(on_wall, 1000);
  EXPECT_GT(ground_ok, 0.97 * ground);
  EXPECT_GT(wall_ok, 0.97 * on_wall);

  // One ring only (the others removed): no point spans two rings, so no normal at all.
  LidarScan one_ring = scan;
  one_ring.points.erase(std::remove_if(one_ring.points.begin(), one_ring.points.end(),
                                       [](const LidarPoint& p) { return p.ring != 9; }),
                        one_ring.points.end());
  ASSERT_GT(one_ring.points.size(), 100u);
  for (const Eigen::Vector3d& n : EstimateScanNormals(one_ring, one_ring.points, config)) {
    EXPECT_TRUE(n.isZero(0.0));
  }
  LidarScan no_ring = scan;
  no_ring.has_ring = false;
  for (const Eigen::Vector3d& n : EstimateScanNormals(no_ring, scan.points, config)) {
    EXPECT_TRUE(n.isZero(0.0));
  }
}

// The neighbour columns wrap around azimuth 0: a point in the first column whose only
// neighbours lie just below 360 deg (and one in the last column with neighbours just above
// 0 deg) still gets its surface's normal. Three rings on a wall at x = 10 m, in three columns
// each: the query's and the two reached across the wrap (5 and 10 bins away).
TEST(ScanNormalsTest, NeighbourColumnsWrapAroundAzimuthZero) {
  const ScanNormalConfig config;
  const double bin_rad = 2.0 * M_PI / config.azimuth_bins;
  for (const int direction : {-1, 1}) {
    // Column centres (in bins from azimuth 0): the query's, then its neighbours'.
    const double query_bins = direction < 0 ? 0.5 : -0.5;
    LidarScan scan;
    scan.has_ring = true;
    for (int ring = 0; ring < 3; ++ring) {
      const double elevation = (ring - 1) * 2.0 * M_PI / 180.0;
      for (const int step : {0, 1, 2}) {
        const double azimuth =
            (query_bins + direction * step * config.column_step) * bin_rad;
        LidarPoint p;
        p.position_m = Eigen::Vector3f(10.0f, static_cast<float>(10.0 * std::tan(azimuth)),
                                       static_cast<float>(10.0 * std::tan(elevation)));
        p.ring = static_cast<std::uint16_t>(ring);
        scan.points.push_back(p);
      }
    }
    const std::vector<LidarPoint> query = {scan.points[3]};  // ring 1, the query's column
    const PointVector normals = EstimateScanNormals(scan, query, config);
    ASSERT_EQ(normals.size(), 1u);
    ASSERT_FALSE(normals[0].isZero(0.0)) << "direction " << direction;
    EXPECT_GT(std::abs(normals[0].x()), std::cos(1.0 * M_PI / 180.0)) << "direction " << direction;
  }
}

TEST(ScanNormalsTest, DropHighPointsOffWallsKeepsGroundWallsAndPointsWithoutNormal) {
  // Sensor frame: ground below, a wall, a crown's leaves and a roof above, a point without
  // a normal above.
  PointVector points = {{5, 0, -1.8}, {5, 1, 2.0}, {4, 2, 3.0}, {6, 0, 2.5}, {3, 3, 2.0},
                        {7, 0, 0.4}};
  PointVector normals = {{0, 0, 1},  {1, 0, 0},  Eigen::Vector3d(0.5, 0, 0.866), {0, 0, -1},
                         {0, 0, 0},  {0, 0.6, 0.8}};
  DropHighPointsOffWalls(0.5, 0.3, &points, &normals);
  ASSERT_EQ(points.size(), 4u);
  ASSERT_EQ(normals.size(), 4u);
  EXPECT_EQ(points[0], Eigen::Vector3d(5, 0, -1.8));  // ground: below the height
  EXPECT_EQ(points[1], Eigen::Vector3d(5, 1, 2.0));   // wall: horizontal normal
  EXPECT_EQ(points[2], Eigen::Vector3d(3, 3, 2.0));   // no normal: left for the ICP to skip
  EXPECT_EQ(points[3], Eigen::Vector3d(7, 0, 0.4));   // tilted, but below the height
  EXPECT_EQ(normals[1], Eigen::Vector3d(1, 0, 0));
  EXPECT_EQ(normals[3], Eigen::Vector3d(0, 0.6, 0.8));
  // An infinite height keeps everything.
  PointVector all = {{0, 0, 9}}, all_normals = {{0, 0, 1}};
  DropHighPointsOffWalls(std::numeric_limits<double>::infinity(), 0.3, &all, &all_normals);
  EXPECT_EQ(all.size(), 1u);
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
