// Bad sensor input for the offline runner (issue 9, item 1): every case writes a small bag with
// the rosbag C++ API (derived from a short simulated session), runs the offline_mapper binary
// and checks its exit code, the message naming the problem and, where the run fails, that no
// map was written and that an existing map directory is byte-for-byte unchanged.
#include <sys/wait.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <ros/time.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/PointCloud2.h>
#include <std_msgs/String.h>

#include "multisession_mapper/core/map_store.h"

namespace multisession_mapper {
namespace {

namespace fs = std::filesystem;
using sensor_msgs::PointCloud2;

const std::string kMapper = MSM_OFFLINE_MAPPER;
const std::string kSimulator = MSM_SIMULATE_CAMPUS;
const std::string kTmp = std::string(MSM_TEST_TMP_DIR) + "/offline_mapper_bad_input_test";
const std::string kTopic = "/velodyne_points";
constexpr int kScans = 40;

std::string ReadText(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream buffer;
  buffer << in.rdbuf();
  return buffer.str();
}

// Every file of a directory tree with its bytes (empty when the directory does not exist).
std::map<std::string, std::string> Snapshot(const fs::path& dir) {
  std::map<std::string, std::string> files;
  std::error_code ec;
  if (!fs::exists(dir, ec)) return files;
  for (const auto& entry : fs::recursive_directory_iterator(dir)) {
    if (entry.is_regular_file()) files[fs::relative(entry.path(), dir).string()] = ReadText(entry.path());
  }
  return files;
}

struct MapperRun {
  int exit_code = -1;
  std::string log;  // stderr and stdout
};

MapperRun RunMapper(const std::string& bag, const std::string& map, const std::string& extra = "") {
  const std::string log = kTmp + "/last_run.log";
  const std::string cmd =
      kMapper + " --bag " + bag + " --map " + map + " --quiet " + extra + " > " + log + " 2>&1";
  const int status = std::system(cmd.c_str());
  MapperRun run;
  run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  run.log = ReadText(log);
  return run;
}

class OfflineMapperBadInputTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    ros::Time::init();
    fs::remove_all(kTmp);
    fs::create_directories(kTmp);
    const std::string cmd = kSimulator + " --profile tiny --sessions 1 --seed 2 --max-scans " +
                            std::to_string(kScans) + " --compression none --quiet --out " + kTmp +
                            "/sim > " + kTmp + "/sim.log 2>&1";
    ASSERT_EQ(std::system(cmd.c_str()), 0) << ReadText(kTmp + "/sim.log");
    rosbag::Bag bag;
    bag.open(kTmp + "/sim/s00.bag", rosbag::bagmode::Read);
    for (const rosbag::MessageInstance& m : rosbag::View(bag, rosbag::TopicQuery(kTopic))) {
      PointCloud2::ConstPtr msg = m.instantiate<PointCloud2>();
      ASSERT_TRUE(msg != nullptr);
      clouds_->push_back(*msg);
    }
    ASSERT_EQ(clouds_->size(), static_cast<std::size_t>(kScans));
    // The existing map that failing runs must leave untouched.
    const MapperRun first = RunMapper(kTmp + "/sim/s00.bag", kTmp + "/existing_map", "--max-scans 20");
    ASSERT_EQ(first.exit_code, 0) << first.log;
  }

  static std::vector<PointCloud2> Clouds() { return *clouds_; }

  // Writes `clouds` on `topic`, each at its header stamp (or the previous time when that is
  // invalid, so that the bag's own order is the given one).
  static std::string WriteBag(const std::string& name, const std::vector<PointCloud2>& clouds,
                              const std::string& topic = kTopic) {
    const std::string path = kTmp + "/" + name + ".bag";
    rosbag::Bag bag;
    bag.open(path, rosbag::bagmode::Write);
    ros::Time t(1000.0);
    for (const PointCloud2& cloud : clouds) {
      if (!cloud.header.stamp.isZero() && cloud.header.stamp > t) t = cloud.header.stamp;
      bag.write(topic, t, cloud);
      t += ros::Duration(1e-6);
    }
    bag.close();
    return path;
  }

  // Runs the mapper on `bag` into a new map directory; returns the run.
  static MapperRun MapInto(const std::string& bag, const std::string& map_name) {
    fs::remove_all(kTmp + "/" + map_name);
    return RunMapper(bag, kTmp + "/" + map_name);
  }

  // Runs the mapper on `bag` into a copy of the existing map and checks that a failing run
  // leaves it byte-for-byte unchanged.
  static void ExpectExistingMapUnchanged(const std::string& bag, const std::string& name) {
    const std::string map = kTmp + "/" + name + "_existing";
    fs::remove_all(map);
    fs::copy(kTmp + "/existing_map", map, fs::copy_options::recursive);
    const auto before = Snapshot(map);
    ASSERT_FALSE(before.empty());
    const MapperRun run = RunMapper(bag, map);
    EXPECT_NE(run.exit_code, 0) << run.log;
    EXPECT_TRUE(Snapshot(map) == before) << "the existing map was modified by a failing run";
    EXPECT_FALSE(fs::exists(map + ".new")) << "a failing run left a partial save";
  }

  static core::MapContents LoadMap(const std::string& map_name) {
    core::StatusOr<core::MapContents> map = core::MapStore().Load(kTmp + "/" + map_name);
    EXPECT_TRUE(map.ok()) << map.status().message();
    return map.ok() ? map.value() : core::MapContents();
  }

  static std::vector<PointCloud2>* clouds_;
};

std::vector<PointCloud2>* OfflineMapperBadInputTest::clouds_ = new std::vector<PointCloud2>();

PointCloud2 EmptyLike(const PointCloud2& cloud) {
  PointCloud2 empty = cloud;
  empty.width = 0;
  empty.row_step = 0;
  empty.data.clear();
  return empty;
}

PointCloud2 AllNaN(const PointCloud2& cloud) {
  PointCloud2 out = cloud;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (const auto& field : cloud.fields) {
    if (field.name != "x" && field.name != "y" && field.name != "z") continue;
    for (std::size_t i = 0; i < static_cast<std::size_t>(cloud.width) * cloud.height; ++i) {
      std::memcpy(&out.data[i * cloud.point_step + field.offset], &nan, sizeof(float));
    }
  }
  out.is_dense = false;
  return out;
}

std::size_t CountOccurrences(const std::string& text, const std::string& what) {
  std::size_t count = 0;
  for (std::size_t pos = text.find(what); pos != std::string::npos; pos = text.find(what, pos + 1)) {
    ++count;
  }
  return count;
}

TEST_F(OfflineMapperBadInputTest, CleanBagMapsEveryScan) {
  const MapperRun run = MapInto(WriteBag("clean", Clouds()), "clean_map");
  ASSERT_EQ(run.exit_code, 0) << run.log;
  const core::MapContents map = LoadMap("clean_map");
  ASSERT_EQ(map.sessions.size(), 1u);
  EXPECT_EQ(map.sessions[0].scans, static_cast<std::uint32_t>(kScans));
}

TEST_F(OfflineMapperBadInputTest, EmptyCloudsAreSkippedWithAMessage) {
  std::vector<PointCloud2> clouds = Clouds();
  for (int i = 3; i < kScans; i += 10) clouds[i] = EmptyLike(clouds[i]);  // 4 empty scans
  const MapperRun run = MapInto(WriteBag("some_empty", clouds), "some_empty_map");
  ASSERT_EQ(run.exit_code, 0) << run.log;
  EXPECT_EQ(CountOccurrences(run.log, "survived the input filter"), 4u) << run.log;
  EXPECT_NE(run.log.find("scan 3 skipped"), std::string::npos) << run.log;
  EXPECT_EQ(LoadMap("some_empty_map").sessions.at(0).scans, static_cast<std::uint32_t>(kScans - 4));
}

TEST_F(OfflineMapperBadInputTest, OnlyEmptyCloudsStopWithAnErrorAndWriteNoMap) {
  std::vector<PointCloud2> clouds = Clouds();
  for (PointCloud2& cloud : clouds) cloud = EmptyLike(cloud);
  const std::string bag = WriteBag("all_empty", clouds);
  const MapperRun run = MapInto(bag, "all_empty_map");
  EXPECT_EQ(run.exit_code, 1) << run.log;
  EXPECT_NE(run.log.find("produced no submap (no usable scan)"), std::string::npos) << run.log;
  EXPECT_FALSE(fs::exists(kTmp + "/all_empty_map/manifest.yaml"));
  ExpectExistingMapUnchanged(bag, "all_empty");
}

TEST_F(OfflineMapperBadInputTest, AllNaNCloudsAreSkippedAndNaNPointsDropped) {
  std::vector<PointCloud2> clouds = Clouds();
  for (int i = 5; i < kScans; i += 10) clouds[i] = AllNaN(clouds[i]);  // 4 all-NaN scans
  // A few NaN points in an otherwise good scan are just dropped.
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::memcpy(&clouds[8].data[0], &nan, sizeof(float));
  const MapperRun run = MapInto(WriteBag("some_nan", clouds), "some_nan_map");
  ASSERT_EQ(run.exit_code, 0) << run.log;
  EXPECT_EQ(CountOccurrences(run.log, "survived the input filter"), 4u) << run.log;
  EXPECT_NE(run.log.find("scan 5 skipped"), std::string::npos) << run.log;
  const core::MapContents map = LoadMap("some_nan_map");
  EXPECT_EQ(map.sessions.at(0).scans, static_cast<std::uint32_t>(kScans - 4));
  for (const core::Submap& submap : map.submaps) {
    for (const Eigen::Vector3d& p : submap.points) ASSERT_TRUE(p.allFinite());
  }
}

TEST_F(OfflineMapperBadInputTest, OnlyNaNCloudsStopWithAnError) {
  std::vector<PointCloud2> clouds = Clouds();
  for (PointCloud2& cloud : clouds) cloud = AllNaN(cloud);
  const std::string bag = WriteBag("all_nan", clouds);
  const MapperRun run = MapInto(bag, "all_nan_map");
  EXPECT_EQ(run.exit_code, 1) << run.log;
  EXPECT_NE(run.log.find("produced no submap"), std::string::npos) << run.log;
  EXPECT_FALSE(fs::exists(kTmp + "/all_nan_map/manifest.yaml"));
  ExpectExistingMapUnchanged(bag, "all_nan");
}

TEST_F(OfflineMapperBadInputTest, CloudsWithoutRingAndTimeAreMappedWithoutDeskew) {
  std::vector<PointCloud2> clouds = Clouds();
  for (PointCloud2& cloud : clouds) {
    for (auto& field : cloud.fields) {
      if (field.name == "ring" || field.name == "time") field.name += "_removed";
    }
  }
  const MapperRun run = MapInto(WriteBag("no_ring_time", clouds), "no_ring_time_map");
  ASSERT_EQ(run.exit_code, 0) << run.log;
  EXPECT_EQ(run.log.find("skipped:"), std::string::npos) << run.log;
  EXPECT_EQ(LoadMap("no_ring_time_map").sessions.at(0).scans, static_cast<std::uint32_t>(kScans));
}

TEST_F(OfflineMapperBadInputTest, ScansInAnotherFrameAreSkipped) {
  std::vector<PointCloud2> clouds = Clouds();
  clouds[10].header.frame_id = "base_link";
  clouds[20].header.frame_id = "";
  const MapperRun run = MapInto(WriteBag("wrong_frame", clouds), "wrong_frame_map");
  ASSERT_EQ(run.exit_code, 0) << run.log;
  EXPECT_NE(run.log.find("scan 10 skipped: frame_id 'base_link' differs from the sensor frame '" +
                         clouds[0].header.frame_id + "'"),
            std::string::npos)
      << run.log;
  EXPECT_NE(run.log.find("scan 20 skipped: frame_id ''"), std::string::npos) << run.log;
  EXPECT_EQ(LoadMap("wrong_frame_map").sessions.at(0).scans, static_cast<std::uint32_t>(kScans - 2));
}

TEST_F(OfflineMapperBadInputTest, StampsGoingBackwardsAreSkipped) {
  std::vector<PointCloud2> clouds = Clouds();
  // Bag order kept; the header stamps of scans 12 and 13 lie before scan 11.
  clouds[12].header.stamp = clouds[9].header.stamp;
  clouds[13].header.stamp = clouds[10].header.stamp;
  const MapperRun run = MapInto(WriteBag("backwards", clouds), "backwards_map");
  ASSERT_EQ(run.exit_code, 0) << run.log;
  EXPECT_NE(run.log.find("scan 12 skipped: odometry: scan stamp"), std::string::npos) << run.log;
  EXPECT_NE(run.log.find("scan 13 skipped"), std::string::npos) << run.log;
  EXPECT_NE(run.log.find("does not increase"), std::string::npos) << run.log;
  EXPECT_EQ(LoadMap("backwards_map").sessions.at(0).scans, static_cast<std::uint32_t>(kScans - 2));
}

TEST_F(OfflineMapperBadInputTest, DuplicatedStampsAreSkipped) {
  std::vector<PointCloud2> clouds = Clouds();
  clouds.insert(clouds.begin() + 15, clouds[14]);  // the same scan twice
  clouds.insert(clouds.begin() + 30, clouds[29]);
  const MapperRun run = MapInto(WriteBag("duplicated", clouds), "duplicated_map");
  ASSERT_EQ(run.exit_code, 0) << run.log;
  EXPECT_NE(run.log.find("scan 15 skipped"), std::string::npos) << run.log;
  EXPECT_NE(run.log.find("scan 30 skipped"), std::string::npos) << run.log;
  EXPECT_EQ(CountOccurrences(run.log, "does not increase"), 2u) << run.log;
  EXPECT_EQ(LoadMap("duplicated_map").sessions.at(0).scans, static_cast<std::uint32_t>(kScans));
}

TEST_F(OfflineMapperBadInputTest, TopicMissingNamesTheTopicsThatExist) {
  const std::string bag = WriteBag("other_topic", Clouds(), "/points_raw");
  const MapperRun run = MapInto(bag, "other_topic_map");
  EXPECT_EQ(run.exit_code, 1) << run.log;
  EXPECT_NE(run.log.find("has no topic '/velodyne_points'; its topics are:\n  /points_raw "
                         "[sensor_msgs/PointCloud2]"),
            std::string::npos)
      << run.log;
  EXPECT_FALSE(fs::exists(kTmp + "/other_topic_map"));
  ExpectExistingMapUnchanged(bag, "other_topic");
}

TEST_F(OfflineMapperBadInputTest, TopicOfAnotherTypeIsRefused) {
  const std::string path = kTmp + "/string_topic.bag";
  {
    rosbag::Bag bag;
    bag.open(path, rosbag::bagmode::Write);
    std_msgs::String text;
    text.data = "not a point cloud";
    for (int i = 0; i < 3; ++i) bag.write(kTopic, ros::Time(1000.0 + i), text);
  }
  const MapperRun run = MapInto(path, "string_topic_map");
  EXPECT_EQ(run.exit_code, 1) << run.log;
  EXPECT_NE(run.log.find("carries std_msgs/String, expected sensor_msgs/PointCloud2"),
            std::string::npos)
      << run.log;
  EXPECT_FALSE(fs::exists(kTmp + "/string_topic_map"));
  ExpectExistingMapUnchanged(path, "string_topic");
}

TEST_F(OfflineMapperBadInputTest, TruncatedBagStopsWithAnErrorAndWritesNoMap) {
  const std::string full = ReadText(WriteBag("to_truncate", Clouds()));
  for (const double fraction : {0.6, 0.05}) {
    const std::string name = "truncated_" + std::to_string(static_cast<int>(fraction * 100));
    const std::string path = kTmp + "/" + name + ".bag";
    std::ofstream(path, std::ios::binary) << full.substr(0, static_cast<std::size_t>(full.size() * fraction));
    const MapperRun run = MapInto(path, name + "_map");
    EXPECT_EQ(run.exit_code, 1) << run.log;
    EXPECT_NE(run.log.find("bag '" + path + "'"), std::string::npos) << run.log;
    EXPECT_FALSE(fs::exists(kTmp + "/" + name + "_map/manifest.yaml"));
    ExpectExistingMapUnchanged(path, name);
  }
}

TEST_F(OfflineMapperBadInputTest, CorruptPointBytesAreDroppedAsNonFinite) {
  // The bag's index is intact but 4 KB in the middle (point data of one scan) are overwritten
  // with 0xff, i.e. NaN floats: those points are dropped, the map holds only finite points.
  std::string bytes = ReadText(WriteBag("to_corrupt", Clouds()));
  const std::size_t middle = bytes.size() / 2;
  for (std::size_t i = 0; i < 4096; ++i) bytes[middle + i] = static_cast<char>(0xff);
  const std::string path = kTmp + "/corrupt.bag";
  std::ofstream(path, std::ios::binary) << bytes;
  const MapperRun run = MapInto(path, "corrupt_map");
  ASSERT_EQ(run.exit_code, 0) << run.log;
  const core::MapContents map = LoadMap("corrupt_map");
  ASSERT_FALSE(map.submaps.empty());
  for (const core::Submap& submap : map.submaps) {
    for (const Eigen::Vector3d& p : submap.points) ASSERT_TRUE(p.allFinite());
  }
}

// How far the odometry thread may run ahead changes only the speed: the trajectories are the
// same with a queue of 1 as with the default; 0 is refused before anything is written.
TEST_F(OfflineMapperBadInputTest, OdometryQueueChangesNothingButIsChecked) {
  const std::string bag = WriteBag("queue", Clouds());
  for (const char* name : {"queue_default", "queue_1", "queue_0"}) fs::remove_all(kTmp + "/" + name);
  const MapperRun by_default = RunMapper(bag, kTmp + "/queue_default");
  ASSERT_EQ(by_default.exit_code, 0) << by_default.log;
  const MapperRun one = RunMapper(bag, kTmp + "/queue_1", "--odometry-queue 1");
  ASSERT_EQ(one.exit_code, 0) << one.log;
  const std::string trajectory = "/trajectories/queue.tum";
  const std::string expected = ReadText(kTmp + "/queue_default" + trajectory);
  EXPECT_FALSE(expected.empty());
  EXPECT_EQ(ReadText(kTmp + "/queue_1" + trajectory), expected);
  const MapperRun zero = RunMapper(bag, kTmp + "/queue_0", "--odometry-queue 0");
  EXPECT_EQ(zero.exit_code, 2) << zero.log;
  EXPECT_NE(zero.log.find("--odometry-queue needs a whole number >= 1"), std::string::npos)
      << zero.log;
  EXPECT_FALSE(fs::exists(kTmp + "/queue_0"));
}

TEST_F(OfflineMapperBadInputTest, NotABagIsRefused) {
  const std::string path = kTmp + "/not_a_bag.bag";
  std::ofstream(path) << "this is not a rosbag\n";
  const MapperRun run = MapInto(path, "not_a_bag_map");
  EXPECT_EQ(run.exit_code, 1) << run.log;
  EXPECT_NE(run.log.find("cannot read bag '" + path + "'"), std::string::npos) << run.log;
  EXPECT_FALSE(fs::exists(kTmp + "/not_a_bag_map"));
}

}  // namespace
}  // namespace multisession_mapper
