#include "multisession_mapper/core/icp_registration.h"

#include <cmath>
#include <fstream>
#include <iostream>
#include <random>
#include <string>
#include <sys/stat.h>

#include <gtest/gtest.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include "multisession_mapper/core/kdtree_target.h"
#include "multisession_mapper/core/se3.h"
#include "multisession_mapper/core/voxel_downsample.h"
#include "multisession_mapper/core/voxel_hash_map.h"
#include "synthetic_lidar_scene.h"

namespace multisession_mapper {
namespace core {
namespace {

constexpr double kDeg = M_PI / 180.0;

// A static scan (no motion during the sweep) of the synthetic scene from `pose`.
PointVector StaticScan(const test::SyntheticScene& scene, const Pose3& pose, unsigned seed) {
  const LidarScan scan = test::SimulateVlp16(
      scene, [&pose](double) { return pose; }, 0.0, seed, 0.01, 1800, 0.1, false);
  return ScanToPointVector(scan);
}

struct SyntheticPair {
  PointVector target;  // frame of scan A: scans from 7 nearby poses merged, like a local map
  PointVector source;  // sensor frame of scan B, one scan
  Pose3 T_a_b;
};

// One VLP-16 scan has 2 deg between rings, so a single scan is too sparse for normals on far
// walls; the registrations that matter (scan-to-local-map, submap-to-submap) have merged
// scans as target, so the test does the same.
SyntheticPair MakePair() {
  const Pose3 pose_a = se3::FromXyzRpy(0.0, 0.0, 1.8, 0.0, 0.0, 0.3);
  SyntheticPair pair;
  pair.T_a_b = se3::FromXyzRpy(0.8, -0.3, 0.05, 1.0 * kDeg, -0.5 * kDeg, 6.0 * kDeg);
  const test::SyntheticScene scene(21, 80, 60.0, {Eigen::Vector2d(0, 0), Eigen::Vector2d(1, 0)},
                                   6.0);
  for (int i = 0; i < 7; ++i) {
    const Pose3 T_a_i =
        se3::FromXyzRpy(-1.5 + 0.5 * i, 0.3 * (i % 3) - 0.3, 0.02 * (i % 2),
                        0.5 * kDeg * (i % 3 - 1), 0.4 * kDeg * (i % 2), 2.0 * kDeg * i);
    for (const Eigen::Vector3d& p : StaticScan(scene, pose_a * T_a_i, 10 + i)) {
      pair.target.push_back(T_a_i * p);
    }
  }
  pair.source = StaticScan(scene, pose_a * pair.T_a_b, 2);
  return pair;
}

void ExpectPoseNear(const Pose3& estimate, const Pose3& truth, double max_t_m, double max_r_rad) {
  const Pose3 error = se3::Between(truth, estimate);
  EXPECT_LT(se3::TranslationNorm(error), max_t_m) << "estimate\n" << estimate.matrix();
  EXPECT_LT(se3::RotationAngleRad(error), max_r_rad) << "estimate\n" << estimate.matrix();
}

TEST(IcpRegistrationTest, RecoversKnownTransformOnSyntheticSceneWithKdTreeTarget) {
  const SyntheticPair pair = MakePair();
  const KdTreeTarget target = KdTreeTarget::Create(VoxelDownsample(pair.target, 0.2)).value();
  const PointVector source = VoxelDownsample(pair.source, 0.3);
  const IcpRegistration icp = IcpRegistration::Create(IcpConfig()).value();
  // From identity (0.85 m and 6 deg away): a wide coarse pass, then the fine one, as a
  // submap-to-submap caller does from a loose prior.
  const StatusOr<IcpResult> coarse = icp.Register(source, target, Pose3::Identity(), 3.0, 1.0);
  ASSERT_TRUE(coarse.ok()) << coarse.status().message();
  const StatusOr<IcpResult> result = icp.Register(source, target, coarse.value().pose, 1.0, 0.2);
  ASSERT_TRUE(result.ok()) << result.status().message();
  ExpectPoseNear(result.value().pose, pair.T_a_b, 0.02, 0.1 * kDeg);
  EXPECT_TRUE(result.value().converged);
  EXPECT_GT(result.value().fitness, 0.8);
  EXPECT_LT(result.value().rmse_m, 0.3);
  EXPECT_GT(result.value().hessian.trace(), 0.0);
  // Most of the source fits within the kernel's scale at the solution.
  EXPECT_GT(result.value().mean_weight, 0.5);
  EXPECT_LE(result.value().mean_weight, 1.0);
}

// The update rotates about the source origin, not the target origin: the same registration
// 2.5 km from the target origin (a robot deep into its odometry frame) must converge as fast
// and land as close as at the origin. Rotating about the target origin, a rotation step of
// 1e-6 rad there is a 2.5 mm translation step, and the translation convergence threshold
// (0.1 mm) was met only after many more iterations, if at all (campus s02: 27 % of the scans
// ran into max_iterations).
TEST(IcpRegistrationTest, ConvergesAsFastFarFromTheTargetOrigin) {
  const SyntheticPair pair = MakePair();
  const Pose3 guess_offset = se3::FromXyzRpy(0.2, 0.1, 0.0, 0.0, 0.0, 1.0 * kDeg);
  const IcpRegistration icp = IcpRegistration::Create(IcpConfig()).value();
  const PointVector source = VoxelDownsample(pair.source, 0.5);
  int iterations[2] = {0, 0};
  for (int far = 0; far < 2; ++far) {
    const Pose3 T_far_a = far ? se3::FromXyzRpy(2000.0, -1500.0, 10.0, 0.0, 0.0, 0.7)
                              : Pose3::Identity();
    PointVector target;
    for (const Eigen::Vector3d& p : VoxelDownsample(pair.target, 0.1)) target.push_back(T_far_a * p);
    VoxelHashMap map = VoxelHashMap::Create(VoxelHashMapConfig()).value();
    map.AddPoints(target);
    const Pose3 truth = T_far_a * pair.T_a_b;
    const StatusOr<IcpResult> result = icp.Register(source, map, truth * guess_offset, 1.0, 0.2);
    ASSERT_TRUE(result.ok()) << result.status().message();
    ExpectPoseNear(result.value().pose, truth, 0.02, 0.1 * kDeg);
    EXPECT_TRUE(result.value().converged) << (far ? "far" : "near");
    iterations[far] = result.value().iterations;
  }
  std::cout << "iterations at the origin " << iterations[0] << ", 2.5 km away " << iterations[1]
            << "\n";
  EXPECT_LE(iterations[1], iterations[0] + 1);
}

TEST(IcpRegistrationTest, RecoversKnownTransformAgainstVoxelMap) {
  const SyntheticPair pair = MakePair();
  VoxelHashMap map = VoxelHashMap::Create(VoxelHashMapConfig()).value();
  map.AddPoints(VoxelDownsample(pair.target, 0.1));
  const IcpRegistration icp = IcpRegistration::Create(IcpConfig()).value();
  // Start close enough for the one-voxel search reach (as the odometry's prediction is).
  const Pose3 guess = pair.T_a_b * se3::FromXyzRpy(0.2, 0.1, 0.0, 0.0, 0.0, 1.0 * kDeg);
  const StatusOr<IcpResult> result =
      icp.Register(VoxelDownsample(pair.source, 0.5), map, guess, 1.0, 0.2);
  ASSERT_TRUE(result.ok()) << result.status().message();
  ExpectPoseNear(result.value().pose, pair.T_a_b, 0.02, 0.1 * kDeg);
}

TEST(IcpRegistrationTest, ReassociationSearchesLessAndLandsOnTheSamePose) {
  const SyntheticPair pair = MakePair();
  VoxelHashMap map = VoxelHashMap::Create(VoxelHashMapConfig()).value();
  map.AddPoints(VoxelDownsample(pair.target, 0.1));
  const PointVector source = VoxelDownsample(pair.source, 0.5);
  const Pose3 guess = pair.T_a_b * se3::FromXyzRpy(0.2, 0.1, 0.0, 0.0, 0.0, 1.0 * kDeg);
  IcpConfig config;
  config.max_iterations = 100;
  const StatusOr<IcpResult> every =
      IcpRegistration::Create(config).value().Register(source, map, guess, 1.0, 0.2);
  config.reassociate_translation_m = 0.03;
  config.reassociate_rotation_rad = 0.003;
  const StatusOr<IcpResult> lazy =
      IcpRegistration::Create(config).value().Register(source, map, guess, 1.0, 0.2);
  ASSERT_TRUE(every.ok() && lazy.ok());
  EXPECT_EQ(every.value().searches, every.value().iterations);
  EXPECT_LT(lazy.value().searches, every.value().searches);
  EXPECT_TRUE(lazy.value().converged);
  ExpectPoseNear(lazy.value().pose, pair.T_a_b, 0.02, 0.1 * kDeg);
  ExpectPoseNear(lazy.value().pose, every.value().pose, 0.005, 0.02 * kDeg);
  std::cout << "searches: every iteration " << every.value().searches << ", re-associating "
            << lazy.value().searches << " in " << lazy.value().iterations << " iterations\n";
  config.reassociate_rotation_rad = -1.0;
  EXPECT_FALSE(config.Validate().ok());
}

// A schedule of correspondence distances with the searches' memory carried from one distance
// to the next (SubmapRegistration does so): every distance's first search is warm-started,
// and each stage lands on the pose it lands on without the memory, to the bit.
TEST(IcpRegistrationTest, SearchMemoryAcrossAScheduleGivesTheSamePoses) {
  const SyntheticPair pair = MakePair();
  const KdTreeTarget target = KdTreeTarget::Create(VoxelDownsample(pair.target, 0.2)).value();
  const PointVector source = VoxelDownsample(pair.source, 0.3);
  const IcpRegistration icp = IcpRegistration::Create(IcpConfig()).value();
  Pose3 cold = Pose3::Identity(), warm = Pose3::Identity();
  IcpSearchMemory memory;
  for (const double distance : {3.0, 1.0, 0.5}) {
    const StatusOr<IcpResult> a = icp.Register(source, target, cold, distance, distance / 3.0);
    const StatusOr<IcpResult> b =
        icp.Register(source, target, warm, distance, distance / 3.0, &memory);
    ASSERT_TRUE(a.ok() && b.ok());
    EXPECT_EQ(a.value().pose.matrix(), b.value().pose.matrix()) << "distance " << distance;
    EXPECT_EQ(a.value().searches, b.value().searches);
    EXPECT_EQ(a.value().num_inliers, b.value().num_inliers);
    ASSERT_EQ(memory.found.size(), source.size());  // holds this stage's last search
    cold = a.value().pose;
    warm = b.value().pose;
  }
  ExpectPoseNear(warm, pair.T_a_b, 0.02, 0.1 * kDeg);
}

// The odometry registers one scan's points several times against the unchanged local map,
// the last time with more source normals (the map-ground refinement): the memory's entries
// follow their source points into another set of searched points (below), and each
// registration lands where it lands without the memory.
TEST(IcpRegistrationTest, SearchMemoryFollowsTheSourcePointsAcrossNormalSets) {
  const SyntheticPair pair = MakePair();
  VoxelHashMap map = VoxelHashMap::Create(VoxelHashMapConfig()).value();
  map.AddPoints(VoxelDownsample(pair.target, 0.1));
  const PointVector source = VoxelDownsample(pair.source, 0.3);
  PointVector normals(source.size(), Eigen::Vector3d::Zero());
  for (std::size_t i = 0; i < source.size(); ++i) {
    Eigen::Vector3d n;
    if (map.PlaneNormalAt(pair.T_a_b * source[i], &n)) {
      normals[i] = pair.T_a_b.linear().transpose() * n;
    }
  }
  const KdTreeTarget target = KdTreeTarget::Create(map.Points()).value();
  // Every other point with a normal, the other half, and all of them: sets of nearly equal
  // size whose entries differ, so entries kept by position would bound the wrong points.
  PointVector even = normals, odd = normals;
  for (std::size_t i = 0; i < source.size(); ++i) (i % 2 == 0 ? odd : even)[i].setZero();
  const IcpRegistration icp = IcpRegistration::Create(IcpConfig()).value();
  const Pose3 guess = pair.T_a_b * se3::FromXyzRpy(0.3, -0.2, 0.05, 0.0, 0.5 * kDeg, 2.0 * kDeg);
  for (const PointVector* next : {&odd, &normals}) {
    IcpSearchMemory memory;
    const StatusOr<IcpResult> first =
        icp.Register(source, even, target, guess, 1.0, 0.3, IcpTranslationPrior(), &memory);
    ASSERT_TRUE(first.ok());
    ASSERT_EQ(memory.searched.size(), memory.found.size());
    const Pose3 from = first.value().pose * se3::FromXyzRpy(0.05, 0.0, 0.0, 0.0, 0.0, 0.2 * kDeg);
    const StatusOr<IcpResult> cold = icp.Register(source, *next, target, from, 1.0, 0.3);
    const StatusOr<IcpResult> warm =
        icp.Register(source, *next, target, from, 1.0, 0.3, IcpTranslationPrior(), &memory);
    ASSERT_TRUE(cold.ok() && warm.ok());
    EXPECT_EQ(cold.value().pose.matrix(), warm.value().pose.matrix());
    EXPECT_EQ(cold.value().searches, warm.value().searches);
    EXPECT_EQ(cold.value().num_inliers, warm.value().num_inliers);
    std::size_t with_normal = 0;
    for (const Eigen::Vector3d& n : *next) with_normal += n.isZero(0.0) ? 0 : 1;
    EXPECT_EQ(memory.searched.size(), with_normal);
    ExpectPoseNear(warm.value().pose, pair.T_a_b, 0.02, 0.1 * kDeg);
  }
}

TEST(IcpRegistrationTest, SearchMemoryEntriesFollowTheirSourcePoints) {
  IcpSearchMemory memory;
  memory.searched = {1, 3, 5};
  memory.found = {1, 0, 1};
  memory.matches.resize(3);
  for (int k = 0; k < 3; ++k) memory.matches[k].point = Eigen::Vector3d(k + 1.0, 0.0, 0.0);
  memory.matches[1].distance_sq = 4.0;  // a miss memo
  memory.FollowSourcePoints({0, 1, 3, 6});
  EXPECT_EQ(memory.searched, (std::vector<std::size_t>{0, 1, 3, 6}));
  ASSERT_EQ(memory.found, (std::vector<std::uint8_t>{0, 1, 0, 0}));
  ASSERT_EQ(memory.matches.size(), 4u);
  EXPECT_EQ(memory.matches[0].point, Eigen::Vector3d::Zero());  // new: no hint
  EXPECT_EQ(memory.matches[0].distance_sq, 0.0);
  EXPECT_EQ(memory.matches[1].point, Eigen::Vector3d(1.0, 0.0, 0.0));
  EXPECT_EQ(memory.matches[2].point, Eigen::Vector3d(2.0, 0.0, 0.0));  // point 3's miss memo
  EXPECT_EQ(memory.matches[2].distance_sq, 4.0);
  EXPECT_EQ(memory.matches[3].distance_sq, 0.0);
  // Entries that do not fit their indices (never filled by a registration): a cold start.
  memory.found.pop_back();
  memory.FollowSourcePoints({2, 3});
  EXPECT_TRUE(memory.found.empty() && memory.matches.empty());
  EXPECT_EQ(memory.searched, (std::vector<std::size_t>{2, 3}));
}

TEST(IcpRegistrationTest, SearchThreadsGiveTheSamePose) {
  const SyntheticPair pair = MakePair();
  VoxelHashMap map = VoxelHashMap::Create(VoxelHashMapConfig()).value();
  map.AddPoints(VoxelDownsample(pair.target, 0.1));
  map.SetNormalsEnabled(false);  // as in the odometry: only then is the search split
  const PointVector source = VoxelDownsample(pair.source, 0.2);
  ASSERT_GT(source.size(), 1000u);  // enough queries for the parallel path
  const Pose3 guess = pair.T_a_b * se3::FromXyzRpy(0.2, 0.1, 0.0, 0.0, 0.0, 1.0 * kDeg);
  IcpConfig config;
  config.point_to_point_fallback = true;  // no normals: every pair is point-to-point
  const StatusOr<IcpResult> one =
      IcpRegistration::Create(config).value().Register(source, map, guess, 1.0, 0.2);
  config.search_threads = 2;
  const StatusOr<IcpResult> two =
      IcpRegistration::Create(config).value().Register(source, map, guess, 1.0, 0.2);
  ASSERT_TRUE(one.ok() && two.ok());
  EXPECT_EQ(one.value().pose.matrix(), two.value().pose.matrix());
  EXPECT_EQ(one.value().iterations, two.value().iterations);
  EXPECT_EQ(one.value().num_inliers, two.value().num_inliers);
  // Point-to-point pairs on sampled rings are biased (see point_to_point_fallback): loose.
  ExpectPoseNear(two.value().pose, pair.T_a_b, 0.1, 1.0 * kDeg);
  config.search_threads = 0;
  EXPECT_FALSE(config.Validate().ok());
}

// A copy at other convergence steps (the odometry's judge): the coarse one stops sooner, and
// the fine one run on from where it stopped lands where the fine one lands from the guess.
TEST(IcpRegistrationTest, CopyWithOtherConvergenceRunsOnFromACoarseStop) {
  const SyntheticPair pair = MakePair();
  VoxelHashMap map = VoxelHashMap::Create(VoxelHashMapConfig()).value();
  map.AddPoints(VoxelDownsample(pair.target, 0.1));
  map.SetNormalsEnabled(false);
  const PointVector source = VoxelDownsample(pair.source, 0.2);
  const Pose3 guess = pair.T_a_b * se3::FromXyzRpy(0.2, 0.1, 0.0, 0.0, 0.0, 1.0 * kDeg);
  IcpConfig config;
  config.point_to_point_fallback = true;
  config.search_threads = 2;
  config.max_iterations = 100;
  const IcpRegistration fine = IcpRegistration::Create(config).value();
  const StatusOr<IcpRegistration> coarse = fine.WithConvergence(3e-3, 3e-4, 100);
  ASSERT_TRUE(coarse.ok()) << coarse.status().message();
  EXPECT_DOUBLE_EQ(coarse.value().config().convergence_translation_m, 3e-3);
  EXPECT_DOUBLE_EQ(coarse.value().config().convergence_rotation_rad, 3e-4);
  EXPECT_EQ(coarse.value().config().search_threads, 2);
  const StatusOr<IcpResult> direct = fine.Register(source, map, guess, 1.0, 0.2);
  const StatusOr<IcpResult> stopped = coarse.value().Register(source, map, guess, 1.0, 0.2);
  ASSERT_TRUE(direct.ok() && stopped.ok());
  const StatusOr<IcpResult> continued =
      fine.Register(source, map, stopped.value().pose, 1.0, 0.2);
  ASSERT_TRUE(continued.ok());
  std::cout << "iterations: fine " << direct.value().iterations << ", coarse "
            << stopped.value().iterations << " + fine from there "
            << continued.value().iterations << "\n";
  EXPECT_TRUE(direct.value().converged && stopped.value().converged);
  EXPECT_LT(stopped.value().iterations, direct.value().iterations);
  ExpectPoseNear(continued.value().pose, direct.value().pose, 0.002, 0.01 * kDeg);
  EXPECT_FALSE(fine.WithConvergence(-1.0, 1e-4, 30).ok());
  EXPECT_FALSE(fine.WithConvergence(1e-3, 1e-4, 0).ok());
}

TEST(IcpRegistrationTest, FailsClearlyWithoutOverlapOrTarget) {
  const IcpRegistration icp = IcpRegistration::Create(IcpConfig()).value();
  VoxelHashMap empty = VoxelHashMap::Create(VoxelHashMapConfig()).value();
  const PointVector source(100, Eigen::Vector3d(1.0, 2.0, 3.0));
  EXPECT_FALSE(icp.Register(source, empty, Pose3::Identity()).ok());
  const KdTreeTarget far = KdTreeTarget::Create({{100.0, 0.0, 0.0}}).value();
  const StatusOr<IcpResult> r = icp.Register(source, far, Pose3::Identity());
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("correspondences"), std::string::npos);
  IcpConfig bad;
  bad.max_iterations = 0;
  EXPECT_FALSE(IcpRegistration::Create(bad).ok());
}

// A corridor: ground and two long parallel walls along x, sampled at random. The pairs fix
// y, z, roll, pitch and yaw but say nothing about x.
PointVector Corridor() {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> along(-30.0, 30.0), across(-2.9, 2.9), up(0.1, 3.0);
  PointVector points;
  for (int i = 0; i < 20000; ++i) {
    switch (i % 3) {
      case 0: points.emplace_back(along(rng), across(rng), 0.0); break;
      case 1: points.emplace_back(along(rng), -3.0, up(rng)); break;
      default: points.emplace_back(along(rng), 3.0, up(rng)); break;
    }
  }
  return points;
}

// The translation prior holds the direction the pairs do not constrain at the prior's value,
// while the constrained ones follow the pairs (a weight of 20 pairs against hundreds).
TEST(IcpRegistrationTest, TranslationPriorHoldsOnlyTheUnconstrainedDirection) {
  const PointVector corridor = Corridor();
  const KdTreeTarget target = KdTreeTarget::Create(corridor).value();
  PointVector source;  // away from the corridor's ends
  for (const Eigen::Vector3d& p : VoxelDownsample(corridor, 0.5)) {
    if (std::abs(p.x()) < 20.0) source.push_back(p);
  }
  const IcpRegistration icp = IcpRegistration::Create(IcpConfig()).value();
  const Pose3 guess = se3::FromXyzRpy(0.3, 0.2, -0.1, 0.0, 0.0, 1.0 * kDeg);
  IcpTranslationPrior prior;
  prior.translation = Eigen::Vector3d(0.1, 0.15, 0.05);
  prior.weight = 20.0;
  const StatusOr<IcpResult> with = icp.Register(source, target, guess, 1.0, 0.3, prior);
  ASSERT_TRUE(with.ok()) << with.status().message();
  const Eigen::Vector3d t = with.value().pose.translation();
  EXPECT_NEAR(t.x(), 0.1, 5e-3);   // the prior's
  EXPECT_NEAR(t.y(), 0.0, 0.01);   // the walls'
  EXPECT_NEAR(t.z(), 0.0, 0.01);   // the ground's
  EXPECT_LT(se3::RotationAngleRad(with.value().pose), 0.2 * kDeg);
  // The Hessian reported is the pairs' own: little along x (some from the edges' normals).
  EXPECT_LT(with.value().hessian(0, 0), 0.01 * with.value().hessian(1, 1));

  IcpTranslationPrior bad = prior;
  bad.weight = -1.0;
  const StatusOr<IcpResult> refused = icp.Register(source, target, guess, 1.0, 0.3, bad);
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.status().message().find("prior"), std::string::npos);
}

// --- Real data: two outdoor scans from koide3/fast_gicp (see ../shared/data/real/README.md).
bool Exists(const std::string& path) {
  struct stat st;
  return stat(path.c_str(), &st) == 0;
}

PointVector LoadXyz(const std::string& path) {
  pcl::PointCloud<pcl::PointXYZ> cloud;
  if (pcl::io::loadPCDFile(path, cloud) != 0) return {};
  PointVector out;
  for (const pcl::PointXYZ& p : cloud) {
    if (std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z)) {
      out.emplace_back(p.x, p.y, p.z);
    }
  }
  return out;
}

class RealPairTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const std::string dir = std::string(MSM_SHARED_DATA_DIR) + "/real/fast_gicp_pair";
    if (!Exists(dir + "/relative.txt")) GTEST_SKIP() << "no real data at " << dir;
    target_ = LoadXyz(dir + "/251370668.pcd");
    source_ = LoadXyz(dir + "/251371071.pcd");
    std::ifstream in(dir + "/relative.txt");
    Eigen::Matrix4d m;
    for (int i = 0; i < 16; ++i) in >> m(i / 4, i % 4);
    ASSERT_TRUE(in.good() || in.eof());
    relative_ = Pose3(m);  // maps 251371071 (source) into 251370668 (target); checked by ICP
    ASSERT_GT(target_.size(), 60000u);
    ASSERT_GT(source_.size(), 60000u);
  }
  PointVector target_, source_;
  Pose3 relative_ = Pose3::Identity();
};

StatusOr<IcpResult> AlignRealPair(const PointVector& source, const PointVector& target,
                                  const Pose3& guess) {
  const KdTreeTarget tree = KdTreeTarget::Create(VoxelDownsample(target, 0.1)).value();
  IcpConfig config;
  config.max_correspondence_distance_m = 1.0;
  config.kernel_scale_m = 0.2;
  config.max_iterations = 50;
  return IcpRegistration::Create(config).value().Register(VoxelDownsample(source, 0.5), tree,
                                                          guess);
}

TEST_F(RealPairTest, RecoversPublishedRelativeTransformFromIdentity) {
  const StatusOr<IcpResult> result = AlignRealPair(source_, target_, Pose3::Identity());
  ASSERT_TRUE(result.ok()) << result.status().message();
  const Pose3 error = se3::Between(relative_, result.value().pose);
  std::cout << "real pair: error " << se3::TranslationNorm(error) * 100.0 << " cm, "
            << se3::RotationAngleRad(error) / kDeg << " deg, " << result.value().iterations
            << " iterations, fitness " << result.value().fitness << std::endl;
  // relative.txt is not the optimum of any local method on this pair: our point-to-plane
  // lands 0.3-0.4 deg from it and PCL's GICP 0.25-0.5 deg (odometry_benchmark), and the
  // residuals at our result are lower than at relative.txt. 2 cm / 0.1 deg is therefore not
  // checkable here; the bound is tighter than the data's own upstream test (5 cm / 1 deg).
  EXPECT_LT(se3::TranslationNorm(error), 0.04);
  EXPECT_LT(se3::RotationAngleRad(error), 0.5 * kDeg);
}

TEST_F(RealPairTest, ForwardAndBackwardAlignmentsAreConsistent) {
  const StatusOr<IcpResult> forward = AlignRealPair(source_, target_, Pose3::Identity());
  const StatusOr<IcpResult> backward = AlignRealPair(target_, source_, Pose3::Identity());
  ASSERT_TRUE(forward.ok() && backward.ok());
  const Pose3 loop = forward.value().pose * backward.value().pose;  // identity if consistent
  EXPECT_LT(se3::TranslationNorm(loop), 0.02);
  EXPECT_LT(se3::RotationAngleRad(loop), 0.2 * kDeg);
}


// Counts the queries it is asked, and answers as the wrapped target.
class CountingTarget : public RegistrationTarget {
 public:
  explicit CountingTarget(const RegistrationTarget& target) : target_(target) {}
  bool FindMatch(const Eigen::Vector3d& query, double max_distance_m,
                 TargetMatch* match) const override {
    ++queries;
    return target_.FindMatch(query, max_distance_m, match);
  }
  void FindMatches(const PointVector& queries_in, double max_distance_m, bool warm_start,
                   WorkerPool* pool, std::vector<std::uint8_t>* found,
                   std::vector<TargetMatch>* matches) const override {
    queries += queries_in.size();
    target_.FindMatches(queries_in, max_distance_m, warm_start, pool, found, matches);
  }
  bool empty() const override { return target_.empty(); }
  mutable std::size_t queries = 0;

 private:
  const RegistrationTarget& target_;
};

// With the source's own normals and no point-to-point fallback, a point without a normal
// never pairs: it is not searched, and the registration is bit for bit that of the points
// with normals alone (same pairs in the same order), its mean weight over all the points.
TEST(IcpRegistrationTest, PointsWithoutNormalsAreNotSearched) {
  const SyntheticPair pair = MakePair();
  VoxelHashMap map = VoxelHashMap::Create(VoxelHashMapConfig()).value();
  map.AddPoints(VoxelDownsample(pair.target, 0.1));
  map.SetNormalsEnabled(false);  // as the odometry: the normals are the source's
  const PointVector all = VoxelDownsample(pair.source, 0.5);
  PointVector normals, with_normal, their_normals;
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (std::size_t i = 0; i < all.size(); ++i) {
    // Every third point without a normal; the others with some unit normal (the planes need
    // not be right for this comparison).
    const Eigen::Vector3d n = Eigen::Vector3d(u(rng), u(rng), 1.0).normalized();
    normals.push_back(i % 3 == 0 ? Eigen::Vector3d::Zero() : n);
    if (i % 3 != 0) {
      with_normal.push_back(all[i]);
      their_normals.push_back(n);
    }
  }
  const Pose3 guess = pair.T_a_b * se3::FromXyzRpy(0.2, 0.1, 0.0, 0.0, 0.0, 1.0 * kDeg);
  IcpConfig reassociating;  // searches again only after a step: iterations on old pairs too
  reassociating.reassociate_translation_m = 0.02;
  reassociating.reassociate_rotation_rad = 0.002;
  for (const IcpConfig& config : {IcpConfig(), reassociating}) {
    const IcpRegistration icp = IcpRegistration::Create(config).value();
    CountingTarget counted_all(map), counted_subset(map);
    const StatusOr<IcpResult> a = icp.Register(all, normals, counted_all, guess, 1.0, 0.2);
    const StatusOr<IcpResult> b =
        icp.Register(with_normal, their_normals, counted_subset, guess, 1.0, 0.2);
    ASSERT_TRUE(a.ok()) << a.status().message();
    ASSERT_TRUE(b.ok()) << b.status().message();
    EXPECT_EQ(a.value().pose.matrix(), b.value().pose.matrix());
    EXPECT_EQ(a.value().iterations, b.value().iterations);
    EXPECT_EQ(a.value().num_inliers, b.value().num_inliers);
    EXPECT_DOUBLE_EQ(a.value().mean_weight * static_cast<double>(all.size()),
                     b.value().mean_weight * static_cast<double>(with_normal.size()));
    EXPECT_EQ(counted_all.queries, counted_subset.queries);
    EXPECT_EQ(counted_all.queries,
              static_cast<std::size_t>(a.value().searches) * with_normal.size());
    if (config.reassociate_translation_m > 0.0) {
      EXPECT_LT(a.value().searches, a.value().iterations);  // the variant did what it is for
    }
  }
  // With the point-to-point fallback every point is searched and may pair.
  IcpConfig fallback_config;
  fallback_config.point_to_point_fallback = true;
  const IcpRegistration fallback = IcpRegistration::Create(fallback_config).value();
  CountingTarget counted_fallback(map);
  const StatusOr<IcpResult> c = fallback.Register(all, normals, counted_fallback, guess, 1.0, 0.2);
  ASSERT_TRUE(c.ok()) << c.status().message();
  EXPECT_EQ(counted_fallback.queries, static_cast<std::size_t>(c.value().searches) * all.size());
}

TEST(IcpRegistrationTest, SourceNormalsMustMatchTheSource) {
  const IcpRegistration icp = IcpRegistration::Create(IcpConfig()).value();
  PointVector target_points;
  for (int i = 0; i < 20; ++i) {
    for (int j = 0; j < 20; ++j) target_points.emplace_back(0.2 * i, 0.2 * j, 0.0);
  }
  const KdTreeTarget target = KdTreeTarget::Create(target_points).value();
  PointVector source(target_points.begin(), target_points.begin() + 100);
  for (Eigen::Vector3d& p : source) p.z() += 0.05;
  EXPECT_FALSE(icp.Register(source, PointVector(3), target, Pose3::Identity(), 1.0, 0.2).ok());
  // A flat patch with its (source) normals: only z is constrained, and it is recovered.
  const PointVector normals(source.size(), Eigen::Vector3d::UnitZ());
  const StatusOr<IcpResult> r =
      icp.Register(source, normals, target, Pose3::Identity(), 1.0, 0.2);
  ASSERT_TRUE(r.ok()) << r.status().message();
  EXPECT_NEAR(r.value().pose.translation().z(), -0.05, 1e-3);
}
}  // namespace
}  // namespace core
}  // namespace multisession_mapper
