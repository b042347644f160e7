#include "multisession_mapper/core/fpfh_features.h"

#include <sys/stat.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <pcl/features/fpfh.h>
#include <pcl/features/normal_3d.h>
#include <pcl/io/pcd_io.h>
#include <pcl/search/kdtree.h>

#include "multisession_mapper/core/se3.h"
#include "multisession_mapper/core/voxel_downsample.h"

namespace multisession_mapper {
namespace core {
namespace {

// A floor, a wall and a few posts with noise, at a 0.5 m spacing: features with structure.
PointVector Scene() {
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.02);
  PointVector points;
  for (double x = -10.0; x <= 10.0; x += 0.5) {
    for (double y = -10.0; y <= 10.0; y += 0.5) points.emplace_back(x, y, noise(rng));
    for (double z = 0.5; z <= 4.0; z += 0.5) points.emplace_back(x, 8.0 + noise(rng), z);
  }
  for (double px : {-5.0, 0.0, 6.0}) {
    for (double z = 0.5; z <= 3.0; z += 0.25) {
      points.emplace_back(px + noise(rng), -3.0 + noise(rng), z);
      points.emplace_back(px + 0.3 + noise(rng), -3.0 + noise(rng), z);
    }
  }
  return points;
}

pcl::PointCloud<pcl::PointXYZ>::Ptr ToPcl(const PointVector& points) {
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  for (const Eigen::Vector3d& p : points) {
    cloud->push_back(pcl::PointXYZ(static_cast<float>(p.x()), static_cast<float>(p.y()),
                                   static_cast<float>(p.z())));
  }
  return cloud;
}

// PCL's normals (radius search, oriented towards a view point above the origin), as the
// global registration computes them.
pcl::PointCloud<pcl::Normal>::Ptr PclNormals(const pcl::PointCloud<pcl::PointXYZ>::Ptr& cloud,
                                             double radius_m) {
  pcl::PointCloud<pcl::Normal>::Ptr normals(new pcl::PointCloud<pcl::Normal>);
  pcl::NormalEstimation<pcl::PointXYZ, pcl::Normal> estimation;
  estimation.setInputCloud(cloud);
  estimation.setSearchMethod(pcl::search::KdTree<pcl::PointXYZ>::Ptr(
      new pcl::search::KdTree<pcl::PointXYZ>));
  estimation.setRadiusSearch(radius_m);
  estimation.setViewPoint(0.0f, 0.0f, 2.0f);
  estimation.compute(*normals);
  return normals;
}

std::vector<Eigen::Vector3d> ToEigen(const pcl::PointCloud<pcl::Normal>& normals) {
  std::vector<Eigen::Vector3d> out;
  for (const pcl::Normal& n : normals) {
    const Eigen::Vector3d v(n.normal_x, n.normal_y, n.normal_z);
    out.push_back(v.allFinite() ? v : Eigen::Vector3d::Zero());
  }
  return out;
}

// How our histograms compare with pcl::FPFHEstimation's on the same points and normals.
struct Comparison {
  std::size_t compared = 0;      // points both define
  std::size_t definition_differs = 0;
  std::vector<double> l1;        // per compared point: L1 distance (each histogram sums to 300)
  double Quantile(double q) const {
    std::vector<double> v = l1;
    std::sort(v.begin(), v.end());
    return v.empty() ? NAN : v[std::min(v.size() - 1, static_cast<std::size_t>(q * v.size()))];
  }
};

// PCL's normals of `all`, then both FPFHs of the points with a normal (ours leaves the others
// out; PCL would count them: FeaturesOfOthersIgnoreThePointsWithoutANormal covers that).
Comparison CompareWithPcl(const PointVector& all, double normal_radius_m,
                          double feature_radius_m) {
  const pcl::PointCloud<pcl::Normal>::Ptr all_normals = PclNormals(ToPcl(all), normal_radius_m);
  PointVector points;
  pcl::PointCloud<pcl::Normal>::Ptr normals(new pcl::PointCloud<pcl::Normal>);
  for (std::size_t i = 0; i < all.size(); ++i) {
    const pcl::Normal& n = (*all_normals)[i];
    if (!std::isfinite(n.normal_x) || !std::isfinite(n.normal_y) || !std::isfinite(n.normal_z)) {
      continue;
    }
    points.push_back(all[i]);
    normals->push_back(n);
  }
  const pcl::PointCloud<pcl::PointXYZ>::Ptr cloud = ToPcl(points);
  pcl::PointCloud<pcl::FPFHSignature33> reference;
  pcl::FPFHEstimation<pcl::PointXYZ, pcl::Normal, pcl::FPFHSignature33> fpfh;
  fpfh.setInputCloud(cloud);
  fpfh.setInputNormals(normals);
  fpfh.setSearchMethod(pcl::search::KdTree<pcl::PointXYZ>::Ptr(
      new pcl::search::KdTree<pcl::PointXYZ>));
  fpfh.setRadiusSearch(feature_radius_m);
  fpfh.compute(reference);

  std::vector<std::uint8_t> defined;
  const std::vector<Eigen::Vector3d> our_normals = ToEigen(*normals);
  const std::vector<float> ours =
      ComputeFpfh(points, our_normals, feature_radius_m, &defined).value();
  Comparison c;
  for (std::size_t i = 0; i < points.size(); ++i) {
    // PCL's feature counts where it is finite and non-zero.
    const float* h = reference[i].histogram;
    bool pcl_defined = true;
    float sum = 0.0f;
    for (int b = 0; b < kFpfhBins && pcl_defined; ++b) {
      pcl_defined = std::isfinite(h[b]);
      sum += h[b];
    }
    pcl_defined = pcl_defined && sum > 0.0f;
    if (pcl_defined != (defined[i] != 0)) {
      ++c.definition_differs;
      continue;
    }
    if (!pcl_defined) continue;
    ++c.compared;
    double l1 = 0.0;
    for (int b = 0; b < kFpfhBins; ++b) l1 += std::abs(h[b] - ours[i * kFpfhBins + b]);
    c.l1.push_back(l1);
  }
  return c;
}

bool Exists(const std::string& path) {
  struct stat st;
  return stat(path.c_str(), &st) == 0;
}

TEST(FpfhFeaturesTest, MatchesPclOnASyntheticScene) {
  const PointVector points = Scene();
  const Comparison c = CompareWithPcl(points, 1.0, 2.5);
  std::cout << "synthetic scene: " << c.compared << " compared, L1 median " << c.Quantile(0.5)
            << ", 99th percentile " << c.Quantile(0.99) << ", max " << c.Quantile(1.0)
            << " (of 300)" << std::endl;
  EXPECT_EQ(c.definition_differs, 0u);
  ASSERT_GT(c.compared, points.size() * 9 / 10);
  // The same histograms up to the rounding of sums taken in another order.
  EXPECT_LT(c.Quantile(1.0), 0.01);
}

TEST(FpfhFeaturesTest, MatchesPclOnARealScanAtTheRegistrationSettings) {
  const std::string path = std::string(MSM_SHARED_DATA_DIR) + "/real/fast_gicp_pair/251370668.pcd";
  if (!Exists(path)) GTEST_SKIP() << "no real data at " << path;
  pcl::PointCloud<pcl::PointXYZ> cloud;
  ASSERT_EQ(pcl::io::loadPCDFile(path, cloud), 0);
  PointVector raw;
  for (const pcl::PointXYZ& p : cloud) {
    const Eigen::Vector3d v(p.x, p.y, p.z);
    if (v.allFinite() && v.norm() <= 60.0) raw.push_back(v);
  }
  // GlobalRegistrationConfig's defaults: 1 m voxels, normals within 2 m, features within 5 m.
  const PointVector points = VoxelDownsample(raw, 1.0);
  const Comparison c = CompareWithPcl(points, 2.0, 5.0);
  std::cout << "real scan: " << c.compared << " compared, L1 median " << c.Quantile(0.5)
            << ", 99th percentile " << c.Quantile(0.99) << ", max " << c.Quantile(1.0)
            << "; definition differs at " << c.definition_differs << std::endl;
  ASSERT_GT(c.compared, 1000u);
  EXPECT_EQ(c.definition_differs, 0u);
  EXPECT_LT(c.Quantile(1.0), 0.01);
}

TEST(FpfhFeaturesTest, FeaturesDoNotChangeUnderARigidMotion) {
  const PointVector points = Scene();
  const std::vector<Eigen::Vector3d> normals = ToEigen(*PclNormals(ToPcl(points), 1.0));
  const Pose3 motion = se3::FromXyzRpy(12.0, -7.0, 1.5, 0.1, -0.05, 2.3);
  PointVector moved_points;
  std::vector<Eigen::Vector3d> moved_normals;
  for (std::size_t i = 0; i < points.size(); ++i) {
    moved_points.push_back(motion * points[i]);
    moved_normals.push_back(motion.linear() * normals[i]);
  }
  std::vector<std::uint8_t> defined, moved_defined;
  const std::vector<float> a = ComputeFpfh(points, normals, 2.5, &defined).value();
  const std::vector<float> b =
      ComputeFpfh(moved_points, moved_normals, 2.5, &moved_defined).value();
  ASSERT_EQ(defined, moved_defined);
  std::vector<double> l1;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!defined[i]) continue;
    double d = 0.0;
    for (int k = 0; k < kFpfhBins; ++k) d += std::abs(a[i * kFpfhBins + k] - b[i * kFpfhBins + k]);
    l1.push_back(d);
  }
  std::sort(l1.begin(), l1.end());
  ASSERT_GT(l1.size(), points.size() / 2);
  EXPECT_LT(l1[l1.size() / 2], 0.01);
  EXPECT_LT(l1[l1.size() * 99 / 100], 1.0);
}

TEST(FpfhFeaturesTest, FeaturesOfOthersIgnoreThePointsWithoutANormal) {
  const PointVector points = Scene();
  const std::vector<Eigen::Vector3d> normals = ToEigen(*PclNormals(ToPcl(points), 1.0));
  // The same scene with points without a normal scattered through it.
  PointVector with_extra = points;
  std::vector<Eigen::Vector3d> extra_normals = normals;
  for (double x = -9.75; x < 10.0; x += 1.5) {
    with_extra.emplace_back(x, 0.25, 1.0);
    extra_normals.push_back(x < 0.0 ? Eigen::Vector3d::Zero()
                                    : Eigen::Vector3d::Constant(std::nan("")));
  }
  std::vector<std::uint8_t> defined, extra_defined;
  const std::vector<float> a = ComputeFpfh(points, normals, 2.5, &defined).value();
  const std::vector<float> b = ComputeFpfh(with_extra, extra_normals, 2.5, &extra_defined).value();
  for (std::size_t i = points.size(); i < with_extra.size(); ++i) EXPECT_EQ(extra_defined[i], 0);
  for (std::size_t i = 0; i < points.size(); ++i) {
    ASSERT_EQ(defined[i], extra_defined[i]) << "point " << i;
    for (int k = 0; k < kFpfhBins; ++k) {  // the kd-tree (and so the order of sums) differs
      ASSERT_NEAR(a[i * kFpfhBins + k], b[i * kFpfhBins + k], 1e-3)
          << "point " << i << " bin " << k;
    }
  }
}

TEST(FpfhFeaturesTest, EachAngleBlockSumsToOneHundred) {
  const PointVector points = Scene();
  const std::vector<Eigen::Vector3d> normals = ToEigen(*PclNormals(ToPcl(points), 1.0));
  std::vector<std::uint8_t> defined;
  const std::vector<float> f = ComputeFpfh(points, normals, 2.5, &defined).value();
  ASSERT_EQ(f.size(), points.size() * kFpfhBins);
  for (std::size_t i = 0; i < points.size(); ++i) {
    for (int block = 0; block < 3; ++block) {
      double sum = 0.0;
      for (int b = 0; b < kFpfhBinsPerAngle; ++b) {
        sum += f[i * kFpfhBins + block * kFpfhBinsPerAngle + b];
      }
      EXPECT_NEAR(sum, defined[i] ? 100.0 : 0.0, 1e-3) << "point " << i << " block " << block;
    }
  }
}

TEST(FpfhFeaturesTest, PointsWithoutANormalOrNeighboursAreUndefined) {
  PointVector points = {{0.0, 0.0, 0.0}, {1.0, 0.0, 0.0}, {0.0, 1.0, 0.5}, {50.0, 0.0, 0.0}};
  std::vector<Eigen::Vector3d> normals = {Eigen::Vector3d::UnitZ(), Eigen::Vector3d::Zero(),
                                          Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitZ()};
  std::vector<std::uint8_t> defined;
  const std::vector<float> f = ComputeFpfh(points, normals, 2.0, &defined).value();
  // Point 0 pairs with point 2 (point 1 has no normal); point 3 has no neighbour.
  EXPECT_EQ(defined, (std::vector<std::uint8_t>{1, 0, 1, 0}));
  for (int b = 0; b < kFpfhBins; ++b) {
    EXPECT_EQ(f[1 * kFpfhBins + b], 0.0f);
    EXPECT_EQ(f[3 * kFpfhBins + b], 0.0f);
  }
}

TEST(FpfhFeaturesTest, RejectsBadInput) {
  std::vector<std::uint8_t> defined;
  const PointVector points = {{0.0, 0.0, 0.0}, {1.0, 0.0, 0.0}};
  const std::vector<Eigen::Vector3d> one = {Eigen::Vector3d::UnitZ()};
  const std::vector<Eigen::Vector3d> two(2, Eigen::Vector3d::UnitZ());
  EXPECT_FALSE(ComputeFpfh(points, one, 1.0, &defined).ok());
  EXPECT_FALSE(ComputeFpfh(points, two, 0.0, &defined).ok());
  EXPECT_FALSE(ComputeFpfh(points, two, std::nan(""), &defined).ok());
  PointVector bad = points;
  bad[1].x() = std::nan("");
  EXPECT_FALSE(ComputeFpfh(bad, two, 1.0, &defined).ok());
  EXPECT_FALSE(ComputeFpfh(points, two, 1.0, nullptr).ok());
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
