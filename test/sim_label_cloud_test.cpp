#include "multisession_mapper/sim/label_cloud.h"

#include <cstdlib>
#include <string>

#include <gtest/gtest.h>
#include <pcl/PCLPointCloud2.h>
#include <pcl/io/pcd_io.h>

namespace multisession_mapper {
namespace sim {
namespace {

TruthPoint Make(float x, float y, float z, ObjectClass label, std::uint32_t id) {
  TruthPoint p;
  p.position_m = Eigen::Vector3f(x, y, z);
  p.label = label;
  p.object_id = id;
  return p;
}

TEST(SimLabelCloudTest, KeepsTheFirstPointPerVoxel) {
  LabelCloud cloud(0.1);
  cloud.Add(Make(0.01f, 0.01f, 0.01f, ObjectClass::kBuilding, 3));
  cloud.Add(Make(0.05f, 0.02f, 0.09f, ObjectClass::kCanopy, 4));  // same voxel
  cloud.Add(Make(0.15f, 0.02f, 0.09f, ObjectClass::kCanopy, 4));
  cloud.Add(Make(-0.05f, 0.02f, 0.09f, ObjectClass::kTerrain, 0));  // negative side
  ASSERT_EQ(cloud.size(), 3u);
  EXPECT_EQ(cloud.points()[0].object_id, 3u);
  EXPECT_EQ(cloud.points()[2].label, ObjectClass::kTerrain);
  LabelCloud all(0.0);
  for (int k = 0; k < 5; ++k) all.Add(Make(0, 0, 0, ObjectClass::kPole, 1));
  EXPECT_EQ(all.size(), 5u);
  // Many points: the table grows and stays exact.
  LabelCloud grid(1.0);
  for (int x = 0; x < 300; ++x) {
    for (int y = 0; y < 300; ++y) {
      grid.Add(Make(x + 0.5f, y + 0.5f, 0.5f, ObjectClass::kTerrain, 0));
      grid.Add(Make(x + 0.7f, y + 0.2f, 0.1f, ObjectClass::kTerrain, 0));
    }
  }
  EXPECT_EQ(grid.size(), 90000u);
}

TEST(SimLabelCloudTest, PcdRoundTripAndPclReadsIt) {
  LabelCloud cloud(0.0);
  cloud.Add(Make(1.5f, -2.25f, 3.0f, ObjectClass::kParkedCar, 123456));
  cloud.Add(Make(-100.0f, 200.0f, 0.5f, ObjectClass::kPedestrian, 7));
  std::system((std::string("mkdir -p ") + MSM_TEST_TMP_DIR).c_str());
  const std::string path = std::string(MSM_TEST_TMP_DIR) + "/sim_label_cloud_test.pcd";
  ASSERT_TRUE(cloud.WritePcd(path).ok());
  auto back = LabelCloud::ReadPcd(path);
  ASSERT_TRUE(back.ok()) << back.status().message();
  ASSERT_EQ(back.value().size(), 2u);
  EXPECT_EQ(back.value()[0].object_id, 123456u);
  EXPECT_EQ(back.value()[0].label, ObjectClass::kParkedCar);
  EXPECT_FLOAT_EQ(back.value()[1].position_m.y(), 200.0f);
  EXPECT_EQ(back.value()[1].label, ObjectClass::kPedestrian);

  pcl::PCLPointCloud2 pcl_cloud;
  ASSERT_EQ(pcl::io::loadPCDFile(path, pcl_cloud), 0);
  EXPECT_EQ(pcl_cloud.width * pcl_cloud.height, 2u);
  ASSERT_EQ(pcl_cloud.fields.size(), 5u);
  EXPECT_EQ(pcl_cloud.fields[3].name, "label");
  EXPECT_EQ(pcl_cloud.fields[3].datatype, pcl::PCLPointField::UINT8);
  EXPECT_EQ(pcl_cloud.fields[4].name, "object_id");
  EXPECT_EQ(pcl_cloud.fields[4].datatype, pcl::PCLPointField::UINT32);
  std::uint32_t id = 0;
  std::memcpy(&id, pcl_cloud.data.data() + pcl_cloud.fields[4].offset, 4);
  EXPECT_EQ(id, 123456u);
  EXPECT_FALSE(LabelCloud::ReadPcd(path + ".missing").ok());
}

}  // namespace
}  // namespace sim
}  // namespace multisession_mapper
