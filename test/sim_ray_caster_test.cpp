#include "multisession_mapper/sim/ray_caster.h"

#include <cmath>
#include <cstdio>

#include <time.h>

#include <gtest/gtest.h>

#include "multisession_mapper/core/se3.h"
#include "multisession_mapper/sim/campus_generator.h"
#include "multisession_mapper/sim/counter_rng.h"

namespace multisession_mapper {
namespace sim {
namespace {

Terrain FlatTerrain(double z) {
  TerrainGrid g;
  g.origin_m = Eigen::Vector2d(-100, -100);
  g.resolution_m = 2.0;
  g.cols = 101;
  g.rows = 101;
  g.heights_m.assign(101 * 101, static_cast<float>(z));
  g.materials.assign(100 * 100, 1);
  return Terrain::Create(g).value();
}

std::vector<Primitive> RandomScene(CounterRng* rng, int n) {
  std::vector<Primitive> prims;
  for (int k = 0; k < n; ++k) {
    Primitive p;
    p.shape = static_cast<Shape>(rng->UniformInt(0, 2));
    const Eigen::Vector3d half(rng->Uniform(0.1, 4), rng->Uniform(0.1, 4), rng->Uniform(0.1, 6));
    p.half_size_m = p.shape == Shape::kCylinder ? Eigen::Vector3d(half.x(), half.x(), half.z())
                                                : half;
    p.pose = core::se3::FromXyzRpy(rng->Uniform(-90, 90), rng->Uniform(-90, 90),
                                   rng->Uniform(-1, 8), rng->Uniform(-0.3, 0.3),
                                   rng->Uniform(-0.3, 0.3), rng->Uniform(-3, 3));
    p.object_id = static_cast<std::uint32_t>(k + 1);
    p.object_class = ObjectClass::kBuilding;
    p.density_per_m = rng->Bernoulli(0.2) ? 0.8 : 0.0;
    p.sessions_mask = rng->Bernoulli(0.3) ? 1ULL : 3ULL;
    prims.push_back(p);
  }
  return prims;
}

TEST(SimRayCasterTest, HitsBoxAndGround) {
  Primitive box;
  box.pose = core::se3::FromXyzRpy(20, 0, 1, 0, 0, 0);
  box.half_size_m = Eigen::Vector3d(1, 1, 1);
  box.object_id = 5;
  box.object_class = ObjectClass::kParkedCar;
  box.sessions_mask = 1ULL;  // session 0 only
  auto caster = RayCaster::Create(FlatTerrain(0.0), {box});
  ASSERT_TRUE(caster.ok()) << caster.status().message();
  Ray ray;
  ray.origin = Eigen::Vector3d(0, 0, 1);
  ray.direction = Eigen::Vector3d(1, 0, 0);
  RayHit hit;
  ASSERT_TRUE(caster.value().Cast(ray, 0.0, 100.0, 0, 1, &hit));
  EXPECT_NEAR(hit.range_m, 19.0, 1e-9);
  EXPECT_EQ(hit.object_id, 5u);
  EXPECT_EQ(hit.object_class, ObjectClass::kParkedCar);
  EXPECT_NEAR(hit.normal.x(), -1.0, 1e-9);
  // Session 1: the car is gone, the horizontal ray escapes.
  EXPECT_FALSE(caster.value().Cast(ray, 0.0, 100.0, 1, 1, &hit));
  EXPECT_LT(hit.range_m, 0.0);
  // Down at 45 degrees from 1 m: ground at sqrt(2) m.
  ray.direction = Eigen::Vector3d(1, 1, -1.4142135623730951).normalized();
  ASSERT_TRUE(caster.value().Cast(ray, 0.0, 100.0, 1, 1, &hit));
  EXPECT_NEAR(hit.range_m, std::sqrt(2.0), 1e-9);
  EXPECT_EQ(hit.object_class, ObjectClass::kTerrain);
  EXPECT_EQ(hit.object_id, 0u);
  // Max range respected.
  EXPECT_FALSE(caster.value().Cast(ray, 0.0, 1.3, 1, 1, &hit));
  EXPECT_NEAR(caster.value().DistanceToSurface(Eigen::Vector3d(19.0, 0, 1), 0), 0.0, 1e-9);
  EXPECT_NEAR(caster.value().DistanceToSurface(Eigen::Vector3d(18.8, 0, 1), 1), 1.0, 1e-9);
}

TEST(SimRayCasterTest, AgreesWithBruteForce) {
  CounterRng rng(11);
  const std::vector<Primitive> prims = RandomScene(&rng, 300);
  auto caster = RayCaster::Create(FlatTerrain(-0.5), prims);
  ASSERT_TRUE(caster.ok());
  int hits = 0;
  for (int k = 0; k < 5000; ++k) {
    Ray ray;
    ray.origin = Eigen::Vector3d(rng.Uniform(-60, 60), rng.Uniform(-60, 60), rng.Uniform(0.5, 3));
    const double az = rng.Uniform(-M_PI, M_PI), el = rng.Uniform(-0.3, 0.3);
    ray.direction = Eigen::Vector3d(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az),
                                    std::sin(el));
    const int session = k % 2;
    const std::uint64_t key = MakeKey(1, k);
    // Brute force: every primitive present in the session, then the flat ground.
    double best = -1.0;
    for (const Primitive& p : prims) {
      if (!(p.sessions_mask & (1ULL << session))) continue;
      const double t = HitDistance(p, ray, 0.5, 80.0, key);
      if (t >= 0.0 && (best < 0.0 || t < best)) best = t;
    }
    if (ray.direction.z() < 0.0) {
      const double tg = (-0.5 - ray.origin.z()) / ray.direction.z();
      const Eigen::Vector3d g = ray.origin + ray.direction * tg;
      const bool inside = std::abs(g.x()) < 100 && std::abs(g.y()) < 100;
      if (inside && tg <= 80.0 && (best < 0.0 || tg < best)) best = tg;
    }
    RayHit hit;
    const bool found = caster.value().Cast(ray, 0.5, 80.0, session, key, &hit);
    ASSERT_EQ(found, best >= 0.0) << "ray " << k;
    if (found) {
      EXPECT_NEAR(hit.range_m, best, 1e-6) << "ray " << k;
      ++hits;
    }
  }
  EXPECT_GT(hits, 2000);
}

}  // namespace
}  // namespace sim
}  // namespace multisession_mapper

namespace multisession_mapper {
namespace sim {
namespace {

// Not a timed assertion (the machine is shared): reports the cost of one VLP-16 sweep worth of
// rays in the generated campus, and fails only on a gross regression.
TEST(SimRayCasterTest, SweepCostOnTheCampus) {
  CampusConfig config;
  config.profile = "small";
  auto campus = GenerateCampus(config);
  ASSERT_TRUE(campus.ok());
  auto caster = RayCaster::Create(Terrain::Create(campus.value().world.terrain).value(),
                                  campus.value().world.StaticPrimitives());
  ASSERT_TRUE(caster.ok());
  const RobotTrajectory& traj = campus.value().trajectories[0];
  const int sweeps = 10;
  long long returns = 0;
  auto cpu_ms = []() {
    timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
  };
  const double t0 = cpu_ms();
  for (int k = 0; k < sweeps; ++k) {
    const core::Pose3 pose = traj.SensorPose(traj.start_stamp_s() + 6.0 * k);
    for (int c = 0; c < 1800; ++c) {
      const double az = 2.0 * M_PI * c / 1800;
      for (int l = 0; l < 16; ++l) {
        const double el = (-15.0 + 2.0 * l) * M_PI / 180.0;
        Ray ray;
        ray.origin = pose.translation();
        ray.direction = pose.linear() * Eigen::Vector3d(std::cos(el) * std::cos(az),
                                                        std::cos(el) * std::sin(az), std::sin(el));
        RayHit hit;
        returns += caster.value().Cast(ray, 0.5, 100.0, 0, MakeKey(k, c, l), &hit);
      }
    }
  }
  const double ms = (cpu_ms() - t0) / sweeps;
  std::printf("[ INFO     ] 28,800 rays: %.2f ms CPU per sweep, %.0f returns per sweep\n", ms,
              static_cast<double>(returns) / sweeps);
  RecordProperty("ms_per_sweep", std::to_string(ms));
  EXPECT_GT(returns / sweeps, 10000);
  EXPECT_LT(ms, 200.0);
}

}  // namespace
}  // namespace sim
}  // namespace multisession_mapper
