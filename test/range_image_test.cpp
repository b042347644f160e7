#include "multisession_mapper/core/range_image.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include <gtest/gtest.h>

namespace multisession_mapper {
namespace core {
namespace {

// Sensor 1.8 m above flat ground with a wall at x = 15 m; VLP-16 beams, 0.2 deg azimuth.
LidarScan GroundAndWall(bool with_ring) {
  LidarScan scan;
  scan.has_ring = with_ring;
  for (int col = 0; col < 1800; ++col) {
    const double az = 2.0 * M_PI * col / 1800.0;
    for (int ring = 0; ring < 16; ++ring) {
      const double el = (-15.0 + 2.0 * ring) * M_PI / 180.0;
      const Eigen::Vector3d d(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az),
                              std::sin(el));
      double range = std::numeric_limits<double>::infinity();
      if (d.z() < 0) range = 1.8 / -d.z();
      if (d.x() > 1e-9) {
        const double t = 15.0 / d.x();
        if (1.8 + t * d.z() >= 0.0) range = std::min(range, t);
      }
      if (!(range < 100.0)) continue;
      LidarPoint p;
      p.position_m = (d * range).cast<float>();
      p.ring = static_cast<std::uint16_t>(ring);
      scan.points.push_back(p);
    }
  }
  return scan;
}

Eigen::Vector3d OnBeam(double range_m, double elevation_deg, double azimuth_deg) {
  const double el = elevation_deg * M_PI / 180.0, az = azimuth_deg * M_PI / 180.0;
  return range_m * Eigen::Vector3d(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az),
                                   std::sin(el));
}

TEST(RangeImage, RingElevationsFromRingFieldOrClustering) {
  for (bool with_ring : {true, false}) {
    const RangeImage image(GroundAndWall(with_ring), RangeImageConfig());
    ASSERT_EQ(image.num_rings(), 16u) << "with_ring=" << with_ring;
    EXPECT_NEAR(image.ring_elevations_rad().front(), -15.0 * M_PI / 180.0, 1e-4);
    EXPECT_NEAR(image.ring_elevations_rad().back(), 15.0 * M_PI / 180.0, 1e-4);
  }
}

TEST(RangeImage, OnBeamConsistentSeenThroughOccluded) {
  const RangeImage image(GroundAndWall(true), RangeImageConfig());
  // The +1 deg beam straight ahead hits the wall at ~15 m.
  const double wall = 15.0 / std::cos(1.0 * M_PI / 180.0);
  EXPECT_EQ(image.Check(OnBeam(wall, 1.0, 0.1), 0.3), Visibility::kConsistent);
  EXPECT_EQ(image.Check(OnBeam(wall - 5.0, 1.0, 0.1), 0.3), Visibility::kSeenThrough);
  EXPECT_EQ(image.Check(OnBeam(wall + 5.0, 1.0, 0.1), 0.3), Visibility::kOccluded);
}

// A pole 8 m ahead in GroundAndWall's scan: every return at azimuth -2 to 1.1 deg and
// elevation above -5 deg comes from 8 m (the beams up to 1.0 deg hit it).
LidarScan WithPole(LidarScan scan) {
  for (LidarPoint& p : scan.points) {
    const Eigen::Vector3d d = p.position_m.cast<double>().normalized();
    const double az = std::atan2(d.y(), d.x()) * 180.0 / M_PI;
    if (az > -2.0 && az < 1.1 && std::asin(d.z()) * 180.0 / M_PI > -5.0) {
      p.position_m = (d * 8.0).cast<float>();
    }
  }
  return scan;
}

TEST(RangeImage, ASurfaceInANeighbouringBinGuardsItsEdge) {
  // A point at the pole's side edge, as a later pose sees it: it falls into the 1.2-1.6 deg
  // bin, whose beams just missed the pole and hit the wall 15 m away. The bin before held the
  // pole at 8 m: with the edge guard the point is not seen through; without it, it is. A
  // point 8 m away in open space (3 deg: the wall in all three bins) is seen through either
  // way. The guard is off by default (RangeImageConfig::edge_guard_columns).
  RangeImageConfig config;
  config.edge_guard_columns = 1;
  const RangeImage guarded(WithPole(GroundAndWall(true)), config);
  config.edge_guard_columns = 0;
  const RangeImage unguarded(WithPole(GroundAndWall(true)), config);
  const Eigen::Vector3d edge = OnBeam(8.0, 1.0, 1.5);
  EXPECT_EQ(unguarded.Check(edge, 0.3), Visibility::kSeenThrough);
  EXPECT_EQ(guarded.Check(edge, 0.3), Visibility::kUnknown);
  EXPECT_EQ(guarded.Check(OnBeam(8.0, 1.0, 3.0), 0.3), Visibility::kSeenThrough);
  // Only a surface at the point's range guards it: 12 m away, beyond the pole, it is free.
  EXPECT_EQ(guarded.Check(OnBeam(12.0, 1.0, 1.5), 0.3), Visibility::kSeenThrough);
  EXPECT_EQ(guarded.Check(OnBeam(8.0, 1.0, 0.5), 0.3), Visibility::kConsistent);
}

TEST(RangeImage, NoReturnIsFreeOnlyUpToItsRange) {
  const RangeImage image(GroundAndWall(true), RangeImageConfig());
  // Looking backwards at +5 deg there is nothing: free space, up to no_return_free_range_m
  // (60 m) and in front of the ground that the -3 deg beam measured at 34.4 m (next test).
  EXPECT_EQ(image.Check(OnBeam(10.0, 5.0, 180.0), 0.3), Visibility::kSeenThrough);
  EXPECT_EQ(image.Check(OnBeam(32.0, 5.0, 180.0), 0.3), Visibility::kSeenThrough);
  RangeImageConfig shorter;
  shorter.no_return_free_range_m = 30.0;
  const RangeImage short_image(GroundAndWall(true), shorter);
  EXPECT_EQ(short_image.Check(OnBeam(10.0, 5.0, 180.0), 0.3), Visibility::kSeenThrough);
  EXPECT_EQ(short_image.Check(OnBeam(32.0, 5.0, 180.0), 0.3), Visibility::kUnknown);
}

TEST(RangeImage, GroundBetweenBeamsIsNeverSeenThrough) {
  const RangeImage image(GroundAndWall(true), RangeImageConfig());
  // Ground points behind the sensor at elevations between the beams (grazing angles).
  int seen_through = 0, tested = 0;
  for (double range = 5.0; range < 40.0; range += 0.37) {
    const double el = std::asin(-1.8 / range);
    const Eigen::Vector3d p = OnBeam(range, el * 180.0 / M_PI, 170.0);
    const Visibility v = image.Check(p, 0.3 + 0.02 * range);
    tested += v != Visibility::kUnknown;
    seen_through += v == Visibility::kSeenThrough;
  }
  EXPECT_GT(tested, 10);
  EXPECT_EQ(seen_through, 0);
}

TEST(RangeImage, DeskewedPointsStayInTheirRingsRow) {
  // De-skewing moves points off their beam's cone: here ground points ahead are lifted and
  // those behind lowered by up to 0.3 deg of elevation (0.3 m of forward motion during the
  // sweep, ground 10 m away), more than the 0.1 deg gate. With the ring field each point
  // still fills its own ring's pixel; gated by elevation, the pixels behind stayed empty,
  // read as free space, and the ground there was "seen through".
  LidarScan scan = GroundAndWall(true);
  for (LidarPoint& p : scan.points) {
    const Eigen::Vector3d q = p.position_m.cast<double>();
    if (q.z() > -1.7) continue;  // ground only
    const double horizontal = q.head<2>().norm();
    const double lift = 0.3 * M_PI / 180.0 * q.x() / horizontal;
    const double el = std::atan2(q.z(), horizontal) + lift;
    const double r = q.norm();
    p.position_m = (Eigen::Vector3d(q.x() / horizontal * r * std::cos(el),
                                    q.y() / horizontal * r * std::cos(el), r * std::sin(el)))
                       .cast<float>();
  }
  const RangeImage image(scan, RangeImageConfig());
  ASSERT_EQ(image.num_rings(), 16u);
  // A ground point 11.5 m behind the sensor, on the lowered -9 deg beam: the measured ground.
  const double range = 1.8 / std::sin(9.0 * M_PI / 180.0);
  const Eigen::Vector3d ground = OnBeam(range, -9.0 - 0.3, 180.0);
  EXPECT_EQ(image.Check(ground, 0.3 + 0.02 * range), Visibility::kConsistent);
  // Something floating 4 m in front of that ground is still seen through.
  EXPECT_EQ(image.Check(OnBeam(range - 4.0, -9.0 - 0.3, 180.0), 0.3), Visibility::kSeenThrough);
}

TEST(RangeImage, NoReturnIsFreeOnlyInFrontOfTheSurfaceBelow) {
  RangeImageConfig config;
  config.no_return_free_range_m = 60.0;
  const RangeImage image(GroundAndWall(true), config);
  // Backwards the +1 deg beam returns nothing; the -3 deg beam below it hits the ground at
  // 34 m. In front of that the empty beam is free space; beyond it, it passed over the ground.
  const double ground_below = 1.8 / std::sin(3.0 * M_PI / 180.0);
  EXPECT_EQ(image.Check(OnBeam(ground_below - 10.0, 1.0, 180.0), 0.3), Visibility::kSeenThrough);
  EXPECT_EQ(image.Check(OnBeam(ground_below + 6.0, 1.0, 180.0), 0.3), Visibility::kUnknown);
}

TEST(RangeImage, GroundSeenFromATiltedPoseIsNotSeenThrough) {
  // Ground 19.5 m behind the sensor (elevation -5.3 deg), queried from a pose tilted by
  // 0.22 deg: it lands on the -5 deg beam, which measured the ground at 20.65 m, 1.15 m
  // behind it. The range slope of that ground (dr/de ~ 170 m/rad) widens the margin.
  const RangeImage image(GroundAndWall(true), RangeImageConfig());
  const double range = 19.5;
  const double el_deg = std::asin(-1.8 / range) * 180.0 / M_PI + 0.22;
  const double margin = 0.3 + 0.02 * range;
  EXPECT_NE(image.Check(OnBeam(range, el_deg, 180.0), margin), Visibility::kSeenThrough);
  RangeImageConfig no_slope;
  no_slope.angular_uncertainty_rad = 0.0;
  EXPECT_EQ(RangeImage(GroundAndWall(true), no_slope).Check(OnBeam(range, el_deg, 180.0), margin),
            Visibility::kSeenThrough);
  // A car 12 m away in that direction (the beam now reaches the ground) is seen through.
  EXPECT_EQ(image.Check(OnBeam(12.0, -5.0, 180.0), 0.3 + 0.02 * 12.0), Visibility::kSeenThrough);
}

TEST(RangeImage, PointAboveTheFieldOfViewIsUnknown) {
  const RangeImage image(GroundAndWall(true), RangeImageConfig());
  EXPECT_EQ(image.Check(OnBeam(5.0, 40.0, 0.0), 0.3), Visibility::kUnknown);
}

TEST(RangeImage, RingLookupIsTheBinarySearchOverTheRingTangents) {
  for (bool with_ring : {true, false}) {
    const RangeImage image(GroundAndWall(with_ring), RangeImageConfig());
    std::vector<double> tangents;
    for (const double elevation : image.ring_elevations_rad()) {
      tangents.push_back(std::tan(elevation));
    }
    std::vector<double> queries = {-1e6, -10.0, -1.0, 0.0, 1.0, 10.0, 1e6};
    for (const double t : tangents) {  // each ring's tangent and its floating-point neighbours
      queries.push_back(t);
      queries.push_back(std::nextafter(t, -1e9));
      queries.push_back(std::nextafter(t, 1e9));
    }
    for (int k = 0; k <= 200000; ++k) queries.push_back(-0.4 + 0.8 * k / 200000.0);
    for (const double q : queries) {
      const int expected = static_cast<int>(
          std::lower_bound(tangents.begin(), tangents.end(), q) - tangents.begin());
      ASSERT_EQ(image.FirstRingAtOrAbove(q), expected) << "tangent " << q;
    }
  }
}

TEST(RangeImage, ConfigValidation) {
  RangeImageConfig c;
  EXPECT_TRUE(c.Validate().ok());
  c.azimuth_resolution_rad = 0.0;
  EXPECT_FALSE(c.Validate().ok());
  c = RangeImageConfig();
  c.no_return_free_range_m = -1.0;
  EXPECT_FALSE(c.Validate().ok());
  c = RangeImageConfig();
  c.angular_uncertainty_rad = -0.001;
  EXPECT_FALSE(c.Validate().ok());
  c = RangeImageConfig();
  c.edge_guard_columns = -1;
  EXPECT_FALSE(c.Validate().ok());
}

// GroundAndWall with a wall segment 6 m away at azimuths 30-70 deg only (positive y), so that
// the scene is not symmetric about the x axis: a wrong azimuth sign changes the answers.
LidarScan GroundAndWallAndSideWall() {
  LidarScan scan = GroundAndWall(true);
  for (LidarPoint& p : scan.points) {
    const Eigen::Vector3d q = p.position_m.cast<double>();
    const double azimuth_deg = std::atan2(q.y(), q.x()) * 180.0 / M_PI;
    const double elevation_deg = std::atan2(q.z(), q.head<2>().norm()) * 180.0 / M_PI;
    if (azimuth_deg >= 30.0 && azimuth_deg <= 70.0 && elevation_deg >= -5.0) {
      p.position_m = (q.normalized() * 6.0).cast<float>();
    }
  }
  return scan;
}

RangeImage::Batch BatchFor(const Eigen::Isometry3d& T_sensor_frame, double max_range_m) {
  RangeImage::Batch batch;
  batch.R_sensor_frame = T_sensor_frame.linear().cast<float>();
  batch.t_sensor_frame = T_sensor_frame.translation().cast<float>();
  batch.max_range_m = max_range_m;
  batch.margin_base_m = 0.3;
  batch.margin_per_m = 0.02;
  return batch;
}

TEST(RangeImage, CheckManyAgreesWithCheck) {
  // Points all around the sensor at 2-70 m, given in a frame rotated and shifted against the
  // sensor's (as submap voxels are): CheckMany must judge them as Check does, apart from the
  // few whose direction lies on a bin's edge (CheckMany computes directions in float), and
  // leave those beyond max_range_m unknown.
  const RangeImage image(GroundAndWallAndSideWall(), RangeImageConfig());
  Eigen::Isometry3d T_sensor_frame = Eigen::Isometry3d::Identity();
  T_sensor_frame.linear() = Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ()).toRotationMatrix() *
                            Eigen::AngleAxisd(0.01, Eigen::Vector3d::UnitX()).toRotationMatrix();
  T_sensor_frame.translation() = Eigen::Vector3d(3.0, -2.0, 0.1);
  std::vector<float> x, y, z;
  std::vector<Eigen::Vector3d> in_sensor;
  std::uint64_t state = 12345;
  const auto uniform = [&state](double low, double high) {
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    return low + (high - low) * static_cast<double>(state >> 11) / 9007199254740992.0;
  };
  for (int i = 0; i < 20000; ++i) {
    const Eigen::Vector3d p_sensor =
        OnBeam(uniform(2.0, 70.0), uniform(-16.0, 16.0), uniform(-180.0, 180.0));
    const Eigen::Vector3f p_frame = (T_sensor_frame.inverse() * p_sensor).cast<float>();
    x.push_back(p_frame.x());
    y.push_back(p_frame.y());
    z.push_back(p_frame.z());
    in_sensor.push_back(T_sensor_frame * p_frame.cast<double>());
  }
  std::vector<Visibility> out(x.size());
  std::vector<float> ranges(x.size());
  image.CheckMany(BatchFor(T_sensor_frame, 60.0), x.data(), y.data(), z.data(), x.size(),
                  out.data(), ranges.data());
  int differ = 0, beyond = 0, side_wall = 0;
  int counts[4] = {0, 0, 0, 0};
  for (std::size_t i = 0; i < x.size(); ++i) {
    const double range = in_sensor[i].norm();
    ASSERT_NEAR(ranges[i], range, 1e-4);
    if (range > 60.0 + 1e-3) {
      ++beyond;
      EXPECT_EQ(out[i], Visibility::kUnknown);
      continue;
    }
    if (range < 60.0 - 1e-3) {
      const Visibility expected = image.Check(in_sensor[i], range, 0.3 + 0.02 * range);
      differ += out[i] != expected;
      // Behind the side wall (positive y only): occluded there, not in the mirrored directions.
      const double azimuth_deg = std::atan2(in_sensor[i].y(), in_sensor[i].x()) * 180.0 / M_PI;
      side_wall += expected == Visibility::kOccluded && azimuth_deg > 32.0 &&
                   azimuth_deg < 68.0 && range > 8.0;
    }
    ++counts[static_cast<int>(out[i])];
  }
  EXPECT_GT(beyond, 1000);
  EXPECT_GT(side_wall, 300);  // the asymmetric part of the scene is exercised
  EXPECT_LE(differ, 10) << counts[0] << " " << counts[1] << " " << counts[2] << " " << counts[3];
  for (const int count : counts) EXPECT_GT(count, 100) << "differ " << differ;  // each occurs
}

TEST(RangeImage, CheckManyEdgeCases) {
  const RangeImage image(GroundAndWall(true), RangeImageConfig());
  const Eigen::Isometry3d identity = Eigen::Isometry3d::Identity();
  // Straight above the sensor (no ring there), on the wall ahead, and 70 m ahead at +1 deg
  // (behind the wall: occluded).
  const double wall = 15.0 / std::cos(1.0 * M_PI / 180.0);
  const Eigen::Vector3d points[] = {Eigen::Vector3d(0.0, 0.0, 5.0), OnBeam(wall, 1.0, 0.1),
                                    OnBeam(70.0, 1.0, 0.1)};
  std::vector<float> x, y, z;
  for (const Eigen::Vector3d& p : points) {
    x.push_back(static_cast<float>(p.x()));
    y.push_back(static_cast<float>(p.y()));
    z.push_back(static_cast<float>(p.z()));
  }
  Visibility out[3];
  float ranges[3];
  // Without a range limit (the default: infinite) every point is judged as Check judges it.
  RangeImage::Batch unlimited = BatchFor(identity, 60.0);
  unlimited.max_range_m = RangeImage::Batch().max_range_m;
  ASSERT_FALSE(std::isfinite(unlimited.max_range_m));
  image.CheckMany(unlimited, x.data(), y.data(), z.data(), 3, out, ranges);
  EXPECT_EQ(out[0], Visibility::kUnknown);
  EXPECT_EQ(out[1], Visibility::kConsistent);
  EXPECT_EQ(out[2], Visibility::kOccluded);
  EXPECT_EQ(image.Check(points[2], 70.0, 0.3 + 0.02 * 70.0), Visibility::kOccluded);
  // With a 60 m limit the far point is not judged.
  image.CheckMany(BatchFor(identity, 60.0), x.data(), y.data(), z.data(), 3, out, ranges);
  EXPECT_EQ(out[1], Visibility::kConsistent);
  EXPECT_EQ(out[2], Visibility::kUnknown);
  // No points: nothing is written.
  out[0] = Visibility::kSeenThrough;
  image.CheckMany(unlimited, x.data(), y.data(), z.data(), 0, out, ranges);
  EXPECT_EQ(out[0], Visibility::kSeenThrough);
  // An image without rings (an empty scan) knows nothing.
  const RangeImage empty{LidarScan(), RangeImageConfig()};
  ASSERT_EQ(empty.num_rings(), 0u);
  empty.CheckMany(unlimited, x.data(), y.data(), z.data(), 3, out, ranges);
  for (const Visibility v : out) EXPECT_EQ(v, Visibility::kUnknown);
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
