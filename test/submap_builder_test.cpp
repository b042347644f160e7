#include "multisession_mapper/core/submap_builder.h"

#include <cmath>
#include <iostream>
#include <limits>
#include <map>
#include <random>
#include <set>
#include <tuple>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "multisession_mapper/core/se3.h"
#include "multisession_mapper/core/voxel_key.h"

namespace multisession_mapper {
namespace core {
namespace {

// Ground (z = 0), a wall at x = wall_x (20 m; 5 m high, |y| < 1.5 wall_x), and a car
// (4.5 x 1.8 x 1.5 m box) driving along y at x = car_x (10 m). The sensor is 1.8 m above
// the ground.
struct Scene {
  double car_y = 0.0;
  bool car_present = true;
  double car_x = 10.0;
  double wall_x = 20.0;
  // The car's half sizes and vertical extent [m] (a pedestrian: 0.25, 0.25, 0 to 1.7 m).
  double car_half_x = 0.9, car_half_y = 2.25, car_bottom_z = 0.2, car_top_z = 1.7;

  double Raycast(const Eigen::Vector3d& o, const Eigen::Vector3d& d) const {
    double best = std::numeric_limits<double>::infinity();
    if (d.z() < -1e-9) best = -o.z() / d.z();
    if (d.x() > 1e-9) {
      const double t = (wall_x - o.x()) / d.x();
      const Eigen::Vector3d p = o + t * d;
      if (t > 0 && std::abs(p.y()) < 3.0 * wall_x / 2.0 && p.z() >= 0.0 && p.z() < 5.0) best = std::min(best, t);
    }
    if (car_present) {
      const Eigen::Vector3d lo(car_x - car_half_x, car_y - car_half_y, car_bottom_z);
      const Eigen::Vector3d hi(car_x + car_half_x, car_y + car_half_y, car_top_z);
      double t_near = 0.0, t_far = best;
      bool hit = true;
      for (int a = 0; a < 3 && hit; ++a) {
        if (std::abs(d(a)) < 1e-12) {
          hit = o(a) >= lo(a) && o(a) <= hi(a);
          continue;
        }
        double t1 = (lo(a) - o(a)) / d(a), t2 = (hi(a) - o(a)) / d(a);
        if (t1 > t2) std::swap(t1, t2);
        t_near = std::max(t_near, t1);
        t_far = std::min(t_far, t2);
        hit = t_near <= t_far;
      }
      if (hit && t_near > 0.0) best = std::min(best, t_near);
    }
    return best;
  }
};

// A VLP-16-like scan in the sensor frame (no motion during the sweep: the builder gets
// de-skewed scans).
LidarScan Scan(const Scene& scene, const Pose3& T_world_sensor, double stamp_s, std::mt19937* rng) {
  std::normal_distribution<double> noise(0.0, 0.02);
  LidarScan scan;
  scan.stamp_s = stamp_s;
  scan.has_ring = true;
  for (int col = 0; col < 900; ++col) {
    const double azimuth = 2.0 * M_PI * col / 900.0;
    for (int ring = 0; ring < 16; ++ring) {
      const double elevation = (-15.0 + 2.0 * ring) * M_PI / 180.0;
      const Eigen::Vector3d d(std::cos(elevation) * std::cos(azimuth),
                              std::cos(elevation) * std::sin(azimuth), std::sin(elevation));
      const double range = scene.Raycast(T_world_sensor.translation(), T_world_sensor.linear() * d);
      if (!(range < 100.0)) continue;
      LidarPoint p;
      p.position_m = (d * (range + noise(*rng))).cast<float>();
      p.ring = static_cast<std::uint16_t>(ring);
      scan.points.push_back(p);
    }
  }
  return scan;
}

bool OnCarPath(const Eigen::Vector3d& p_world, double car_x = 10.0) {
  return p_world.x() > car_x - 1.1 && p_world.x() < car_x + 1.1 && p_world.z() > 0.1;
}

// Points of the builder's finished submaps on the car's path (map frame).
int CarPointsIn(SubmapBuilder* builder, double car_x = 10.0) {
  int car_points = 0;
  for (const Submap& submap : builder->TakeFinished()) {
    for (const Eigen::Vector3d& p : submap.points) {
      car_points += OnCarPath(submap.T_map_submap * p, car_x);
    }
  }
  return car_points;
}

struct Result {
  int car_points = 0;
  int static_points = 0;
  PointVector points;  ///< every submap point, map frame, in submap and storage order
  std::uint64_t dropped = 0;
  std::size_t submaps = 0;
};

// Robot creeps along x while the car crosses its view at 4 m/s, then turns off the road (out
// of view) for the last 4 s.
Result RunCrossingCar(bool filter_enabled, int grow_depth = 2, int check_threads = 2,
                      double max_translation_m = 20.0,
                      SubmapBuilderConfig config = SubmapBuilderConfig()) {
  config.max_translation_m = max_translation_m;
  config.dynamic_filter.enabled = filter_enabled;
  config.dynamic_filter.grow_depth = grow_depth;
  config.dynamic_filter.check_threads = check_threads;
  StatusOr<SubmapBuilder> builder = SubmapBuilder::Create(config, "s00");
  EXPECT_TRUE(builder.ok()) << builder.status().message();
  std::mt19937 rng(1);
  Scene scene;
  std::vector<Pose3, Eigen::aligned_allocator<Pose3>> poses;
  for (int i = 0; i < 160; ++i) {
    scene.car_y = -24.0 + 0.4 * i;
    scene.car_present = i < 120;
    const Pose3 T_world_sensor = se3::FromXyzRpy(0.025 * i, 0.0, 1.8, 0, 0, 0);
    builder.value().AddScan(Scan(scene, T_world_sensor, 100.0 + 0.1 * i, &rng), T_world_sensor);
  }
  builder.value().FinishSession();
  Result result;
  for (const Submap& submap : builder.value().TakeFinished()) {
    for (const Eigen::Vector3d& p : submap.points) {
      (OnCarPath(submap.T_map_submap * p) ? result.car_points : result.static_points)++;
      result.points.push_back(submap.T_map_submap * p);
    }
  }
  result.dropped = builder.value().stats().voxels_dropped_dynamic;
  result.submaps = builder.value().stats().submaps_finished;
  return result;
}

TEST(SubmapBuilder, CheckThreadsChangeNothing) {
  // The visibility check's voxels are split over the threads in blocks; each voxel's evidence
  // is its own, so the submaps must be the same point for point with 1 thread (one plain loop
  // per open submap), 2 and 3. Submaps of 1 m, so that several are open at every check.
  const Result one = RunCrossingCar(true, 2, 1, 1.0);
  ASSERT_GT(one.dropped, 100u) << "the check must have dropped the car";
  ASSERT_GT(one.points.size(), 20000u) << "several blocks of voxels per check";
  ASSERT_GE(one.submaps, 3u) << "several open submaps per check";
  for (const int threads : {2, 3}) {
    const Result more = RunCrossingCar(true, 2, threads, 1.0);
    EXPECT_EQ(more.dropped, one.dropped) << threads << " threads";
    ASSERT_EQ(more.points.size(), one.points.size()) << threads << " threads";
    for (std::size_t i = 0; i < one.points.size(); ++i) {
      ASSERT_EQ(more.points[i], one.points[i]) << threads << " threads, point " << i;
    }
  }
}

TEST(SubmapBuilder, MovingCarIsRemovedAndStaticWorldKept) {
  const Result unfiltered = RunCrossingCar(false);
  const Result filtered = RunCrossingCar(true);
  ASSERT_GT(unfiltered.car_points, 500) << "the car must leave a trail without the filter";
  // >= 97 % of the moving car's points gone (what remains is its lowest 0.2-0.5 m, where a
  // range test cannot tell it from the ground just behind), >= 99 % of static points kept.
  EXPECT_LT(filtered.car_points, 0.03 * unfiltered.car_points)
      << filtered.car_points << " of " << unfiltered.car_points << " car points remain";
  EXPECT_GT(filtered.static_points, 0.99 * unfiltered.static_points)
      << filtered.static_points << " of " << unfiltered.static_points << " static points kept";
}

// The sensor is 1.8 m up: the ground lies on a boundary of the submap's voxel layers and its
// returns (2 cm noise) fill both layers at about one height. Under the car's path, whose body
// voxels are dropped, the upper one would go as "residue" without the rule's minimum rise.
TEST(SubmapBuilder, ResidueRuleKeepsGroundThatStraddlesTwoLayers) {
  SubmapBuilderConfig config;
  config.dynamic_filter.drop_residue_under_removed = false;
  const Result without = RunCrossingCar(true, 2, 2, 20.0, config);
  config.dynamic_filter.drop_residue_under_removed = true;
  const Result with = RunCrossingCar(true, 2, 2, 20.0, config);
  config.dynamic_filter.residue_min_rise_m = 0.0;
  const Result no_rise = RunCrossingCar(true, 2, 2, 20.0, config);
  std::cout << "static points: " << without.static_points << " without the residue rule, "
            << with.static_points << " with it, " << no_rise.static_points
            << " with it and no minimum rise" << std::endl;
  EXPECT_EQ(with.static_points, without.static_points);
  EXPECT_LT(no_rise.static_points, without.static_points - 200);
}

TEST(SubmapBuilder, GrowingRemovesTheLowestPartsOfTheMovingCar) {
  // The lowest 0.2-0.5 m of the car get no "seen through" evidence (the beams that pass there
  // now hit the ground just behind at grazing angles); growing the dropped voxels into
  // neighbours that were only measured while the car was there removes them, and keeps the
  // ground under the car's path, which was measured again after it passed.
  const Result unfiltered = RunCrossingCar(false);
  const Result no_growing = RunCrossingCar(true, 0);
  const Result growing = RunCrossingCar(true, 2);
  std::cout << "car points: " << unfiltered.car_points << " unfiltered, " << no_growing.car_points
            << " without growing, " << growing.car_points << " with growing; static "
            << unfiltered.static_points << " / " << no_growing.static_points << " / "
            << growing.static_points << std::endl;
  EXPECT_LT(growing.car_points, no_growing.car_points);
  EXPECT_LT(growing.car_points, 0.015 * unfiltered.car_points);
  EXPECT_GT(growing.static_points, 0.99 * unfiltered.static_points);
}

// The robot stands still for 10 s while a car at x = car_x is present from scan `first_scan`
// to scan `car_scans` and then gone; the wall is 10 m behind the car, so that the beams that
// hit the car hit the wall once it is gone. Returns the car's points left in the submaps.
int CarPointsLeft(const SubmapBuilderConfig& config, double car_x, int car_scans, bool moving,
                  int first_scan = 0) {
  StatusOr<SubmapBuilder> builder = SubmapBuilder::Create(config, "s00");
  EXPECT_TRUE(builder.ok()) << builder.status().message();
  std::mt19937 rng(3);
  Scene scene;
  scene.car_x = car_x;
  scene.wall_x = car_x + 10.0;
  const Pose3 pose = se3::FromXyzRpy(0, 0, 1.8, 0, 0, 0);
  for (int i = 0; i < 100; ++i) {
    scene.car_y = moving ? -20.0 + 0.4 * i : 0.0;
    scene.car_present = i >= first_scan && i < car_scans;
    builder.value().AddScan(Scan(scene, pose, 10.0 + 0.1 * i, &rng), pose);
  }
  builder.value().FinishSession();
  return CarPointsIn(&builder.value(), car_x);
}

// A car crossing 50 m away (one ring of a VLP-16 on it, none on the ground there) is
// checked up to max_check_range_m, and removed by the majority of its checks.
TEST(SubmapBuilder, FarCarIsCheckedUpToTheCheckRange) {
  SubmapBuilderConfig config;
  config.dynamic_filter.enabled = false;
  const int unfiltered = CarPointsLeft(config, 50.0, 90, true);
  config.dynamic_filter.enabled = true;
  ASSERT_GT(unfiltered, 30) << "the car must leave a trail without the filter";
  config.dynamic_filter.max_check_range_m = 40.0;
  const int unchecked = CarPointsLeft(config, 50.0, 90, true);
  config.dynamic_filter.max_check_range_m = 60.0;
  const int checked = CarPointsLeft(config, 50.0, 90, true);
  std::cout << "far car points: " << unfiltered << " unfiltered, " << unchecked
            << " checked to 40 m, " << checked << " checked to 60 m" << std::endl;
  EXPECT_EQ(unchecked, unfiltered) << "never checked: all kept";
  EXPECT_LT(checked, 0.05 * unfiltered);
}

// A car parked for 94 scans that leaves 6 scans (3 checks) before the end: near, its last
// three checks saw through it and it goes (the consecutive rule: recent evidence wins); far,
// three seen-through checks against 47 consistent ones are no majority, and it stays.
TEST(SubmapBuilder, FarChecksDropOnlyByTheirMajority) {
  SubmapBuilderConfig config;
  config.dynamic_filter.max_check_range_m = 60.0;
  config.dynamic_filter.near_range_m = 40.0;
  const int near_kept = CarPointsLeft(config, 25.0, 94, false);
  const int far_kept = CarPointsLeft(config, 50.0, 94, false);
  SubmapBuilderConfig unfiltered = config;
  unfiltered.dynamic_filter.enabled = false;
  const int far_all = CarPointsLeft(unfiltered, 50.0, 94, false);
  config.dynamic_filter.near_range_m = 60.0;
  const int far_as_near_kept = CarPointsLeft(config, 50.0, 94, false);
  std::cout << "parked car points left: near " << near_kept << ", far " << far_kept << " of "
            << far_all << ", far counted as near " << far_as_near_kept << std::endl;
  ASSERT_GT(far_all, 5);
  EXPECT_LT(near_kept, 5) << "near: the consecutive rule drops the car that left";
  EXPECT_EQ(far_kept, far_all) << "far: no majority, kept";
  EXPECT_LT(far_as_near_kept, 0.2 * far_all)
      << "with far checks counted as near the consecutive rule drops it";
}

// A car 30 m away stands for the first 60 of the 100 scans and leaves. Each of its voxels was
// measured in 30 checks and seen through in 20: no majority, and with the consecutive rule
// off nothing else drops it. As a group above the ground, 40 % of its checks saw through it:
// the seen-through groups drop it, or the part of it that stands high enough: two rings hit
// it, and the lower one hits it 0.2 m up, below both height limits (0.25 m over the fine
// ground, 0.5 m over the coarse one), so it stays (half the car's points). The same car
// standing for 94 scans (3 of 50 checks seen through) stays whole.
TEST(SubmapBuilder, SeenThroughGroupsDropWhatNoSingleVoxelsMajorityCould) {
  SubmapBuilderConfig config;
  config.dynamic_filter.min_consecutive_seen_through = 0;
  SubmapBuilderConfig unfiltered = config;
  unfiltered.dynamic_filter.enabled = false;
  SubmapBuilderConfig no_groups = config;
  no_groups.dynamic_filter.groups.min_seen_through_ratio = 0.0;
  const int all = CarPointsLeft(unfiltered, 30.0, 60, false);
  const int per_voxel = CarPointsLeft(no_groups, 30.0, 60, false);
  const int grouped = CarPointsLeft(config, 30.0, 60, false);
  const int stayed = CarPointsLeft(config, 30.0, 94, false);
  const int stayed_all = CarPointsLeft(unfiltered, 30.0, 94, false);
  std::cout << "car 30 m away for 60 scans: " << all << " points unfiltered, " << per_voxel
            << " left by the per-voxel rules, " << grouped << " with the groups; for 94 scans "
            << stayed << " of " << stayed_all << std::endl;
  ASSERT_GT(all, 20);
  EXPECT_GT(per_voxel, 0.8 * all) << "no single voxel's majority";
  EXPECT_LT(grouped, 0.6 * per_voxel);
  EXPECT_GT(stayed, 0.9 * stayed_all) << "a car that stayed is kept";
}

// A pedestrian (0.5 x 0.5 x 1.7 m, standing on the ground) `x_m` ahead for the first
// `present_scans` scans, then gone, while the robot creeps towards it at 0.2 m/s. The sensor
// is 1.9 m up, so that the ground lies in the middle of its voxel layer and the lowest
// 0.1-0.3 m of the pedestrian (its feet) fill the voxel layer above the ground. Returns the
// pedestrian's points left more than 0.1 m above the ground, and the static points kept.
std::pair<int, int> PedestrianPointsLeft(const SubmapBuilderConfig& config, int present_scans,
                                         double x_m) {
  StatusOr<SubmapBuilder> builder = SubmapBuilder::Create(config, "s00");
  EXPECT_TRUE(builder.ok()) << builder.status().message();
  std::mt19937 rng(4);
  Scene scene;
  scene.car_x = x_m;
  scene.car_y = 0.0;
  scene.wall_x = x_m + 10.0;
  scene.car_half_x = scene.car_half_y = 0.25;
  scene.car_bottom_z = 0.0;
  for (int i = 0; i < 100; ++i) {
    scene.car_present = i < present_scans;
    const Pose3 pose = se3::FromXyzRpy(0.02 * i, 0.0, 1.9, 0, 0, 0);
    builder.value().AddScan(Scan(scene, pose, 10.0 + 0.1 * i, &rng), pose);
  }
  builder.value().FinishSession();
  std::pair<int, int> left(0, 0);
  for (const Submap& submap : builder.value().TakeFinished()) {
    for (const Eigen::Vector3d& p : submap.points) {
      const Eigen::Vector3d w = submap.T_map_submap * p;
      const bool on_pedestrian = std::abs(w.x() - x_m) < 0.35 && std::abs(w.y()) < 0.35;
      if (on_pedestrian && w.z() > 0.1) {
        ++left.first;
      } else if (!on_pedestrian) {
        ++left.second;
      }
    }
  }
  return left;
}

// A feet rule's effect: the pedestrian's points left (first) and the static points kept
// (second) without the filter, then with it (no checks against the past, neither feet rule)
// without and with `rule`, for a pedestrian who leaves after 30 scans 8 m ahead and for one
// who never leaves, 10 m ahead.
struct FeetRuleEffect {
  std::pair<int, int> unfiltered, without, with, stays_without, stays_with;
};
FeetRuleEffect FeetRule(bool InSessionDynamicFilterConfig::*rule, const char* name) {
  FeetRuleEffect e;
  SubmapBuilderConfig config;
  config.dynamic_filter.enabled = false;
  e.unfiltered = PedestrianPointsLeft(config, 30, 8.0);
  config.dynamic_filter.enabled = true;
  config.dynamic_filter.past_checks = 0;
  config.dynamic_filter.grow_over_measured_ground = false;
  config.dynamic_filter.drop_residue_under_removed = false;
  e.without = PedestrianPointsLeft(config, 30, 8.0);
  e.stays_without = PedestrianPointsLeft(config, 100, 10.0);
  config.dynamic_filter.*rule = true;
  e.with = PedestrianPointsLeft(config, 30, 8.0);
  e.stays_with = PedestrianPointsLeft(config, 100, 10.0);
  std::cout << "pedestrian points: " << e.unfiltered.first << " unfiltered, " << e.without.first
            << " without " << name << ", " << e.with.first << " with it; static "
            << e.unfiltered.second << " / " << e.without.second << " / " << e.with.second
            << "; one that never leaves: " << e.stays_without.first << " / "
            << e.stays_with.first << std::endl;
  EXPECT_GT(e.unfiltered.first, 20) << "the pedestrian must leave points without the filter";
  EXPECT_GT(e.without.first, 0) << "without the rule its feet stay";
  EXPECT_EQ(e.with.first, 0);
  EXPECT_GT(e.with.second, 0.99 * e.unfiltered.second);
  EXPECT_GT(e.stays_without.first, 10);
  EXPECT_EQ(e.stays_with.first, e.stays_without.first);
  return e;
}

// The pedestrian's body is seen through once it has gone and is dropped; the voxel of its feet
// just above the ground is not (the beams through it land on the ground just behind it, within
// the margin), but it received no point after the pedestrian left while the ground voxel right
// below it did: grown over the measured ground, it goes too. A pedestrian that never leaves
// loses nothing more to the rule (10 m away the check itself drops part of its top as the
// robot's rings sweep over it, and growing spreads from there; the rule must not add to it:
// without its "nothing below the ground" condition it took 5 of the 29 points left). The foot
// here is one voxel. The rule is measured without the checks against the past; with them
// (the defaults) the one that never leaves loses one point more of its 29 (a voxel at its
// top seen through by both kinds of checks grows down to the foot).
TEST(SubmapBuilder, FeetAreGrownOverTheGroundMeasuredAfterThePedestrianLeft) {
  const FeetRuleEffect e =
      FeetRule(&InSessionDynamicFilterConfig::grow_over_measured_ground, "the ground rule");
  const std::pair<int, int> stays_default =
      PedestrianPointsLeft(SubmapBuilderConfig(), 100, 10.0);
  std::cout << "one that never leaves, defaults: " << stays_default.first << std::endl;
  EXPECT_GE(stays_default.first, e.stays_with.first - 1);
}

// The other rule for the same feet: the voxel layer right above the ground under the removed
// body, with nothing kept above it, goes (after the groups; here without the growing over the
// measured ground, which would take these feet first). A pedestrian that never leaves keeps
// its feet: its body above them is kept.
TEST(SubmapBuilder, ResidueUnderARemovedPedestrianIsDropped) {
  FeetRule(&InSessionDynamicFilterConfig::drop_residue_under_removed, "the residue rule");
}

// A car follows the robot along x at its speed (0.4 m per scan), its front 7.75 m behind the
// sensor. Every place its front face was is later occluded by the car itself, so the checks
// of later scans never see through its trail; the beams of earlier scans passed through each
// of those places before the car arrived. Returns the car's points and the static points
// left in the submaps; car points only from the place its front reached after 10 scans
// (-3.75 m): before that there are no earlier images to check against.
std::pair<int, int> FollowerPointsLeft(const SubmapBuilderConfig& config) {
  StatusOr<SubmapBuilder> builder = SubmapBuilder::Create(config, "s00");
  EXPECT_TRUE(builder.ok()) << builder.status().message();
  std::mt19937 rng(5);
  Scene scene;
  scene.car_half_x = 2.25;
  scene.car_half_y = 0.9;
  scene.wall_x = 60.0;
  std::pair<int, int> left(0, 0);
  for (int i = 0; i < 100; ++i) {
    const double x = 0.4 * i;
    scene.car_x = x - 10.0;
    const Pose3 pose = se3::FromXyzRpy(x, 0.0, 1.8, 0, 0, 0);
    builder.value().AddScan(Scan(scene, pose, 10.0 + 0.1 * i, &rng), pose);
  }
  builder.value().FinishSession();
  for (const Submap& submap : builder.value().TakeFinished()) {
    for (const Eigen::Vector3d& p : submap.points) {
      const Eigen::Vector3d w = submap.T_map_submap * p;
      // The front face's trail: from the first front (-7.75 m) to the last (31.85 m).
      const bool on_trail = w.x() > -8.0 && w.x() < 32.0 && std::abs(w.y()) < 1.0 && w.z() > 0.15;
      if (!on_trail) {
        ++left.second;
      } else if (w.x() > -3.5) {
        ++left.first;
      }
    }
  }
  return left;
}

TEST(SubmapBuilder, PastChecksRemoveTheTrailOfACarThatFollows) {
  SubmapBuilderConfig config;
  config.dynamic_filter.enabled = false;
  const std::pair<int, int> unfiltered = FollowerPointsLeft(config);
  config.dynamic_filter.enabled = true;
  config.dynamic_filter.past_checks = 0;
  const std::pair<int, int> later_only = FollowerPointsLeft(config);
  config.dynamic_filter.past_checks = 5;
  config.dynamic_filter.past_check_stride = 1;
  const std::pair<int, int> with_past = FollowerPointsLeft(config);
  std::cout << "follower trail points: " << unfiltered.first << " unfiltered, "
            << later_only.first << " with later checks only, " << with_past.first
            << " with past checks; static " << unfiltered.second << " / " << later_only.second
            << " / " << with_past.second << std::endl;
  ASSERT_GT(unfiltered.first, 300) << "the follower must leave a trail without the filter";
  EXPECT_GT(later_only.first, 0.5 * unfiltered.first) << "later scans cannot see the trail";
  EXPECT_LT(with_past.first, 0.05 * unfiltered.first);
  EXPECT_GT(with_past.second, 0.99 * unfiltered.second);
}

// A pedestrian runs straight at the robot, which stands still, at 0.3 m per scan, from 45 m
// to 15 m, a wall 10 m behind its start. Each place its front was is later occluded by the
// runner itself, closer now; a beam of an earlier scan measured the front farther away, but
// beyond the margin (0.3 m + 2 % of 15-45 m: 0.6-1.2 m) only when that scan is 4 or more scans
// old at 30 m. Returns its points left in the submaps (more than 0.1 m above the ground).
int RunnerPointsLeft(const SubmapBuilderConfig& config) {
  StatusOr<SubmapBuilder> builder = SubmapBuilder::Create(config, "s00");
  EXPECT_TRUE(builder.ok()) << builder.status().message();
  std::mt19937 rng(6);
  Scene scene;
  scene.car_half_x = scene.car_half_y = 0.25;
  scene.car_bottom_z = 0.0;
  scene.wall_x = 55.0;
  const Pose3 pose = se3::FromXyzRpy(0.0, 0.0, 1.8, 0, 0, 0);
  for (int i = 0; i < 100; ++i) {
    scene.car_x = 45.0 - 0.3 * i;
    builder.value().AddScan(Scan(scene, pose, 10.0 + 0.1 * i, &rng), pose);
  }
  builder.value().FinishSession();
  int left = 0;
  for (const Submap& submap : builder.value().TakeFinished()) {
    for (const Eigen::Vector3d& p : submap.points) {
      const Eigen::Vector3d w = submap.T_map_submap * p;
      left += w.x() > 14.0 && w.x() < 45.5 && std::abs(w.y()) < 0.35 && w.z() > 0.1;
    }
  }
  return left;
}

// Two past images, 1-4 scans back (checks every 2nd scan), see through little of the runner's
// trail (a voxel is dropped when seen through twice and more often than measured); with a
// stride of 4 the same two images are 1-8 and 9-16 scans old and see through more than half
// of what is left.
TEST(SubmapBuilder, OlderPastImagesSeeWhatRecentOnesCannot) {
  SubmapBuilderConfig config;
  config.dynamic_filter.enabled = false;
  const int unfiltered = RunnerPointsLeft(config);
  config.dynamic_filter.enabled = true;
  config.dynamic_filter.past_checks = 0;
  const int later_only = RunnerPointsLeft(config);
  config.dynamic_filter.past_checks = 2;
  config.dynamic_filter.past_check_stride = 1;
  const int recent = RunnerPointsLeft(config);
  config.dynamic_filter.past_check_stride = 4;
  const int strided = RunnerPointsLeft(config);
  std::cout << "runner points: " << unfiltered << " unfiltered, " << later_only
            << " later checks only, 2 past images: " << recent
            << ", 2 of every 4th check: " << strided << std::endl;
  ASSERT_GT(unfiltered, 100) << "the runner must leave a trail without the filter";
  EXPECT_GT(later_only, 0.5 * unfiltered);
  EXPECT_GT(recent, 0.5 * unfiltered);
  EXPECT_LT(strided, 0.5 * recent);
}

// A car that arrives while the robot stands there (scan 20 of 100) and stays: every earlier
// image saw through where it now is, and every later check measures it. The later checks
// outvote the earlier ones (40 against at most 16), and it is kept, as it is without them.
TEST(SubmapBuilder, ACarThatArrivesAndStaysIsKept) {
  SubmapBuilderConfig config;
  const auto car_points = [&config]() { return CarPointsLeft(config, 10.0, 100, false, 20); };
  const int with_past = car_points();
  config.dynamic_filter.past_checks = 0;
  const int later_only = car_points();
  std::cout << "arrived car points: " << with_past << " with past checks, " << later_only
            << " without" << std::endl;
  ASSERT_GT(later_only, 100);
  EXPECT_GE(with_past, later_only);
}

TEST(SubmapBuilder, ParkedCarIsKept) {
  // A car that never moves is static within a session (low-dynamic objects are the job of
  // the multi-session stage).
  SubmapBuilderConfig config;
  StatusOr<SubmapBuilder> builder = SubmapBuilder::Create(config, "s00");
  ASSERT_TRUE(builder.ok());
  std::mt19937 rng(2);
  Scene scene;
  scene.car_y = 3.0;
  for (int i = 0; i < 60; ++i) {
    const Pose3 pose = se3::FromXyzRpy(0.1 * i, -10.0 + 0.3 * i, 1.8, 0, 0, 0.1);
    builder.value().AddScan(Scan(scene, pose, 10.0 + 0.1 * i, &rng), pose);
  }
  builder.value().FinishSession();
  EXPECT_GT(CarPointsIn(&builder.value()), 300);
  EXPECT_EQ(builder.value().stats().voxels_dropped_dynamic < 0.01 * builder.value().stats().voxels_kept, true)
      << builder.value().stats().voxels_dropped_dynamic << " dropped of "
      << builder.value().stats().voxels_kept;
}

// The submap's points are the centroids of its voxels, every in-range point summed in scan
// order, stored in Z-order (the voxels in first-hit order, sorted): a plain reference against
// the builder's prefetching look-ups (runs of one voxel, voxels revisited out of order, scans
// of 0 to 40 points around the look-up's lag, points out of range and not finite).
// With robust_height off (on: the next test).
TEST(SubmapBuilder, VoxelsAreTheCentroidsOfTheirPointsInZOrderWithTheirViews) {
  SubmapBuilderConfig config;
  config.robust_height = false;
  config.dynamic_filter.enabled = false;
  config.voxel_size_m = 0.5;
  config.max_point_range_m = 9.0;
  StatusOr<SubmapBuilder> builder = SubmapBuilder::Create(config, "s00");
  ASSERT_TRUE(builder.ok());
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> coordinate(-6.0f, 6.0f);
  std::uniform_int_distribution<int> run(1, 4);
  std::vector<VoxelKey> first_hit;
  std::map<std::tuple<int, int, int>, std::pair<Eigen::Vector3d, int>> sums;
  // Per voxel: the scan of its nearest point (the first on ties) and its last scan.
  std::map<std::tuple<int, int, int>, std::pair<double, PointViews>> views;
  const Pose3 T_odom_sensor = se3::FromXyzRpy(0.3, -0.2, 0.1, 0.0, 0.0, 0.4);
  for (int k = 0; k < 60; ++k) {
    LidarScan scan;
    scan.stamp_s = k;
    const int n = k % 41;  // 0 .. 40 points
    while (static_cast<int>(scan.points.size()) < n) {
      LidarPoint p;
      p.position_m = Eigen::Vector3f(coordinate(rng), coordinate(rng), coordinate(rng) / 3.0f);
      for (int r = run(rng); r > 0 && static_cast<int>(scan.points.size()) < n; --r) {
        scan.points.push_back(p);  // a run of points in one voxel
        p.position_m.x() += 0.01f;
      }
    }
    if (n > 3) scan.points[1].position_m.y() = std::numeric_limits<float>::quiet_NaN();
    if (n > 5) scan.points[4].position_m = Eigen::Vector3f(9.5f, 0.0f, 0.0f);  // out of range
    builder.value().AddScan(scan, T_odom_sensor);
    for (const LidarPoint& p : scan.points) {
      const Eigen::Vector3d q = p.position_m.cast<double>();
      if (!q.allFinite() || q.norm() > config.max_point_range_m) continue;
      const Eigen::Vector3d& in_submap = q;  // every scan at the submap's origin pose
      const VoxelKey key = ToVoxelKey(in_submap, config.voxel_size_m);
      auto& sum = sums[{key.x(), key.y(), key.z()}];
      if (sum.second == 0) {
        first_hit.push_back(key);
        sum.first.setZero();
      }
      sum.first += in_submap;
      ++sum.second;
      auto& view = views[{key.x(), key.y(), key.z()}];
      if (sum.second == 1 || static_cast<float>(q.squaredNorm()) < view.first) {
        view.first = static_cast<float>(q.squaredNorm());
        view.second.nearest_scan = static_cast<std::uint32_t>(k);
      }
      view.second.last_scan = static_cast<std::uint32_t>(k);
    }
  }
  builder.value().FinishSession();
  const auto submaps = builder.value().TakeFinished();
  ASSERT_EQ(submaps.size(), 1u);
  // The voxels in first-hit order, then stored in Z-order of blocks of voxels (submap_test).
  Submap expected;
  std::set<std::uint32_t> nearest_scans;
  for (const VoxelKey& key : first_hit) {
    const auto& sum = sums[{key.x(), key.y(), key.z()}];
    expected.points.push_back(sum.first / sum.second);
    expected.views.push_back(views[{key.x(), key.y(), key.z()}].second);
    nearest_scans.insert(expected.views.back().nearest_scan);
  }
  SortSubmapPointsInVoxelBlocks(config.voxel_size_m, &expected);
  ASSERT_EQ(submaps[0].points.size(), first_hit.size());
  ASSERT_EQ(submaps[0].views.size(), first_hit.size());
  ASSERT_EQ(submaps[0].scans.size(), 60u);
  bool reordered = false;
  for (std::size_t i = 0; i < first_hit.size(); ++i) {
    ASSERT_EQ(submaps[0].points[i], expected.points[i]) << "voxel " << i;
    EXPECT_EQ(submaps[0].views[i].nearest_scan, expected.views[i].nearest_scan) << "voxel " << i;
    EXPECT_EQ(submaps[0].views[i].last_scan, expected.views[i].last_scan) << "voxel " << i;
    const auto& first = sums[{first_hit[i].x(), first_hit[i].y(), first_hit[i].z()}];
    reordered = reordered || submaps[0].points[i] != first.first / first.second;
  }
  EXPECT_TRUE(reordered);  // the Z-order is not the first-hit order here
  EXPECT_GT(nearest_scans.size(), 20u);  // the views differ from voxel to voxel
}

// Ground 1.95 m below the sensor (in the voxel layer [-2.0, -1.8) m) over 4 x 4 voxels; in two
// scans of five something stands on it, and half of those scans' returns come from it, 6-14 cm
// above the ground (the same voxels; a fifth of all returns). With robust_height the stored
// points stay on the ground; without it they are lifted by about 2 cm. x and y are the
// centroid's either way.
TEST(SubmapBuilder, RobustHeightKeepsAMinorityAboveTheGroundFromLiftingIt) {
  std::map<bool, std::vector<Eigen::Vector3d>> stored;
  std::vector<Eigen::Vector3d> centroids;
  for (const bool robust : {false, true}) {
    SubmapBuilderConfig config;
    config.robust_height = robust;
    config.dynamic_filter.enabled = false;
    StatusOr<SubmapBuilder> builder = SubmapBuilder::Create(config, "s00");
    ASSERT_TRUE(builder.ok());
    std::mt19937 rng(9);
    std::uniform_real_distribution<float> xy(0.0f, 0.8f);
    std::normal_distribution<float> noise(0.0f, 0.005f);
    std::uniform_real_distribution<float> lift(0.06f, 0.14f);
    std::map<std::tuple<int, int>, std::pair<Eigen::Vector3d, int>> sums;
    for (int k = 0; k < 50; ++k) {
      LidarScan scan;
      scan.stamp_s = k;
      for (int i = 0; i < 200; ++i) {
        LidarPoint p;
        p.position_m = Eigen::Vector3f(2.0f + xy(rng), xy(rng), -1.95f + noise(rng));
        if (k % 5 < 2 && i % 2 == 1) p.position_m.z() = -1.95f + lift(rng);
        scan.points.push_back(p);
        const Eigen::Vector3d q = p.position_m.cast<double>();
        auto& sum = sums[{static_cast<int>(std::floor(q.x() / 0.2)),
                          static_cast<int>(std::floor(q.y() / 0.2))}];
        if (sum.second == 0) sum.first.setZero();
        sum.first += q;
        ++sum.second;
      }
      builder.value().AddScan(scan, Pose3::Identity());
    }
    builder.value().FinishSession();
    const auto submaps = builder.value().TakeFinished();
    ASSERT_EQ(submaps.size(), 1u);
    ASSERT_EQ(submaps[0].points.size(), 16u);
    stored[robust] = submaps[0].points;
    if (robust) {
      for (const Eigen::Vector3d& p : submaps[0].points) {
        const auto& sum = sums.at({static_cast<int>(std::floor(p.x() / 0.2)),
                                   static_cast<int>(std::floor(p.y() / 0.2))});
        centroids.push_back(sum.first / sum.second);
      }
    }
  }
  for (std::size_t i = 0; i < 16; ++i) {
    EXPECT_NEAR(stored[false][i].z(), centroids[i].z(), 1e-9);
    EXPECT_GT(stored[false][i].z(), -1.95 + 0.015) << "the mean of all returns is lifted";
    EXPECT_NEAR(stored[true][i].z(), -1.95, 0.003) << "voxel " << i;
    EXPECT_NEAR(stored[true][i].x(), centroids[i].x(), 1e-9);
    EXPECT_NEAR(stored[true][i].y(), centroids[i].y(), 1e-9);
  }
}

TEST(SubmapBuilder, SplitsOnTranslationAndRotationThresholds) {
  SubmapBuilderConfig config;
  config.dynamic_filter.enabled = false;
  StatusOr<SubmapBuilder> builder = SubmapBuilder::Create(config, "s01");
  ASSERT_TRUE(builder.ok());
  LidarScan empty;
  // 50 scans 1 m apart along x, then 20 scans turning 0.1 rad in place.
  for (int i = 0; i < 50; ++i) {
    empty.stamp_s = i;
    builder.value().AddScan(empty, se3::FromXyzRpy(i, 0, 0, 0, 0, 0));
  }
  for (int i = 1; i <= 20; ++i) {
    empty.stamp_s = 50 + i;
    builder.value().AddScan(empty, se3::FromXyzRpy(49, 0, 0, 0, 0, 0.1 * i));
  }
  builder.value().FinishSession();
  const auto submaps = builder.value().TakeFinished();
  ASSERT_GE(submaps.size(), 4u);
  std::size_t scans = 0;
  for (std::size_t k = 0; k < submaps.size(); ++k) {
    EXPECT_EQ(submaps[k].id, k);
    EXPECT_EQ(submaps[k].session, "s01");
    scans += submaps[k].scans.size();
    for (const SubmapScanRecord& scan : submaps[k].scans) {
      EXPECT_LE(se3::TranslationNorm(scan.T_submap_sensor), 20.0 + 1e-9);
      EXPECT_LE(se3::RotationAngleRad(scan.T_submap_sensor), 0.7 + 1e-9);
    }
    // Origin = pose of the first scan.
    EXPECT_TRUE(submaps[k].scans.front().T_submap_sensor.isApprox(Pose3::Identity(), 1e-12));
  }
  EXPECT_EQ(scans, 70u) << "every scan lands in exactly one submap";
  // 0..20 m, 21..41 m, 42..49 m + turning up to 0.7 rad, the rest of the turn.
  EXPECT_EQ(submaps[0].scans.size(), 21u);
  EXPECT_EQ(submaps[1].scans.size(), 21u);
}

// A scan that the odometry put far from its prediction (a jump) ends the open submaps and
// starts a new one at that scan, with the dynamic filter's tails still open; a smaller
// deviation does not, nor does any deviation with the rule off.
TEST(SubmapBuilder, AJumpOfTheOdometryStartsANewSubmap) {
  for (const double break_m : {0.6, 0.0}) {
    SubmapBuilderConfig config;
    config.break_on_jump_m = break_m;
    StatusOr<SubmapBuilder> builder = SubmapBuilder::Create(config, "s01");
    ASSERT_TRUE(builder.ok());
    LidarScan empty;
    // 10 scans 0.5 m apart; scan 4 deviates 0.5 m from its prediction, scan 7 0.9 m.
    for (int i = 0; i < 10; ++i) {
      empty.stamp_s = i;
      const double jump_m = i == 4 ? 0.5 : i == 7 ? 0.9 : 0.01;
      builder.value().AddScan(empty, se3::FromXyzRpy(0.5 * i, 0, 0, 0, 0, 0), jump_m);
      if (i == 7 && break_m > 0.0) {
        // The submap before the jump is final at once (its tail is not left open).
        const auto before = builder.value().TakeFinished();
        ASSERT_EQ(before.size(), 1u);
        EXPECT_EQ(before[0].started_at_jump_m, 0.0);
      }
    }
    builder.value().FinishSession();
    std::vector<Submap, Eigen::aligned_allocator<Submap>> submaps = builder.value().TakeFinished();
    if (break_m > 0.0) {
      ASSERT_EQ(submaps.size(), 1u);  // the one after the jump (the first was taken above)
      EXPECT_EQ(submaps[0].id, 1u);
      ASSERT_EQ(submaps[0].scans.size(), 3u);  // scans 7, 8, 9
      EXPECT_DOUBLE_EQ(submaps[0].scans.front().stamp_s, 7.0);
      EXPECT_NEAR(submaps[0].T_map_submap.translation().x(), 3.5, 1e-12);
      EXPECT_DOUBLE_EQ(submaps[0].started_at_jump_m, 0.9);  // widens its odometry link
      EXPECT_EQ(builder.value().stats().jump_breaks, 1u);
    } else {
      ASSERT_EQ(submaps.size(), 1u);
      EXPECT_EQ(submaps[0].scans.size(), 10u);
      EXPECT_EQ(submaps[0].started_at_jump_m, 0.0);
      EXPECT_EQ(builder.value().stats().jump_breaks, 0u);
    }
  }
}

TEST(SubmapBuilder, ConfigValidation) {
  SubmapBuilderConfig config;
  EXPECT_TRUE(config.Validate().ok());
  config.max_translation_m = 0.0;
  EXPECT_FALSE(config.Validate().ok());
  config = SubmapBuilderConfig();
  config.dynamic_filter.min_seen_through_ratio = 1.5;
  EXPECT_FALSE(config.Validate().ok());
  config = SubmapBuilderConfig();
  config.dynamic_filter.grow_depth = -1;
  EXPECT_FALSE(config.Validate().ok());
  config = SubmapBuilderConfig();
  config.dynamic_filter.grow_max_scan_gap = -1;
  EXPECT_FALSE(config.Validate().ok());
  config = SubmapBuilderConfig();
  config.dynamic_filter.residue_min_rise_m = -0.01;
  EXPECT_FALSE(config.Validate().ok());
  config = SubmapBuilderConfig();
  config.break_on_jump_m = -0.1;
  EXPECT_FALSE(config.Validate().ok());
  config = SubmapBuilderConfig();
  config.dynamic_filter.check_threads = 0;
  EXPECT_FALSE(config.Validate().ok());
  config = SubmapBuilderConfig();
  config.dynamic_filter.near_range_m = 0.0;
  EXPECT_FALSE(config.Validate().ok());
  config = SubmapBuilderConfig();
  config.dynamic_filter.past_checks = -1;
  EXPECT_FALSE(config.Validate().ok());
  config.dynamic_filter.past_checks = 65;
  EXPECT_FALSE(config.Validate().ok());
  config = SubmapBuilderConfig();
  config.dynamic_filter.past_check_stride = 0;
  EXPECT_FALSE(config.Validate().ok());
  EXPECT_FALSE(SubmapBuilder::Create(SubmapBuilderConfig(), "").ok());
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
