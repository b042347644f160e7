#include "multisession_mapper/sim/campus_generator.h"

#include <cmath>
#include <sstream>
#include <vector>

#include <gtest/gtest.h>

#include "multisession_mapper/sim/world_io.h"

namespace multisession_mapper {
namespace sim {
namespace {

Campus Generate(const std::string& profile, std::uint64_t seed, int sessions = 3) {
  CampusConfig config;
  config.profile = profile;
  config.seed = seed;
  config.num_sessions = sessions;
  auto campus = GenerateCampus(config);
  EXPECT_TRUE(campus.ok()) << campus.status().message();
  return std::move(campus).value();
}

std::string Text(const World& w) {
  std::ostringstream out;
  EXPECT_TRUE(WriteWorldYaml(out, w).ok());
  return out.str();
}

// Positions of the robot every `dt` seconds.
std::vector<Eigen::Vector3d> Samples(const RobotTrajectory& t, double dt) {
  std::vector<Eigen::Vector3d> out;
  for (double s = t.start_stamp_s(); s <= t.end_stamp_s(); s += dt) {
    out.push_back(t.BasePose(s).translation());
  }
  return out;
}

TEST(SimCampusGeneratorTest, DeterministicFromTheSeed) {
  const Campus a = Generate("small", 5);
  const Campus b = Generate("small", 5);
  const Campus c = Generate("small", 6);
  EXPECT_EQ(Text(a.world), Text(b.world));
  EXPECT_NE(Text(a.world), Text(c.world));
}

TEST(SimCampusGeneratorTest, WorldHasEveryKindOfObject) {
  const Campus campus = Generate("small", 1);
  const World& w = campus.world;
  std::vector<int> per_class(kNumObjectClasses, 0);
  int always_parked = 0, changing_parked = 0, changing_movables = 0, curbs = 0;
  for (const WorldObject& o : w.objects) {
    ++per_class[static_cast<int>(o.object_class)];
    if (o.object_class == ObjectClass::kParkedCar) {
      (o.sessions_mask == w.AllSessionsMask() ? always_parked : changing_parked)++;
    }
    if (o.object_class == ObjectClass::kMovable) {
      EXPECT_NE(o.sessions_mask, w.AllSessionsMask()) << "movables must change";
      EXPECT_NE(o.sessions_mask, 0u);
      ++changing_movables;
    }
    curbs += o.kind == "curb";
  }
  for (int c = 1; c < kNumObjectClasses; ++c) {
    EXPECT_GT(per_class[c], 0) << ObjectClassName(static_cast<ObjectClass>(c));
  }
  EXPECT_GT(always_parked, 10);
  EXPECT_GT(changing_parked, 10);
  EXPECT_GT(changing_movables, 3);
  EXPECT_GT(curbs, 100);
  // About 500 m x 500 m, a few metres of relief, slopes of a few degrees.
  const TerrainGrid& g = w.terrain;
  EXPECT_NEAR((g.cols - 1) * g.resolution_m, 500.0, 1.0);
  float lo = 1e9f, hi = -1e9f;
  for (float h : g.heights_m) {
    lo = std::min(lo, h);
    hi = std::max(hi, h);
  }
  EXPECT_GT(hi - lo, 2.0f);
  EXPECT_LT(hi - lo, 20.0f);
}

TEST(SimCampusGeneratorTest, SmallSessionsShareMostOfTheRouteButNotAll) {
  const Campus campus = Generate("small", 1);
  ASSERT_EQ(campus.trajectories.size(), 3u);
  std::vector<std::vector<Eigen::Vector3d>> pts;
  for (const RobotTrajectory& t : campus.trajectories) {
    EXPECT_GT(t.length_m(), 100.0);
    EXPECT_LT(t.length_m(), 260.0);
    pts.push_back(Samples(t, 0.5));
  }
  auto nearest = [](const Eigen::Vector3d& p, const std::vector<Eigen::Vector3d>& others) {
    double best = 1e9;
    for (const auto& q : others) best = std::min(best, (p - q).head<2>().norm());
    return best;
  };
  // Different start points.
  EXPECT_GT((pts[0].front() - pts[1].front()).norm(), 10.0);
  EXPECT_GT((pts[0].front() - pts[2].front()).norm(), 10.0);
  // Most of session 1 lies on session 0's roads (lanes differ by direction: < 5 m), and some
  // of it is somewhere session 0 and 2 never go.
  int shared = 0, unique = 0;
  for (const auto& p : pts[1]) {
    const double d = std::min(nearest(p, pts[0]), nearest(p, pts[2]));
    shared += d < 5.0;
    unique += d > 20.0;
  }
  EXPECT_GT(shared, static_cast<int>(pts[1].size()) / 2);
  EXPECT_GT(unique, 5);
  // Session 0 revisits its own path: two moments more than 40 s apart, less than 3 m apart.
  bool revisit = false;
  const double dt = 0.5;
  for (std::size_t i = 0; i < pts[0].size() && !revisit; ++i) {
    for (std::size_t j = i + static_cast<std::size_t>(40.0 / dt); j < pts[0].size(); ++j) {
      if ((pts[0][i] - pts[0][j]).head<2>().norm() < 3.0) {
        revisit = true;
        break;
      }
    }
  }
  EXPECT_TRUE(revisit);
  // Session 1 drives some road in the opposite direction of session 0.
  int opposite = 0;
  const RobotTrajectory& t0 = campus.trajectories[0];
  const RobotTrajectory& t1 = campus.trajectories[1];
  for (double a = t1.start_stamp_s(); a < t1.end_stamp_s(); a += 1.0) {
    const core::Pose3 p1 = t1.BasePose(a);
    for (double b = t0.start_stamp_s(); b < t0.end_stamp_s(); b += 0.5) {
      const core::Pose3 p0 = t0.BasePose(b);
      if ((p0.translation() - p1.translation()).head<2>().norm() > 5.0) continue;
      const Eigen::Vector3d f0 = p0.linear().col(0), f1 = p1.linear().col(0);
      if (f0.dot(f1) < -0.9) {
        ++opposite;
        break;
      }
    }
  }
  EXPECT_GT(opposite, 10);
  // Sessions start on different days.
  EXPECT_NEAR(campus.trajectories[1].start_stamp_s() - campus.trajectories[0].start_stamp_s(),
              86400.0, 1e-6);
}

TEST(SimCampusGeneratorTest, CampusRoutesHaveThePaperScale) {
  const Campus campus = Generate("campus", 1, 3);
  for (const RobotTrajectory& t : campus.trajectories) {
    EXPECT_GT(t.length_m(), 900.0);
    EXPECT_LT(t.length_m(), 1300.0);
  }
}

TEST(SimCampusGeneratorTest, MovingObjectsPassCloseToTheRobot) {
  const Campus campus = Generate("small", 2);
  const World& w = campus.world;
  for (int s = 0; s < 3; ++s) {
    const RobotTrajectory& robot = campus.trajectories[s];
    int cars = 0, pedestrians = 0, close = 0;
    for (const WorldObject& o : w.objects) {
      if (!o.moving() || !(o.sessions_mask & (1ULL << s))) continue;
      EXPECT_EQ(o.sessions_mask, 1ULL << s) << "a moving object lives in one session";
      cars += o.object_class == ObjectClass::kMovingCar;
      pedestrians += o.object_class == ObjectClass::kPedestrian;
      EXPECT_GE(o.trajectory.front().stamp_s, robot.start_stamp_s() - 1e-6);
      EXPECT_LE(o.trajectory.back().stamp_s, robot.end_stamp_s() + 1e-6);
      double best = 1e9;
      for (const TrajectoryRow& row : o.trajectory) {
        best = std::min(best, (row.position_m - robot.BasePose(row.stamp_s).translation())
                                  .head<2>()
                                  .norm());
      }
      close += best < 6.0;
    }
    EXPECT_GT(cars, 0) << "session " << s;
    EXPECT_GT(pedestrians, 0) << "session " << s;
    EXPECT_GT(close, 2) << "session " << s;
  }
}

TEST(SimCampusGeneratorTest, EverySeedGivesAValidWorld) {
  // Road jitter changes block sizes: every seed must still give valid objects and routes.
  for (std::uint64_t seed = 1; seed <= 12; ++seed) {
    CampusConfig config;
    config.seed = seed;
    config.num_sessions = 5;
    auto campus = GenerateCampus(config);
    ASSERT_TRUE(campus.ok()) << "seed " << seed << ": " << campus.status().message();
    EXPECT_EQ(campus.value().trajectories.size(), 5u);
  }
}

TEST(SimCampusGeneratorTest, RejectsBadConfigurations) {
  CampusConfig config;
  config.profile = "huge";
  EXPECT_FALSE(GenerateCampus(config).ok());
  config = CampusConfig();
  config.num_sessions = 0;
  EXPECT_FALSE(GenerateCampus(config).ok());
  config = CampusConfig();
  config.parked_car_density = 1.5;
  EXPECT_FALSE(GenerateCampus(config).ok());
  EXPECT_EQ(SessionName(3), "s03");
}

}  // namespace
}  // namespace sim
}  // namespace multisession_mapper
