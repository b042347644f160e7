#include "multisession_mapper/core/pcd_scan_io.h"

#include <cmath>
#include <string>
#include <sys/stat.h>

#include <gtest/gtest.h>

namespace multisession_mapper {
namespace core {
namespace {

bool Exists(const std::string& path) {
  struct stat st;
  return stat(path.c_str(), &st) == 0;
}

// A real VLP-16 scan: fields x y z _ intensity ring _ (padding), binary PCD.
TEST(PcdScanIoTest, ReadsRealVlp16ScanWithPaddingAndRing) {
  const std::string path = std::string(MSM_SHARED_DATA_DIR) + "/real/vlp16_indoor/0.pcd";
  if (!Exists(path)) GTEST_SKIP() << "no real data at " << path;
  const StatusOr<LidarScan> scan = LoadPcdScan(path);
  ASSERT_TRUE(scan.ok()) << scan.status().message();
  EXPECT_EQ(scan.value().points.size(), 28221u);  // POINTS in the header
  EXPECT_TRUE(scan.value().has_ring);
  EXPECT_FALSE(scan.value().has_time);
  int rings[16] = {0};
  std::size_t finite = 0;
  double max_range = 0.0;
  for (const LidarPoint& p : scan.value().points) {
    ASSERT_LT(p.ring, 16);
    ++rings[p.ring];
    if (p.position_m.allFinite()) {
      ++finite;
      max_range = std::max(max_range, static_cast<double>(p.position_m.norm()));
    }
    EXPECT_GE(p.intensity, 0.0f);
  }
  for (int r = 0; r < 16; ++r) EXPECT_GT(rings[r], 500) << "ring " << r;  // all 16 beams
  EXPECT_GT(finite, 28000u);
  EXPECT_GT(max_range, 5.0);    // a room and a corridor: metres, not millimetres
  EXPECT_LT(max_range, 130.0);  // nor kilometres (a wrong field offset would show)
}

TEST(PcdScanIoTest, RoundTripKeepsEveryField) {
  LidarScan scan;
  scan.has_ring = true;
  scan.has_time = true;
  for (int i = 0; i < 100; ++i) {
    LidarPoint p;
    p.position_m = Eigen::Vector3f(0.5f * i, -0.25f * i, 0.01f * i);
    p.intensity = static_cast<float>(i % 256);
    p.ring = static_cast<std::uint16_t>(i % 16);
    p.time_s = 0.001f * i;
    scan.points.push_back(p);
  }
  mkdir(MSM_TEST_TMP_DIR, 0755);
  const std::string path = std::string(MSM_TEST_TMP_DIR) + "/pcd_scan_io_roundtrip.pcd";
  ASSERT_TRUE(SavePcdScan(path, scan).ok());
  const StatusOr<LidarScan> loaded = LoadPcdScan(path);
  ASSERT_TRUE(loaded.ok()) << loaded.status().message();
  ASSERT_EQ(loaded.value().points.size(), scan.points.size());
  EXPECT_TRUE(loaded.value().has_ring);
  EXPECT_TRUE(loaded.value().has_time);
  for (std::size_t i = 0; i < scan.points.size(); ++i) {
    EXPECT_EQ(loaded.value().points[i].position_m, scan.points[i].position_m);
    EXPECT_EQ(loaded.value().points[i].ring, scan.points[i].ring);
    EXPECT_FLOAT_EQ(loaded.value().points[i].time_s, scan.points[i].time_s);
    EXPECT_FLOAT_EQ(loaded.value().points[i].intensity, scan.points[i].intensity);
  }
}

TEST(PcdScanIoTest, MissingFileIsAClearError) {
  const StatusOr<LidarScan> scan = LoadPcdScan("/nonexistent/scan.pcd");
  ASSERT_FALSE(scan.ok());
  EXPECT_NE(scan.status().message().find("/nonexistent/scan.pcd"), std::string::npos);
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
