#include "multisession_mapper/core/range_image.h"

#include <cmath>
#include <limits>

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

TEST(RangeImage, NoReturnIsFreeOnlyUpToItsRange) {
  const RangeImage image(GroundAndWall(true), RangeImageConfig());
  // Looking backwards at +5 deg there is nothing: free space, up to no_return_free_range_m.
  EXPECT_EQ(image.Check(OnBeam(10.0, 5.0, 180.0), 0.3), Visibility::kSeenThrough);
  EXPECT_EQ(image.Check(OnBeam(50.0, 5.0, 180.0), 0.3), Visibility::kUnknown);
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

TEST(RangeImage, PointAboveTheFieldOfViewIsUnknown) {
  const RangeImage image(GroundAndWall(true), RangeImageConfig());
  EXPECT_EQ(image.Check(OnBeam(5.0, 40.0, 0.0), 0.3), Visibility::kUnknown);
}

TEST(RangeImage, ConfigValidation) {
  RangeImageConfig c;
  EXPECT_TRUE(c.Validate().ok());
  c.azimuth_resolution_rad = 0.0;
  EXPECT_FALSE(c.Validate().ok());
  c = RangeImageConfig();
  c.no_return_free_range_m = -1.0;
  EXPECT_FALSE(c.Validate().ok());
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
