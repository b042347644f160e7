#include "multisession_mapper/core/input_filter.h"

#include <limits>

#include <gtest/gtest.h>

namespace multisession_mapper {
namespace core {
namespace {

LidarPoint MakePoint(float x, float y, float z) {
  LidarPoint p;
  p.position_m = Eigen::Vector3f(x, y, z);
  return p;
}

TEST(InputFilterConfig, DefaultsAreValid) { EXPECT_TRUE(InputFilterConfig().Validate().ok()); }

TEST(InputFilterConfig, RejectsBadRanges) {
  InputFilterConfig c;
  c.min_range_m = -1.0;
  EXPECT_FALSE(c.Validate().ok());
  c = InputFilterConfig();
  c.max_range_m = 0.5;  // below min_range_m
  Status s = c.Validate();
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("max_range_m"), std::string::npos);
  c = InputFilterConfig();
  c.max_range_m = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(c.Validate().ok());
  c = InputFilterConfig();
  c.self_box_enabled = true;
  c.self_box_max_m.x() = c.self_box_min_m.x() - 1.0;
  EXPECT_FALSE(c.Validate().ok());
  EXPECT_FALSE(InputFilter::Create(c).ok());
}

TEST(InputFilter, DropsNonFiniteZeroOutOfRangeAndSelfHits) {
  InputFilterConfig c;
  c.min_range_m = 1.0;
  c.max_range_m = 50.0;
  c.self_box_enabled = true;
  c.self_box_min_m = Eigen::Vector3d(-2.0, -2.0, -2.0);
  c.self_box_max_m = Eigen::Vector3d(-1.0, 2.0, 2.0);  // a box behind the sensor
  StatusOr<InputFilter> filter = InputFilter::Create(c);
  ASSERT_TRUE(filter.ok()) << filter.status().message();

  LidarScan scan;
  scan.stamp_s = 12.5;
  scan.has_ring = true;
  scan.has_time = true;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  scan.points = {MakePoint(5, 0, 0),    MakePoint(nan, 0, 0),  MakePoint(0, inf, 0),
                 MakePoint(0, 0, 0),    MakePoint(0.5, 0, 0),  MakePoint(60, 0, 0),
                 MakePoint(-1.5, 0, 0), MakePoint(10, 10, 1)};
  scan.points[0].ring = 7;
  scan.points[0].time_s = 0.05f;
  scan.points[0].intensity = 33.0f;

  InputFilterStats stats;
  const LidarScan out = filter.value().Apply(scan, &stats);
  ASSERT_EQ(out.points.size(), 2u);
  EXPECT_EQ(stats.input, 8u);
  EXPECT_EQ(stats.non_finite, 2u);
  EXPECT_EQ(stats.out_of_range, 3u);
  EXPECT_EQ(stats.self_hits, 1u);
  EXPECT_EQ(stats.kept, 2u);
  // Attributes and scan metadata survive.
  EXPECT_EQ(out.points[0].ring, 7);
  EXPECT_FLOAT_EQ(out.points[0].time_s, 0.05f);
  EXPECT_FLOAT_EQ(out.points[0].intensity, 33.0f);
  EXPECT_DOUBLE_EQ(out.stamp_s, 12.5);
  EXPECT_TRUE(out.has_ring);
  EXPECT_TRUE(out.has_time);
}

TEST(InputFilter, EmptyScanStaysEmpty) {
  StatusOr<InputFilter> filter = InputFilter::Create(InputFilterConfig());
  ASSERT_TRUE(filter.ok());
  InputFilterStats stats;
  EXPECT_TRUE(filter.value().Apply(LidarScan(), &stats).points.empty());
  EXPECT_EQ(stats.input, 0u);
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
