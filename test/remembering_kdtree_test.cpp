#include "multisession_mapper/core/remembering_kdtree.h"

#include <cstring>
#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <pcl/features/fpfh.h>
#include <pcl/features/normal_3d.h>

namespace multisession_mapper {
namespace core {
namespace {

// A wall, a floor and a few posts with noise: features with structure.
pcl::PointCloud<pcl::PointXYZ>::Ptr Scene() {
  std::mt19937 rng(7);
  std::normal_distribution<float> noise(0.0f, 0.02f);
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  for (float x = -10.0f; x <= 10.0f; x += 0.5f) {
    for (float y = -10.0f; y <= 10.0f; y += 0.5f) cloud->push_back({x, y, noise(rng)});
    for (float z = 0.5f; z <= 4.0f; z += 0.5f) cloud->push_back({x, 8.0f + noise(rng), z});
  }
  for (float px : {-5.0f, 0.0f, 6.0f}) {
    for (float z = 0.5f; z <= 3.0f; z += 0.25f) {
      cloud->push_back({px + noise(rng), -3.0f + noise(rng), z});
      cloud->push_back({px + 0.3f + noise(rng), -3.0f + noise(rng), z});
    }
  }
  return cloud;
}

pcl::PointCloud<pcl::FPFHSignature33> Features(const pcl::PointCloud<pcl::PointXYZ>::Ptr& cloud,
                                               pcl::search::KdTree<pcl::PointXYZ>::Ptr tree) {
  pcl::PointCloud<pcl::Normal>::Ptr normals(new pcl::PointCloud<pcl::Normal>);
  pcl::NormalEstimation<pcl::PointXYZ, pcl::Normal> normal_estimation;
  normal_estimation.setInputCloud(cloud);
  normal_estimation.setSearchMethod(tree);
  normal_estimation.setRadiusSearch(1.0);
  normal_estimation.compute(*normals);
  pcl::FPFHEstimation<pcl::PointXYZ, pcl::Normal, pcl::FPFHSignature33> fpfh;
  fpfh.setInputCloud(cloud);
  fpfh.setInputNormals(normals);
  fpfh.setSearchMethod(tree);
  fpfh.setRadiusSearch(2.5);
  pcl::PointCloud<pcl::FPFHSignature33> features;
  fpfh.compute(features);
  return features;
}

TEST(RememberingKdTreeTest, FpfhFeaturesAreBitForBitPcls) {
  const pcl::PointCloud<pcl::PointXYZ>::Ptr cloud = Scene();
  pcl::search::KdTree<pcl::PointXYZ>::Ptr plain(new pcl::search::KdTree<pcl::PointXYZ>);
  auto* remembering_raw = new RememberingKdTree(2.5);
  pcl::search::KdTree<pcl::PointXYZ>::Ptr remembering(remembering_raw);
  const pcl::PointCloud<pcl::FPFHSignature33> expected = Features(cloud, plain);
  const pcl::PointCloud<pcl::FPFHSignature33> got = Features(cloud, remembering);
  ASSERT_EQ(expected.size(), cloud->size());
  ASSERT_EQ(got.size(), expected.size());
  int differing = 0;
  for (std::size_t i = 0; i < got.size(); ++i) {
    differing += std::memcmp(got[i].histogram, expected[i].histogram,
                             sizeof(expected[i].histogram)) != 0;
  }
  EXPECT_EQ(differing, 0);
  // Every point's second FPFH search came from memory; the normals' 1 m searches did not.
  EXPECT_EQ(remembering_raw->remembered_answers(), cloud->size());
}

TEST(RememberingKdTreeTest, OtherSearchesAndANewCloudAreNotServedFromMemory) {
  const pcl::PointCloud<pcl::PointXYZ>::Ptr cloud = Scene();
  RememberingKdTree tree(2.0);
  tree.setInputCloud(cloud);
  pcl::Indices first, second, other;
  std::vector<float> d_first, d_second, d_other;
  ASSERT_GT(tree.radiusSearch(*cloud, 10, 2.0, first, d_first), 1);
  ASSERT_GT(tree.radiusSearch(*cloud, 10, 1.0, other, d_other), 0);  // another radius
  EXPECT_LT(other.size(), first.size());
  EXPECT_EQ(tree.remembered_answers(), 0u);
  EXPECT_EQ(tree.radiusSearch(*cloud, 10, 2.0, second, d_second),
            static_cast<int>(first.size()));
  EXPECT_EQ(tree.remembered_answers(), 1u);
  EXPECT_EQ(second, first);
  EXPECT_EQ(d_second, d_first);
  // A limited search is never served from memory.
  tree.radiusSearch(*cloud, 11, 2.0, first, d_first);
  EXPECT_EQ(tree.radiusSearch(*cloud, 11, 2.0, other, d_other, 3), 3);
  EXPECT_EQ(tree.remembered_answers(), 1u);
  // A new cloud (here: the same points moved) forgets what was remembered for the old one.
  pcl::PointCloud<pcl::PointXYZ>::Ptr moved(new pcl::PointCloud<pcl::PointXYZ>(*cloud));
  for (pcl::PointXYZ& p : *moved) p.x += 100.0f;
  (*moved)[11] = (*cloud)[0];
  tree.setInputCloud(moved);
  pcl::Indices after;
  std::vector<float> d_after;
  tree.radiusSearch(*moved, 11, 2.0, after, d_after);
  EXPECT_EQ(tree.remembered_answers(), 1u);
  EXPECT_EQ(after.size(), 1u);  // only itself: its old neighbours moved away
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
