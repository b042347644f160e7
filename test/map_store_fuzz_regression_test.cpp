// Regression tests for inputs the map-loader fuzzers (test/fuzz) crashed on, and for the PCD
// header checks added in MapStore's loader because of them. Each case puts the input into a
// small valid map as a submap PCD, with the manifest's size and checksum updated (as a
// deliberately crafted map would have), and expects Load() to refuse it with a Status that
// names the file.
#include <filesystem>
#include <cstring>
#include <fstream>
#include <iomanip>
#include <sstream>
#include <string>

#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include "multisession_mapper/core/checksum.h"
#include "multisession_mapper/core/map_store.h"

namespace multisession_mapper {
namespace core {
namespace {

namespace fs = std::filesystem;
const std::string kDir = std::string(MSM_TEST_TMP_DIR) + "/map_store_fuzz_regression_test";

std::string Hex(std::uint64_t v) {
  std::ostringstream out;
  out << std::hex << std::setw(16) << std::setfill('0') << v;
  return out.str();
}

// A valid one-submap map whose submap file is replaced by `pcd`.
std::string MapWithSubmapFile(const std::string& name, const std::string& pcd) {
  const std::string dir = kDir + "/" + name;
  fs::remove_all(dir);
  MapContents map;
  SessionRecord session;
  session.name = "a";
  session.scans = 1;
  map.sessions.push_back(session);
  Submap submap;
  submap.session = "a";
  submap.id = 0;
  SubmapScanRecord scan;
  scan.stamp_s = 1.0;
  submap.scans.push_back(scan);
  for (int i = 0; i < 5; ++i) submap.points.emplace_back(i, 0.5 * i, 1.0);
  map.submaps.push_back(submap);
  map.graph.SetNodePose(0, Pose3::Identity());
  EXPECT_TRUE(MapStore().Save(map, dir).ok());
  const std::string rel = "submaps/a/0.pcd";
  std::ofstream(dir + "/" + rel, std::ios::binary | std::ios::trunc) << pcd;
  YAML::Node manifest = YAML::LoadFile(dir + "/manifest.yaml");
  manifest["files"][rel]["bytes"] = static_cast<std::uint64_t>(pcd.size());
  manifest["files"][rel]["fnv1a64"] = Hex(Fnv1a64(pcd));
  YAML::Emitter out;
  out << manifest;
  std::ofstream(dir + "/manifest.yaml", std::ios::trunc) << out.c_str() << "\n";
  return dir;
}

void ExpectRefused(const std::string& name, const std::string& pcd, const std::string& reason) {
  const std::string dir = MapWithSubmapFile(name, pcd);
  const StatusOr<MapContents> map = MapStore().Load(dir);
  ASSERT_FALSE(map.ok()) << name << " was accepted";
  EXPECT_NE(map.status().message().find("submaps/a/0.pcd"), std::string::npos)
      << map.status().message();
  EXPECT_NE(map.status().message().find(reason), std::string::npos) << map.status().message();
}

const std::string kHeader =
    "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n";

TEST(MapStoreFuzzRegressionTest, ValidAsciiSubmapStillLoads) {
  const std::string dir = MapWithSubmapFile(
      "valid_ascii", kHeader + "WIDTH 2\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 2\nDATA ascii\n"
                               "1 2 3\n4 5 6\n");
  const StatusOr<MapContents> map = MapStore().Load(dir);
  ASSERT_TRUE(map.ok()) << map.status().message();
  ASSERT_EQ(map.value().submaps.at(0).points.size(), 2u);
  EXPECT_EQ(map.value().submaps[0].points[1], Eigen::Vector3d(4, 5, 6));
}

// fuzz_submap_pcd, first execution: an empty file made PCL's PCDReader::read dereference null.
TEST(MapStoreFuzzRegressionTest, EmptySubmapFileIsRefused) {
  ExpectRefused("empty", "", "no DATA line");
}

TEST(MapStoreFuzzRegressionTest, HeaderWithoutDataLineIsRefused) {
  ExpectRefused("no_data", kHeader + "WIDTH 2\nHEIGHT 1\nPOINTS 2\n", "no DATA line");
}

TEST(MapStoreFuzzRegressionTest, PointsLargerThanTheDataAreRefused) {
  ExpectRefused("short_binary",
                kHeader + "WIDTH 1000000\nHEIGHT 1\nPOINTS 1000000\nDATA binary\n" +
                    std::string(24, '\0'),
                "binary data shorter than POINTS");
  ExpectRefused("short_ascii",
                kHeader + "WIDTH 1000\nHEIGHT 1\nPOINTS 1000\nDATA ascii\n1 2 3\n",
                "fewer data than POINTS");
}

TEST(MapStoreFuzzRegressionTest, InconsistentHeaderIsRefused) {
  ExpectRefused("points_not_product",
                kHeader + "WIDTH 3\nHEIGHT 2\nPOINTS 2\nDATA ascii\n1 2 3\n4 5 6\n",
                "POINTS is not WIDTH x HEIGHT");
  ExpectRefused("size_count_mismatch",
                "VERSION 0.7\nFIELDS x y z\nSIZE 4 4\nTYPE F F F\nWIDTH 1\nHEIGHT 1\nPOINTS 1\n"
                "DATA ascii\n1 2 3\n",
                "differ in length");
  ExpectRefused("no_z", "VERSION 0.7\nFIELDS x y\nSIZE 4 4\nTYPE F F\nWIDTH 1\nHEIGHT 1\n"
                        "POINTS 1\nDATA ascii\n1 2\n",
                "x, y and z");
  ExpectRefused("bad_size", "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 3\nTYPE F F F\nWIDTH 1\n"
                            "HEIGHT 1\nPOINTS 1\nDATA ascii\n1 2 3\n",
                "SIZE");
  ExpectRefused("negative_width", kHeader + "WIDTH -1\nHEIGHT 1\nPOINTS 1\nDATA ascii\n1 2 3\n",
                "bad WIDTH");
  ExpectRefused("unknown_data", kHeader + "WIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA lz4\n1 2 3\n",
                "unknown DATA");
}

TEST(MapStoreFuzzRegressionTest, CompressedSizesThatDoNotAddUpAreRefused) {
  std::string sizes(8, '\0');
  const std::uint32_t compressed = 1u << 30, uncompressed = 24;
  std::memcpy(&sizes[0], &compressed, 4);
  std::memcpy(&sizes[4], &uncompressed, 4);
  ExpectRefused("compressed_too_long",
                kHeader + "WIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA binary_compressed\n" + sizes + "xx",
                "compressed size exceeds the file");
  ExpectRefused("compressed_no_sizes",
                kHeader + "WIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA binary_compressed\n",
                "no size header");
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
