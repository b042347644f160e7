// End-to-end test of the simulate_campus tool: byte-identical output for the same seed (also
// with a different number of threads), bags that hold only /velodyne_points in the Velodyne
// layout with stamps equal to the ground-truth trajectory, and clear usage errors.
#include <sys/wait.h>

#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>
#include <ros/time.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/PointCloud2.h>

#include "multisession_mapper/core/trajectory_io.h"
#include "multisession_mapper/ros/conversions.h"
#include "multisession_mapper/sim/label_cloud.h"
#include "multisession_mapper/sim/world_io.h"

namespace multisession_mapper {
namespace {

const std::string kTool = MSM_SIMULATE_CAMPUS;
const std::string kTmp = std::string(MSM_TEST_TMP_DIR) + "/sim_simulate_campus_test";

int RunTool(const std::string& args) {
  const std::string cmd = kTool + " " + args + " > /dev/null 2>&1";
  const int status = std::system(cmd.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

std::string Read(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream buffer;
  buffer << in.rdbuf();
  return buffer.str();
}

class SimSimulateCampusTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    std::system(("rm -rf " + kTmp + " && mkdir -p " + kTmp).c_str());
    ros::Time::init();
    const std::string common = "--profile tiny --sessions 2 --seed 4 --max-scans 15 --quiet";
    ASSERT_EQ(RunTool(common + " --out " + kTmp + "/a"), 0);
    ASSERT_EQ(RunTool(common + " --threads 1 --out " + kTmp + "/b"), 0);
  }
};

TEST_F(SimSimulateCampusTest, SameSeedGivesByteIdenticalOutput) {
  for (const std::string f :
       {"sessions.yaml", "world.yaml", "s00.bag", "s01.bag", "truth/s00.tum", "truth/s01.tum",
        "truth/s00_labels.pcd", "truth/s01_labels.pcd"}) {
    const std::string a = Read(kTmp + "/a/" + f);
    const std::string b = Read(kTmp + "/b/" + f);
    EXPECT_GT(a.size(), 100u) << f;
    EXPECT_TRUE(a == b) << f << " differs between two runs with the same seed";
  }
  ASSERT_EQ(RunTool("--profile tiny --sessions 1 --seed 5 --max-scans 3 --quiet --out " + kTmp +
                "/c"),
            0);
  EXPECT_NE(Read(kTmp + "/a/s00.bag"), Read(kTmp + "/c/s00.bag"));
}

TEST_F(SimSimulateCampusTest, BagHoldsVelodyneScansMatchingTheTruth) {
  auto truth = core::ReadTumFile(kTmp + "/a/truth/s01.tum");
  ASSERT_TRUE(truth.ok()) << truth.status().message();
  ASSERT_EQ(truth.value().size(), 15u);
  rosbag::Bag bag;
  bag.open(kTmp + "/a/s01.bag", rosbag::bagmode::Read);
  rosbag::View view(bag);
  std::size_t count = 0;
  for (const rosbag::MessageInstance& m : view) {
    ASSERT_EQ(m.getTopic(), "/velodyne_points");
    sensor_msgs::PointCloud2::ConstPtr msg = m.instantiate<sensor_msgs::PointCloud2>();
    ASSERT_TRUE(msg != nullptr);
    EXPECT_EQ(msg->header.frame_id, "velodyne");
    EXPECT_EQ(m.getTime(), msg->header.stamp);
    ASSERT_LT(count, truth.value().size());
    EXPECT_NEAR(msg->header.stamp.toSec(), truth.value()[count].stamp_s, 1e-6);
    auto scan = conversions::FromPointCloud2(*msg);
    ASSERT_TRUE(scan.ok()) << scan.status().message();
    EXPECT_TRUE(scan.value().has_ring);
    EXPECT_TRUE(scan.value().has_time);
    EXPECT_GT(scan.value().points.size(), 5000u);
    ++count;
  }
  EXPECT_EQ(count, 15u);
  bag.close();
  // Sessions are days apart.
  auto truth0 = core::ReadTumFile(kTmp + "/a/truth/s00.tum");
  ASSERT_TRUE(truth0.ok());
  EXPECT_NEAR(truth.value()[0].stamp_s - truth0.value()[0].stamp_s, 86400.0, 1.0);
  // Ground truth beside the bags: the world and the labelled points.
  auto world = sim::ReadWorldYamlFile(kTmp + "/a/world.yaml");
  ASSERT_TRUE(world.ok()) << world.status().message();
  EXPECT_EQ(world.value().session_names.size(), 2u);
  auto labels = sim::LabelCloud::ReadPcd(kTmp + "/a/truth/s01_labels.pcd");
  ASSERT_TRUE(labels.ok());
  EXPECT_GT(labels.value().size(), 10000u);
  const std::string index = Read(kTmp + "/a/sessions.yaml");
  EXPECT_NE(index.find("format: multisession_mapper_sim/1"), std::string::npos);
  EXPECT_NE(index.find("bag: s01.bag"), std::string::npos);
  EXPECT_NE(index.find("scans: 15"), std::string::npos);
}

TEST_F(SimSimulateCampusTest, BadArgumentsGiveUsageErrors) {
  EXPECT_EQ(RunTool("--help"), 0);
  EXPECT_NE(RunTool(""), 0);  // --out is required
  EXPECT_NE(RunTool("--profile huge --out " + kTmp + "/x"), 0);
  EXPECT_NE(RunTool("--sessions 0 --out " + kTmp + "/x"), 0);
  EXPECT_NE(RunTool("--seed abc --out " + kTmp + "/x"), 0);
  EXPECT_NE(RunTool("--noise -1 --out " + kTmp + "/x"), 0);
  EXPECT_NE(RunTool("--frobnicate 3 --out " + kTmp + "/x"), 0);
  EXPECT_NE(RunTool("--out"), 0);
}

}  // namespace
}  // namespace multisession_mapper
