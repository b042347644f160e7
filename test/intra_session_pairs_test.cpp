#include "multisession_mapper/core/intra_session_pairs.h"

#include <cmath>
#include <cstdio>
#include <iostream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "multisession_mapper/core/se3.h"
#include "multisession_mapper/core/submap_builder.h"
#include "synthetic_lidar_scene.h"

namespace multisession_mapper {
namespace core {
namespace {

using test::SceneBox;
using test::SyntheticScene;

// A street along y: a wall at x = 12, a car parked for the whole session at y = -12 and a car
// at y = 14 that is there only while the robot is still 30-45 m away (it then drives off).
// The robot drives along x = 0 from y = -30 to y = 30, 0.5 m per scan.
SceneBox Box(double x, double y, double half_x, double half_y, double height) {
  SceneBox b;
  b.center = Eigen::Vector3d(x, y, height / 2.0);
  b.half_size = Eigen::Vector3d(half_x, half_y, height / 2.0);
  return b;
}
const SceneBox kWall = Box(12.15, 0.0, 0.15, 40.0, 4.0);
const SceneBox kParkedCar = Box(8.1, -12.0, 0.9, 2.25, 1.5);
const SceneBox kLeavingCar = Box(8.1, 14.0, 0.9, 2.25, 1.5);
// A second car, there while the robot is 40-55 m away: a VLP-16 1.8 m up measures flat ground
// up to ~34 m (its -3 deg ring) and then not before ~100 m (-1 deg), so no ground around it.
const SceneBox kFarCar = Box(-8.1, 26.0, 0.9, 2.25, 1.5);

// Within `margin` of the box, above the lowest ring's hits on the ground (0.23-0.25 m: what
// is left of a removed car there is the ground's business, see the bottom extension).
bool InBox(const SceneBox& b, const Eigen::Vector3d& p, double margin) {
  return p.z() > 0.3 && ((p - b.center).cwiseAbs() - b.half_size).maxCoeff() < margin;
}

struct Counts {
  int leaving = 0, far = 0, parked = 0, wall = 0, ground = 0;
};

Counts Count(const std::vector<Submap, Eigen::aligned_allocator<Submap>>& submaps) {
  Counts c;
  for (const Submap& submap : submaps) {
    for (const Eigen::Vector3d& q : submap.points) {
      const Eigen::Vector3d p = submap.T_map_submap * q;
      if (InBox(kLeavingCar, p, 0.3)) {
        ++c.leaving;
      } else if (InBox(kFarCar, p, 0.3)) {
        ++c.far;
      } else if (InBox(kParkedCar, p, 0.3)) {
        ++c.parked;
      } else if (InBox(kWall, p, 0.3)) {
        ++c.wall;
      } else if (std::abs(p.z()) < 0.2) {
        ++c.ground;
      }
    }
  }
  return c;
}

// The session's submaps (20 m each), without the in-session visibility check, so that the
// leaving car, seen only 30-45 m away, is in the first submap as it would be with it.
// With `far_car`, the far car is in the street too (a scene of its own: the other tests'
// scenes stay the same, sample for sample).
std::vector<Submap, Eigen::aligned_allocator<Submap>> BuildSession(bool far_car = false) {
  SubmapBuilderConfig config;
  config.dynamic_filter.enabled = false;
  config.break_on_jump_m = 0.0;
  StatusOr<SubmapBuilder> builder = SubmapBuilder::Create(config, "s00");
  EXPECT_TRUE(builder.ok()) << builder.status().message();
  SyntheticScene with_car(1, 0, 1.0, {}, 0.0), without_car(1, 0, 1.0, {}, 0.0);
  if (far_car) {
    with_car.SetBoxes({kWall, kParkedCar, kLeavingCar, kFarCar});
  } else {
    with_car.SetBoxes({kWall, kParkedCar, kLeavingCar});
  }
  without_car.SetBoxes({kWall, kParkedCar});
  for (int i = 0; i <= 120; ++i) {
    const double y = -30.0 + 0.5 * i;
    const Pose3 pose = se3::FromXyzRpy(0.0, y, 1.8, 0.0, 0.0, M_PI / 2.0);
    const SyntheticScene& scene = y < -16.0 ? with_car : without_car;
    const LidarScan scan = test::SimulateVlp16(
        scene, [&](double) { return pose; }, 10.0 + 0.1 * i, 100 + i, 0.01, 900, 0.1, false, 60.0);
    builder.value().AddScan(scan, pose);
  }
  builder.value().FinishSession();
  return builder.value().TakeFinished();
}

TEST(IntraSessionPairs, CarSeenOnlyFarAwayIsRemovedAndTheStaticStreetKept) {
  auto submaps = BuildSession(true);
  ASSERT_GE(submaps.size(), 3u);
  for (const Submap& s : submaps) ASSERT_EQ(s.views.size(), s.points.size());
  const Counts before = Count(submaps);
  ASSERT_GT(before.leaving, 30);  // the first submap holds the leaving car
  ASSERT_GT(before.parked, 500);
  IntraSessionPairsConfig config;
  config.neighbours = 2;
  StatusOr<IntraSessionPairsStats> stats = RemoveDynamicsBetweenSubmaps(config, &submaps);
  ASSERT_TRUE(stats.ok()) << stats.status().message();
  EXPECT_EQ(stats.value().pairs, 2 * submaps.size() - 3);  // next and next but one
  EXPECT_EQ(stats.value().skipped_pairs, 0u);
  EXPECT_EQ(stats.value().pair_s.size(), stats.value().pairs);
  const Counts after = Count(submaps);
  EXPECT_LE(after.leaving, before.leaving / 20) << "of " << before.leaving;
  EXPECT_LE(after.far, before.far / 5) << "of " << before.far;
  EXPECT_EQ(after.parked, before.parked);
  EXPECT_GE(after.wall, before.wall * 0.995) << "of " << before.wall;
  EXPECT_GE(after.ground, before.ground * 0.995) << "of " << before.ground;
  for (const Submap& s : submaps) EXPECT_EQ(s.views.size(), s.points.size());
}

TEST(IntraSessionPairs, CarWithoutGroundAroundItNeedsTheJointGround) {
  // The far car's submap measured no ground near it: its own lowest points are its ground, so
  // with the merge's 1 m gap the car is ground and stays; against both submaps' ground (the
  // later submaps measured the street there) it goes.
  auto submaps = BuildSession(true);
  const Counts before = Count(submaps);
  ASSERT_GT(before.far, 10);
  IntraSessionPairsConfig config;
  config.neighbours = 2;
  config.own_ground_max_gap_m = 1.0;
  auto own = submaps;
  ASSERT_TRUE(RemoveDynamicsBetweenSubmaps(config, &own).ok());
  EXPECT_GE(Count(own).far, before.far / 2) << "of " << before.far;
  std::printf("far car points: %d before, %d after with the 1 m gap, ", before.far, Count(own).far);
  config.own_ground_max_gap_m = IntraSessionPairsConfig().own_ground_max_gap_m;
  ASSERT_TRUE(RemoveDynamicsBetweenSubmaps(config, &submaps).ok());
  const Counts after = Count(submaps);
  EXPECT_LE(after.far, before.far / 5) << "of " << before.far;
  std::printf("%d with the default\n", after.far);
  EXPECT_EQ(after.parked, before.parked);
  EXPECT_GE(after.ground, before.ground * 0.995) << "of " << before.ground;
}

TEST(IntraSessionPairs, WithTheMergesSettingsTheFarSideOfTheParkedCarGoes) {
  // The second submap sees the parked car's rear face, which the first one never saw: rays of
  // the first submap graze that face and pass below it. With the merge's settings in place of
  // the intra-session ones (rays from the viewing scans, no grazing rays, a detection mostly
  // seen through, ...) the face is detected; with them (the test above) it stays.
  auto submaps = BuildSession();
  const Counts before = Count(submaps);
  IntraSessionPairsConfig config;
  const DynamicDetectionConfig merge;
  config.rays_from_viewing_scans = merge.rays_from_viewing_scans;
  config.min_pass_incidence_rad = merge.min_pass_incidence_rad;
  config.min_cluster_coarse_fraction = merge.min_cluster_coarse_fraction;
  config.own_ground_max_gap_m = merge.own_ground_max_gap_m;
  config.changed_objects_enabled = merge.changed_objects_enabled;
  config.far_range_m = merge.far_range_m;
  StatusOr<IntraSessionPairsStats> stats = RemoveDynamicsBetweenSubmaps(config, &submaps);
  ASSERT_TRUE(stats.ok()) << stats.status().message();
  const Counts after = Count(submaps);
  EXPECT_LT(after.parked, before.parked - 10) << "of " << before.parked;
  EXPECT_LE(after.leaving, before.leaving / 5) << "of " << before.leaving;
}

TEST(IntraSessionPairs, NoPairAcrossAJumpOfTheOdometry) {
  auto submaps = BuildSession();
  ASSERT_GE(submaps.size(), 3u);
  submaps[1].started_at_jump_m = 0.8;  // the odometry jumped between submaps 0 and 1
  const Counts before = Count(submaps);
  IntraSessionPairsConfig config;
  config.neighbours = 2;
  StatusOr<IntraSessionPairsStats> stats = RemoveDynamicsBetweenSubmaps(config, &submaps);
  ASSERT_TRUE(stats.ok()) << stats.status().message();
  // Submap 0 pairs with nothing (1 and 2 lie beyond the jump); the others as usual.
  EXPECT_EQ(stats.value().pairs, 2 * submaps.size() - 5);
  EXPECT_EQ(stats.value().pairs_across_jumps, 2u);
  // The leaving car is only in submap 0, so it stays.
  EXPECT_EQ(Count(submaps).leaving, before.leaving);
}

// The worker detects the pairs while the submaps come (here: caught up with, at normal
// priority), on copies, at the relative poses given to Add; the result is that of detecting
// them all at the end.
TEST(IntraSessionPairs, DetectedDuringTheSessionAsAtTheEnd) {
  const auto session = BuildSession(true);
  ASSERT_GE(session.size(), 3u);
  IntraSessionPairsConfig config;
  config.neighbours = 2;
  auto at_end = session;
  StatusOr<IntraSessionPairsStats> end_stats = RemoveDynamicsBetweenSubmaps(config, &at_end);
  ASSERT_TRUE(end_stats.ok()) << end_stats.status().message();
  ASSERT_GT(end_stats.value().points_removed, 0u);
  EXPECT_EQ(end_stats.value().pairs_during_session, 0u);

  StatusOr<std::unique_ptr<IntraSessionPairDetector>> pairs =
      IntraSessionPairDetector::Create(config);
  ASSERT_TRUE(pairs.ok()) << pairs.status().message();
  for (const Submap& submap : session) pairs.value()->Add(submap, submap.T_map_submap);
  const std::size_t expected = pairs.value()->pairs_known();
  EXPECT_EQ(expected, end_stats.value().pairs);
  pairs.value()->CatchUp();
  EXPECT_EQ(pairs.value()->pairs_detected_during_session(), expected);
  auto during = session;
  StatusOr<IntraSessionPairsStats> stats = pairs.value()->Finish(&during);
  ASSERT_TRUE(stats.ok()) << stats.status().message();
  EXPECT_EQ(stats.value().pairs_during_session, expected) << "the worker did not run";
  EXPECT_EQ(stats.value().points_removed, end_stats.value().points_removed);
  ASSERT_EQ(during.size(), at_end.size());
  for (std::size_t k = 0; k < during.size(); ++k) {
    EXPECT_TRUE(during[k].points == at_end[k].points) << "submap " << k;
  }
  EXPECT_FALSE(pairs.value()->Finish(&during).ok()) << "once only";
}

// More submaps than the worker may hold copies of (kMaxCopies): whichever pairs it gets to,
// the rest are detected at Finish, with the same result.
TEST(IntraSessionPairs, MoreSubmapsThanCopiesGivesTheSameResult) {
  const auto one = BuildSession(true);
  ASSERT_GE(one.size(), 3u);
  std::vector<Submap, Eigen::aligned_allocator<Submap>> session;
  while (session.size() <= IntraSessionPairDetector::kMaxCopies + 2) {
    for (const Submap& submap : one) {
      session.push_back(submap);
      session.back().id = static_cast<std::uint32_t>(session.size() - 1);
    }
  }
  IntraSessionPairsConfig config;
  auto at_end = session;
  StatusOr<IntraSessionPairsStats> end_stats = RemoveDynamicsBetweenSubmaps(config, &at_end);
  ASSERT_TRUE(end_stats.ok()) << end_stats.status().message();
  StatusOr<std::unique_ptr<IntraSessionPairDetector>> pairs =
      IntraSessionPairDetector::Create(config);
  ASSERT_TRUE(pairs.ok());
  for (const Submap& submap : session) pairs.value()->Add(submap, submap.T_map_submap);
  auto during = session;
  StatusOr<IntraSessionPairsStats> stats = pairs.value()->Finish(&during);
  ASSERT_TRUE(stats.ok()) << stats.status().message();
  std::cout << stats.value().pairs_during_session << " of " << stats.value().pairs
            << " pairs detected by the worker" << std::endl;
  EXPECT_EQ(stats.value().pairs, end_stats.value().pairs);
  EXPECT_EQ(stats.value().points_removed, end_stats.value().points_removed);
  for (std::size_t k = 0; k < during.size(); ++k) {
    EXPECT_TRUE(during[k].points == at_end[k].points) << "submap " << k;
  }
}

// The submaps handed to Finish must be those added (the worker detected on copies of them).
TEST(IntraSessionPairs, FinishRefusesSubmapsThatChangedSinceAdd) {
  auto session = BuildSession();
  ASSERT_GE(session.size(), 2u);
  IntraSessionPairsConfig config;
  config.during_session = false;
  StatusOr<std::unique_ptr<IntraSessionPairDetector>> pairs =
      IntraSessionPairDetector::Create(config);
  ASSERT_TRUE(pairs.ok());
  for (const Submap& submap : session) pairs.value()->Add(submap, submap.T_map_submap);
  session[1].points.pop_back();
  StatusOr<IntraSessionPairsStats> stats = pairs.value()->Finish(&session);
  ASSERT_FALSE(stats.ok());
  EXPECT_NE(stats.status().message().find("submap 1"), std::string::npos)
      << stats.status().message();
  session.pop_back();
  StatusOr<std::unique_ptr<IntraSessionPairDetector>> again =
      IntraSessionPairDetector::Create(config);
  ASSERT_TRUE(again.ok());
  for (std::size_t k = 0; k + 1 < session.size(); ++k) again.value()->Add(session[k], {});
  session.clear();
  EXPECT_FALSE(again.value()->Finish(&session).ok()) << "fewer submaps than added";
}

TEST(IntraSessionPairs, RejectsInvalidConfigs) {
  std::vector<Submap, Eigen::aligned_allocator<Submap>> submaps(2);
  IntraSessionPairsConfig config;
  config.neighbours = 0;
  EXPECT_FALSE(RemoveDynamicsBetweenSubmaps(config, &submaps).ok());
  config = IntraSessionPairsConfig();
  config.max_dynamic_fraction = 0.0;
  EXPECT_FALSE(RemoveDynamicsBetweenSubmaps(config, &submaps).ok());
  config = IntraSessionPairsConfig();
  config.num_threads = 0;
  EXPECT_FALSE(RemoveDynamicsBetweenSubmaps(config, &submaps).ok());
  config = IntraSessionPairsConfig();
  config.min_cluster_coarse_fraction = 1.5;
  EXPECT_FALSE(RemoveDynamicsBetweenSubmaps(config, &submaps).ok());
  config = IntraSessionPairsConfig();
  config.own_ground_max_gap_m = -0.1;
  EXPECT_FALSE(RemoveDynamicsBetweenSubmaps(config, &submaps).ok());
  config = IntraSessionPairsConfig();
  config.detection.voxel_size_m = -1.0;
  EXPECT_FALSE(RemoveDynamicsBetweenSubmaps(config, &submaps).ok());
  // Submaps without points or scans are no pairs.
  StatusOr<IntraSessionPairsStats> stats =
      RemoveDynamicsBetweenSubmaps(IntraSessionPairsConfig(), &submaps);
  ASSERT_TRUE(stats.ok()) << stats.status().message();
  EXPECT_EQ(stats.value().pairs, 0u);
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
