#include "multisession_mapper/sim/vlp16.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include <gtest/gtest.h>

#include "multisession_mapper/sim/campus_simulator.h"

namespace multisession_mapper {
namespace sim {
namespace {

double Median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

bool IsMoving(ObjectClass c) {
  return c == ObjectClass::kMovingCar || c == ObjectClass::kPedestrian;
}

class SimVlp16Test : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    CampusSimulatorConfig config;
    config.campus.profile = "small";
    config.campus.seed = 7;
    config.campus.num_sessions = 2;
    auto sim = CampusSimulator::Create(config);
    ASSERT_TRUE(sim.ok()) << sim.status().message();
    sim_ = new CampusSimulator(std::move(sim).value());
  }
  static void TearDownTestSuite() {
    delete sim_;
    sim_ = nullptr;
  }
  static CampusSimulator* sim_;
};
CampusSimulator* SimVlp16Test::sim_ = nullptr;

TEST(SimVlp16StaticTest, LaserTable) {
  // Firing order -15, +1, -13, +3, ... ; ring 0 is the lowest beam.
  EXPECT_NEAR(Vlp16::LaserElevationRad(0) * 180 / M_PI, -15.0, 1e-12);
  EXPECT_NEAR(Vlp16::LaserElevationRad(1) * 180 / M_PI, 1.0, 1e-12);
  EXPECT_NEAR(Vlp16::LaserElevationRad(14) * 180 / M_PI, -1.0, 1e-12);
  EXPECT_NEAR(Vlp16::LaserElevationRad(15) * 180 / M_PI, 15.0, 1e-12);
  std::vector<int> rings;
  for (int l = 0; l < 16; ++l) rings.push_back(Vlp16::LaserRing(l));
  std::sort(rings.begin(), rings.end());
  for (int r = 0; r < 16; ++r) EXPECT_EQ(rings[r], r);
  Vlp16Config bad;
  bad.range_noise_sigma_m = -0.1;
  EXPECT_FALSE(Vlp16::Create(bad).ok());
}

TEST_F(SimVlp16Test, ScanHasVelodyneRingStructure) {
  const SimulatedScan s = sim_->SimulateScan(0, 120);
  const core::LidarScan& scan = s.scan;
  ASSERT_TRUE(scan.has_ring && scan.has_time);
  EXPECT_GT(scan.points.size(), 8000u);
  EXPECT_LE(scan.points.size(), 28800u);
  ASSERT_EQ(s.truth.size(), scan.points.size());
  std::vector<int> per_ring(16, 0);
  float last_time = -1.0f;
  for (const core::LidarPoint& p : scan.points) {
    ASSERT_LT(p.ring, 16);
    ++per_ring[p.ring];
    const double el = std::atan2(p.position_m.z(), p.position_m.head<2>().norm()) * 180 / M_PI;
    EXPECT_NEAR(el, -15.0 + 2.0 * p.ring, 0.01);
    EXPECT_GE(p.time_s, 0.0f);
    EXPECT_LT(p.time_s, 0.1f);
    EXPECT_GE(p.time_s, last_time);  // firing order
    last_time = p.time_s;
    const double range = p.position_m.norm();
    EXPECT_GE(range, 0.4);
    EXPECT_LE(range, 100.1);
    EXPECT_GE(p.intensity, 0.0f);
    EXPECT_LE(p.intensity, 255.0f);
  }
  for (int r = 0; r < 16; ++r) EXPECT_GT(per_ring[r], 0) << "ring " << r;
  // The low rings see the ground all around: close to 1800 returns.
  EXPECT_GT(per_ring[0], 1700);
}

TEST_F(SimVlp16Test, DeskewedScanLiesOnTheWorldSurfaces) {
  const int index = 150;
  const SimulatedScan s = sim_->SimulateScan(0, index);
  const RobotTrajectory& traj = sim_->trajectory(0);
  ASSERT_GT(traj.Speed(s.scan.stamp_s), 1.0) << "the robot must move during the sweep";
  std::vector<double> deskewed, truth_error, raw_error, solid_deskewed;
  for (std::size_t i = 0; i < s.scan.points.size(); ++i) {
    const ObjectClass label = s.truth[i].label;
    if (IsMoving(label)) continue;
    const core::LidarPoint& p = s.scan.points[i];
    const Eigen::Vector3d local = p.position_m.cast<double>();
    const Eigen::Vector3d world = traj.SensorPose(s.scan.stamp_s + p.time_s) * local;
    const Eigen::Vector3d world_raw = s.pose_at_stamp * local;
    deskewed.push_back(sim_->ray_caster().DistanceToSurface(world, 0));
    truth_error.push_back((world - s.truth[i].position_m.cast<double>()).norm());
    raw_error.push_back((world_raw - s.truth[i].position_m.cast<double>()).norm());
    if (label == ObjectClass::kBuilding || label == ObjectClass::kTrunk ||
        label == ObjectClass::kPole || label == ObjectClass::kParkedCar) {
      solid_deskewed.push_back(deskewed.back());
    }
  }
  ASSERT_GT(solid_deskewed.size(), 300u);
  ASSERT_GT(deskewed.size(), 5000u);
  const double median_deskewed = Median(deskewed);
  const double median_solid = Median(solid_deskewed);
  const double median_raw = Median(raw_error);
  EXPECT_LT(median_deskewed, 0.03);
  EXPECT_LT(median_solid, 0.03);
  EXPECT_LT(Median(truth_error), 0.03);  // sigma 2.5 cm range noise
  // Without de-skewing the sweep is distorted by the motion during the sweep (v * ~0.05 s).
  EXPECT_GT(median_raw, 0.06);
  RecordProperty("median_deskewed_m", std::to_string(median_deskewed));
  RecordProperty("median_raw_error_m", std::to_string(median_raw));
  RecordProperty("median_solid_m", std::to_string(median_solid));
}

TEST_F(SimVlp16Test, NoiseFreeSweepIsExact) {
  Vlp16Config config;
  config.range_noise_sigma_m = 0.0;
  auto sensor = Vlp16::Create(config);
  ASSERT_TRUE(sensor.ok());
  const RobotTrajectory& traj = sim_->trajectory(1);
  const double stamp = sim_->ScanStamps(1).at(80);
  const SimulatedScan s = sensor.value().Simulate(
      sim_->ray_caster(), sim_->Movers(1), [&](double t) { return traj.SensorPose(t); }, 1,
      stamp, 99);
  ASSERT_GT(s.scan.points.size(), 5000u);
  double worst = 0.0;
  for (std::size_t i = 0; i < s.scan.points.size(); ++i) {
    const core::LidarPoint& p = s.scan.points[i];
    const Eigen::Vector3d world =
        traj.SensorPose(stamp + p.time_s) * p.position_m.cast<double>();
    worst = std::max(worst, (world - s.truth[i].position_m.cast<double>()).norm());
  }
  // Float storage and the 2 us firing offsets only.
  EXPECT_LT(worst, 2e-3);
}

TEST_F(SimVlp16Test, CanopiesDifferBetweenSessionsSolidsDoNot) {
  // The same pose in two sessions: leaves are hit at different places, walls are not.
  const RobotTrajectory& traj = sim_->trajectory(0);
  const std::vector<double> stamps = sim_->ScanStamps(0);
  Vlp16Config config;
  config.range_noise_sigma_m = 0.0;
  const Vlp16 sensor = Vlp16::Create(config).value();
  auto pose = [&](double) { return traj.SensorPose(stamps[100]); };
  const SimulatedScan a = sensor.Simulate(sim_->ray_caster(), {}, pose, 0, stamps[100], 1);
  const SimulatedScan b = sensor.Simulate(sim_->ray_caster(), {}, pose, 1, stamps[100], 2);
  int canopy = 0, canopy_same = 0, solid = 0, solid_same = 0;
  // Compare ray by ray (same ring, same time = same column).
  std::size_t j = 0;
  for (std::size_t i = 0; i < a.scan.points.size(); ++i) {
    const auto& pa = a.scan.points[i];
    while (j < b.scan.points.size() && b.scan.points[j].time_s < pa.time_s) ++j;
    if (j >= b.scan.points.size() || b.scan.points[j].time_s != pa.time_s) continue;
    const bool same = (a.truth[i].position_m - b.truth[j].position_m).norm() < 1e-4;
    if (a.truth[i].label == ObjectClass::kCanopy) {
      ++canopy;
      canopy_same += same;
    } else if (a.truth[i].label == ObjectClass::kBuilding ||
               a.truth[i].label == ObjectClass::kTerrain) {
      ++solid;
      solid_same += same;
    }
  }
  ASSERT_GT(solid, 1000);
  EXPECT_GT(static_cast<double>(solid_same) / solid, 0.9);
  if (canopy < 50) GTEST_SKIP() << "too few canopy returns at this pose (" << canopy << ")";
  EXPECT_LT(static_cast<double>(canopy_same) / canopy, 0.3);
}

}  // namespace
}  // namespace sim
}  // namespace multisession_mapper
