#include "multisession_mapper/sim/label_cloud.h"

#include <cstdlib>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <pcl/PCLPointCloud2.h>
#include <pcl/io/pcd_io.h>

namespace multisession_mapper {
namespace sim {
namespace {

TruthPoint Make(float x, float y, float z, ObjectClass label, std::uint32_t id,
               float range_m = 0.0f) {
  TruthPoint p;
  p.position_m = Eigen::Vector3f(x, y, z);
  p.label = label;
  p.object_id = id;
  p.range_m = range_m;
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

TEST(SimLabelCloudTest, KeepsTheSmallestRangePerVoxel) {
  LabelCloud cloud(0.1);
  cloud.Add(Make(0.01f, 0.01f, 0.01f, ObjectClass::kBuilding, 3, 72.0f));
  cloud.Add(Make(0.05f, 0.02f, 0.09f, ObjectClass::kBuilding, 3, 35.5f));  // same voxel
  cloud.Add(Make(0.06f, 0.03f, 0.08f, ObjectClass::kBuilding, 3, 48.0f));  // same voxel
  cloud.Add(Make(0.15f, 0.02f, 0.09f, ObjectClass::kBuilding, 3, 90.0f));
  ASSERT_EQ(cloud.size(), 2u);
  EXPECT_FLOAT_EQ(cloud.points()[0].range_m, 35.5f);
  EXPECT_FLOAT_EQ(cloud.points()[0].position_m.x(), 0.01f);  // still the first point
  EXPECT_FLOAT_EQ(cloud.points()[1].range_m, 90.0f);
  // Also after the table has grown.
  LabelCloud grid(1.0);
  for (int x = 0; x < 300; ++x) grid.Add(Make(x + 0.5f, 0.5f, 0.5f, ObjectClass::kTerrain, 0, 50.0f));
  for (int x = 0; x < 300; ++x) grid.Add(Make(x + 0.7f, 0.2f, 0.1f, ObjectClass::kTerrain, 0, 10.0f + x));
  ASSERT_EQ(grid.size(), 300u);
  EXPECT_FLOAT_EQ(grid.points()[0].range_m, 10.0f);
  EXPECT_FLOAT_EQ(grid.points()[299].range_m, 50.0f);
}

TEST(SimLabelCloudTest, PcdRoundTripAndPclReadsIt) {
  LabelCloud cloud(0.0);
  cloud.Add(Make(1.5f, -2.25f, 3.0f, ObjectClass::kParkedCar, 123456, 42.25f));
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
  EXPECT_FLOAT_EQ(back.value()[0].range_m, 42.25f);

  pcl::PCLPointCloud2 pcl_cloud;
  ASSERT_EQ(pcl::io::loadPCDFile(path, pcl_cloud), 0);
  EXPECT_EQ(pcl_cloud.width * pcl_cloud.height, 2u);
  ASSERT_EQ(pcl_cloud.fields.size(), 6u);
  EXPECT_EQ(pcl_cloud.fields[5].name, "range");
  EXPECT_EQ(pcl_cloud.fields[5].datatype, pcl::PCLPointField::FLOAT32);
  EXPECT_EQ(pcl_cloud.fields[3].name, "label");
  EXPECT_EQ(pcl_cloud.fields[3].datatype, pcl::PCLPointField::UINT8);
  EXPECT_EQ(pcl_cloud.fields[4].name, "object_id");
  EXPECT_EQ(pcl_cloud.fields[4].datatype, pcl::PCLPointField::UINT32);
  std::uint32_t id = 0;
  std::memcpy(&id, pcl_cloud.data.data() + pcl_cloud.fields[4].offset, 4);
  EXPECT_EQ(id, 123456u);
  EXPECT_FALSE(LabelCloud::ReadPcd(path + ".missing").ok());
}

TEST(SimLabelCloudTest, ReadsFilesWithoutTheRangeField) {
  // Truth written before the range field existed: 17 bytes per point, range_m = 0.
  std::system((std::string("mkdir -p ") + MSM_TEST_TMP_DIR).c_str());
  const std::string path = std::string(MSM_TEST_TMP_DIR) + "/sim_label_cloud_old.pcd";
  {
    std::ofstream out(path, std::ios::binary);
    out << "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z label object_id\nSIZE 4 4 4 1 4\n"
        << "TYPE F F F U U\nCOUNT 1 1 1 1 1\nWIDTH 1\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\n"
        << "POINTS 1\nDATA binary\n";
    const float xyz[3] = {1.0f, 2.0f, 3.0f};
    const std::uint8_t label = static_cast<std::uint8_t>(ObjectClass::kPole);
    const std::uint32_t id = 99;
    out.write(reinterpret_cast<const char*>(xyz), 12);
    out.write(reinterpret_cast<const char*>(&label), 1);
    out.write(reinterpret_cast<const char*>(&id), 4);
  }
  auto back = LabelCloud::ReadPcd(path);
  ASSERT_TRUE(back.ok()) << back.status().message();
  ASSERT_EQ(back.value().size(), 1u);
  EXPECT_EQ(back.value()[0].object_id, 99u);
  EXPECT_EQ(back.value()[0].range_m, 0.0f);
}

}  // namespace
}  // namespace sim
}  // namespace multisession_mapper
