#include "multisession_mapper/core/global_registration.h"

#include <sys/stat.h>

#include <cmath>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_types.h>

#include "multisession_mapper/core/se3.h"
#include "multisession_mapper/core/voxel_downsample.h"
#include "synthetic_lidar_scene.h"

namespace multisession_mapper {
namespace core {
namespace {

constexpr double kDeg = M_PI / 180.0;

// A submap of the synthetic scene: scans from `poses` (T_world_sensor, static sensor),
// accumulated in the frame of the first pose and downsampled to 0.2 m as SubmapBuilder does.
PointVector SimulateSubmap(const test::SyntheticScene& scene,
                           const std::vector<Pose3, Eigen::aligned_allocator<Pose3>>& poses,
                           unsigned seed) {
  PointVector points;
  const Pose3 T_submap_world = poses.front().inverse();
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const Pose3 pose = poses[i];
    const LidarScan scan = test::SimulateVlp16(
        scene, [&](double) { return pose; }, 0.0, seed + static_cast<unsigned>(i), 0.01, 900,
        0.1, false, 80.0);
    const Pose3 T_submap_sensor = T_submap_world * pose;
    for (const LidarPoint& p : scan.points) {
      points.push_back(T_submap_sensor * p.position_m.cast<double>());
    }
  }
  return VoxelDownsample(points, 0.2);
}

// Sensor poses every 2 m along a 20 m straight drive from (x, y) with heading `yaw_rad`.
std::vector<Pose3, Eigen::aligned_allocator<Pose3>> Drive(double x, double y, double yaw_rad) {
  std::vector<Pose3, Eigen::aligned_allocator<Pose3>> poses;
  for (int i = 0; i <= 10; ++i) {
    const double s = 2.0 * i;
    poses.push_back(se3::FromXyzRpy(x + s * std::cos(yaw_rad), y + s * std::sin(yaw_rad), 1.8,
                                    0.01 * std::sin(i), 0.01 * std::cos(i), yaw_rad));
  }
  return poses;
}

std::vector<Eigen::Vector2d> PathOf(const std::vector<Pose3, Eigen::aligned_allocator<Pose3>>& p) {
  std::vector<Eigen::Vector2d> out;
  for (const Pose3& pose : p) out.push_back(pose.translation().head<2>());
  return out;
}

class SyntheticPairTest : public ::testing::Test {
 protected:
  void SetUp() override {
    // Target drives east from (-10, 0); source drives along heading 150 deg from (12, -4): the
    // two drives cross, relative yaw 150 deg, origins about 22 m apart.
    target_poses_ = Drive(-10.0, 0.0, 0.0);
    source_poses_ = Drive(12.0, -4.0, 150.0 * kDeg);
    std::vector<Eigen::Vector2d> clear = PathOf(target_poses_);
    for (const Eigen::Vector2d& p : PathOf(source_poses_)) clear.push_back(p);
    test::SyntheticScene scene(7, 120, 60.0, clear, 3.0);
    target_ = SimulateSubmap(scene, target_poses_, 100);
    source_ = SimulateSubmap(scene, source_poses_, 200);
    truth_ = target_poses_.front().inverse() * source_poses_.front();
    // An unrelated place: another random scene seen from the source's drive.
    test::SyntheticScene other(8, 120, 60.0, clear, 3.0);
    unrelated_ = SimulateSubmap(other, source_poses_, 300);
  }
  // Registers `source` to `target` with the default config and prints why it was judged so.
  static GlobalRegistrationResult RegisterAndPrint(const char* what, const PointVector& source,
                                                   const PointVector& target) {
    const GlobalRegistration registration =
        GlobalRegistration::Create(GlobalRegistrationConfig()).value();
    const GlobalRegistrationResult r = registration.Register(source, target);
    std::cout << what << ": " << r.reason << " (overlap " << r.overlap_ratio << ", structure "
              << r.structure_overlap_ratio << ")" << std::endl;
    return r;
  }

  std::vector<Pose3, Eigen::aligned_allocator<Pose3>> target_poses_, source_poses_;
  PointVector target_, source_, unrelated_;
  Pose3 truth_ = Pose3::Identity();
};

TEST_F(SyntheticPairTest, RecoversLargeYawAndOffsetWithoutGuess) {
  ASSERT_GT(se3::TranslationNorm(truth_), 20.0);
  ASSERT_NEAR(se3::RotationAngleRad(truth_), 150.0 * kDeg, 2.0 * kDeg);
  const GlobalRegistration registration =
      GlobalRegistration::Create(GlobalRegistrationConfig()).value();
  const GlobalRegistrationResult r = registration.Register(source_, target_);
  ASSERT_TRUE(r.accepted) << r.reason;
  const Pose3 error = se3::Between(truth_, r.T_target_source);
  std::cout << "synthetic pair (" << source_.size() << " / " << target_.size() << " points): "
            << se3::TranslationNorm(error) * 100.0 << " cm, "
            << se3::RotationAngleRad(error) / kDeg << " deg, overlap " << r.overlap_ratio
            << ", structure overlap " << r.structure_overlap_ratio << ", "
            << r.coarse_inliers << " RANSAC inliers, " << r.time_s << " s (coarse "
            << r.coarse_time_s << " s)" << std::endl;
  EXPECT_LT(se3::TranslationNorm(error), 0.05);
  EXPECT_LT(se3::RotationAngleRad(error), 0.3 * kDeg);
  EXPECT_GT(r.overlap_ratio, registration.config().fine.min_overlap_ratio);
  EXPECT_TRUE(r.reason.empty());
  // Information from the fine stage's loop sigmas.
  EXPECT_NEAR(r.information(0, 0), 1.0 / (0.1 * 0.1), 1e-6);
}

TEST_F(SyntheticPairTest, ExactFeatureMatchingFindsTheSamePose) {
  // The default matches features approximately (feature_match_epsilon); exact matching must
  // reach the same pose, and the steps' times account for the registration's.
  GlobalRegistrationConfig exact_config;
  exact_config.feature_match_epsilon = 0.0;
  const GlobalRegistration exact = GlobalRegistration::Create(exact_config).value();
  const GlobalRegistration approximate =
      GlobalRegistration::Create(GlobalRegistrationConfig()).value();
  const GlobalRegistrationResult a = exact.Register(source_, target_);
  const GlobalRegistrationResult b = approximate.Register(source_, target_);
  ASSERT_TRUE(a.accepted) << a.reason;
  ASSERT_TRUE(b.accepted) << b.reason;
  const Pose3 between = se3::Between(a.T_target_source, b.T_target_source);
  EXPECT_LT(se3::TranslationNorm(between), 0.01);
  EXPECT_LT(se3::RotationAngleRad(between), 0.05 * kDeg);
  for (const GlobalRegistrationResult* r : {&a, &b}) {
    EXPECT_GT(r->prepare_s, 0.0);
    EXPECT_GT(r->matching_s, 0.0);
    EXPECT_GT(r->fine_s, 0.0);
    const double steps = r->prepare_s + r->matching_s + r->hypotheses_s + r->fine_s;
    EXPECT_LE(steps, r->time_s + 1e-6);
    EXPECT_GT(steps, 0.9 * r->time_s);
  }
}

TEST_F(SyntheticPairTest, RecoversTheSameTransformInReverse) {
  const GlobalRegistration registration =
      GlobalRegistration::Create(GlobalRegistrationConfig()).value();
  const GlobalRegistrationResult r = registration.Register(target_, source_);
  ASSERT_TRUE(r.accepted) << r.reason;
  const Pose3 error = se3::Between(truth_.inverse(), r.T_target_source);
  EXPECT_LT(se3::TranslationNorm(error), 0.05);
  EXPECT_LT(se3::RotationAngleRad(error), 0.3 * kDeg);
}

TEST_F(SyntheticPairTest, RegisterFromAPriorRefinesItWithoutFeatures) {
  const GlobalRegistration registration =
      GlobalRegistration::Create(GlobalRegistrationConfig()).value();
  // Prepared without FPFH features: enough for the fine stage, refused without a prior.
  const auto source = registration.Prepare(source_, false, false).value();
  const auto target = registration.Prepare(target_, true, false).value();
  EXPECT_FALSE(registration.Register(*source, *target).accepted);
  // A prior 0.8 m and 1.5 deg off (a neighbouring loop's placement after some drift).
  const Pose3 prior = truth_ * se3::FromXyzRpy(0.6, -0.5, 0.1, 0.0, 0.0, 1.5 * kDeg);
  const GlobalRegistrationResult r = registration.RegisterFrom(*source, *target, prior);
  ASSERT_TRUE(r.accepted) << r.reason;
  const Pose3 error = se3::Between(truth_, r.T_target_source);
  EXPECT_LT(se3::TranslationNorm(error), 0.05);
  EXPECT_LT(se3::RotationAngleRad(error), 0.3 * kDeg);
  EXPECT_GT(r.structure_overlap_ratio, registration.config().min_structure_overlap_ratio);
  EXPECT_EQ(r.coarse_inliers, 0);
  // The unrelated place from the same prior is refused by the same checks.
  const auto unrelated = registration.Prepare(unrelated_, false, false).value();
  const GlobalRegistrationResult wrong = registration.RegisterFrom(*unrelated, *target, prior);
  EXPECT_FALSE(wrong.accepted);
  EXPECT_FALSE(wrong.reason.empty());
}

TEST_F(SyntheticPairTest, RejectsSubmapsOfDifferentPlaces) {
  const GlobalRegistrationResult r = RegisterAndPrint("unrelated pair", unrelated_, target_);
  EXPECT_FALSE(r.accepted);
  EXPECT_FALSE(r.reason.empty());
}

// A place that does not exist: the target mirrored (y -> -y). Its ground and some of its
// structure still line up with the source under some rigid pose, but too little structure.
TEST_F(SyntheticPairTest, RejectsTheMirrorImageOfTheTarget) {
  PointVector mirrored = target_;
  for (Eigen::Vector3d& p : mirrored) p.y() = -p.y();
  EXPECT_FALSE(RegisterAndPrint("mirrored pair", source_, mirrored).accepted);
}

TEST_F(SyntheticPairTest, YawSearchMethodRunsAndNeverAcceptsAWrongPose) {
  GlobalRegistrationConfig config;
  config.method = GlobalRegistrationConfig::Method::kYawSearchIcp;
  const GlobalRegistration registration = GlobalRegistration::Create(config).value();
  const GlobalRegistrationResult r = registration.Register(source_, target_);
  if (r.accepted) {
    const Pose3 error = se3::Between(truth_, r.T_target_source);
    EXPECT_LT(se3::TranslationNorm(error), 0.1);
    EXPECT_LT(se3::RotationAngleRad(error), 0.5 * kDeg);
  } else {
    EXPECT_FALSE(r.reason.empty());
  }
  EXPECT_FALSE(registration.Register(unrelated_, target_).accepted);
}

TEST(GlobalRegistrationConfigTest, ValidatesFields) {
  EXPECT_TRUE(GlobalRegistrationConfig().Validate().ok());
  GlobalRegistrationConfig c;
  c.coarse_voxel_m = 0.0;
  EXPECT_FALSE(GlobalRegistration::Create(c).ok());
  c = GlobalRegistrationConfig();
  c.ransac_edge_similarity = 1.5;
  EXPECT_FALSE(c.Validate().ok());
  c = GlobalRegistrationConfig();
  c.min_ransac_inliers = 2;
  EXPECT_FALSE(c.Validate().ok());
  c = GlobalRegistrationConfig();
  c.feature_match_epsilon = -0.5;
  EXPECT_FALSE(c.Validate().ok());
  c = GlobalRegistrationConfig();
  c.fine.min_overlap_ratio = 2.0;
  EXPECT_FALSE(c.Validate().ok());
  // The fine stage's bounds are loose (coarse poses are off by up to about a metre).
  EXPECT_GE(GlobalRegistrationConfig().fine.max_correction_m, 2.0);
}

TEST(GlobalRegistrationTest, EmptyInputIsARejectionNotACrash) {
  const GlobalRegistration registration =
      GlobalRegistration::Create(GlobalRegistrationConfig()).value();
  const GlobalRegistrationResult r = registration.Register({}, {Eigen::Vector3d::Zero()});
  EXPECT_FALSE(r.accepted);
  EXPECT_EQ(r.reason, "empty submap");
}

// --- Real data: two outdoor scans from koide3/fast_gicp (see ../shared/data/real/README.md),
// the source moved by a large known transform.
bool Exists(const std::string& path) {
  struct stat st;
  return stat(path.c_str(), &st) == 0;
}

PointVector LoadXyz(const std::string& path) {
  pcl::PointCloud<pcl::PointXYZ> cloud;
  if (pcl::io::loadPCDFile(path, cloud) != 0) return {};
  PointVector out;
  for (const pcl::PointXYZ& p : cloud) {
    if (std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z)) out.emplace_back(p.x, p.y, p.z);
  }
  return out;
}

TEST(GlobalRegistrationRealTest, RecoversRealPairMovedBy150DegreesAnd20Metres) {
  const std::string dir = std::string(MSM_SHARED_DATA_DIR) + "/real/fast_gicp_pair";
  if (!Exists(dir + "/relative.txt")) GTEST_SKIP() << "no real data at " << dir;
  const PointVector target = VoxelDownsample(LoadXyz(dir + "/251370668.pcd"), 0.2);
  const PointVector source_raw = VoxelDownsample(LoadXyz(dir + "/251371071.pcd"), 0.2);
  std::ifstream in(dir + "/relative.txt");
  Eigen::Matrix4d m;
  for (int i = 0; i < 16; ++i) in >> m(i / 4, i % 4);
  const Pose3 relative(m);  // maps 251371071 into 251370668 (icp_registration_test)
  // Express the source in a frame turned by 150 deg and shifted by 20 m.
  const Pose3 moved = se3::FromXyzRpy(14.0, -15.0, 0.3, 0.0, 0.0, 150.0 * kDeg);
  PointVector source;
  for (const Eigen::Vector3d& p : source_raw) source.push_back(moved * p);
  const GlobalRegistration registration =
      GlobalRegistration::Create(GlobalRegistrationConfig()).value();
  const GlobalRegistrationResult r = registration.Register(source, target);
  ASSERT_TRUE(r.accepted) << r.reason;
  // Error in the scan's own frame: in the moved frame, relative.txt's own 0.3-0.4 deg offset
  // from every local optimum (icp_registration_test) would add a 20 m lever arm.
  const Pose3 error = se3::Between(relative, r.T_target_source * moved);
  std::cout << "real pair moved by 150 deg / 20 m: " << se3::TranslationNorm(error) * 100.0
            << " cm, " << se3::RotationAngleRad(error) / kDeg << " deg, overlap "
            << r.overlap_ratio << ", " << r.time_s << " s" << std::endl;
  EXPECT_LT(se3::TranslationNorm(error), 0.05);
  EXPECT_LT(se3::RotationAngleRad(error), 0.6 * kDeg);
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
