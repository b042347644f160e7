#include "multisession_mapper/core/dynamic_detection.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <numeric>
#include <random>
#include <string>
#include <unordered_map>

#include <gtest/gtest.h>

#include "multisession_mapper/core/point_index.h"
#include "multisession_mapper/core/voxel_key.h"

namespace multisession_mapper {
namespace core {
namespace {

// A synthetic street, ray-cast like a VLP-16 (16 rings, -15..15 deg) from a robot that drives
// along y at x = 0: ground z = 0, a wall at x = 12, a tree (trunk and porous canopy) at
// x = -5, and optionally a parked car between the robot and the wall that hides part of it.
enum Label : int { kGround = 0, kWall = 1, kCar = 2, kTrunk = 3, kCanopy = 4 };

struct Box {
  Eigen::Vector3d lo, hi;
};
const Box kWallBox{{12.0, -10.0, 0.0}, {12.3, 10.0, 4.0}};
const Box kCarBox{{7.2, -2.25, 0.25}, {9.0, 2.25, 1.6}};
const Box kTrunkBox{{-5.2, 5.8, 0.0}, {-4.8, 6.2, 3.5}};
const Eigen::Vector3d kCanopyCentre(-5.0, 6.0, 4.8);
const Eigen::Vector3d kCanopySemiAxes(2.5, 2.5, 1.5);
constexpr double kCanopyDensity = 1.0;  // returns per metre (Beer-Lambert), as the simulator

// Entry/exit distance of a ray through an axis-aligned box; false when it misses.
bool RayBox(const Eigen::Vector3d& o, const Eigen::Vector3d& d, const Box& box, double* t_in,
            double* t_out) {
  double t0 = 0.0, t1 = std::numeric_limits<double>::max();
  for (int i = 0; i < 3; ++i) {
    if (std::abs(d[i]) < 1e-12) {
      if (o[i] < box.lo[i] || o[i] > box.hi[i]) return false;
      continue;
    }
    double a = (box.lo[i] - o[i]) / d[i], b = (box.hi[i] - o[i]) / d[i];
    if (a > b) std::swap(a, b);
    t0 = std::max(t0, a);
    t1 = std::min(t1, b);
    if (t0 > t1) return false;
  }
  *t_in = t0;
  *t_out = t1;
  return true;
}

bool SegmentHitsBox(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Box& box) {
  double t_in = 0.0, t_out = 0.0;
  const Eigen::Vector3d d = b - a;
  return RayBox(a, d, box, &t_in, &t_out) && t_in <= 1.0;
}

struct Scene {
  bool car = false;
  Box car_box = kCarBox;  // another car in the same place: another box
};

struct LabelledCloud {
  PointVector points;
  std::vector<int> labels;
};

// Every return of every scan (world frame), one point per 0.2 m voxel of the SUBMAP frame
// (T_world_submap), as the pipeline's submaps.
LabelledCloud Scan(const Scene& scene, const std::vector<Eigen::Vector3d>& origins,
                   unsigned seed, const Pose3& T_world_submap) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  std::normal_distribution<double> noise(0.0, 0.02);
  VoxelMap<int> first;  // voxel -> index into the output
  LabelledCloud out;
  const Pose3 T_submap_world = T_world_submap.inverse();
  for (std::size_t s = 0; s < origins.size(); ++s) {
    const Eigen::Vector3d& o = origins[s];
    const double azimuth_offset = uniform(rng) * 0.4;
    for (int ring = 0; ring < 16; ++ring) {
      const double elevation = (-15.0 + 2.0 * ring) * M_PI / 180.0;
      for (int column = 0; column < 900; ++column) {
        const double azimuth = (column * 0.4 + azimuth_offset) * M_PI / 180.0;
        const Eigen::Vector3d d(std::cos(elevation) * std::cos(azimuth),
                                std::cos(elevation) * std::sin(azimuth), std::sin(elevation));
        double best = 40.0;
        int label = -1;
        if (d.z() < 0.0) {
          const double t = -o.z() / d.z();
          if (t < best) best = t, label = kGround;
        }
        double t_in = 0.0, t_out = 0.0;
        if (RayBox(o, d, kWallBox, &t_in, &t_out) && t_in < best) best = t_in, label = kWall;
        if (scene.car && RayBox(o, d, scene.car_box, &t_in, &t_out) && t_in < best) {
          best = t_in, label = kCar;
        }
        if (RayBox(o, d, kTrunkBox, &t_in, &t_out) && t_in < best) best = t_in, label = kTrunk;
        // Porous ellipsoid: stopped with probability 1 - exp(-density L) at an exponential
        // depth; a different draw per session.
        const Eigen::Vector3d oc = (o - kCanopyCentre).cwiseQuotient(kCanopySemiAxes);
        const Eigen::Vector3d dc = d.cwiseQuotient(kCanopySemiAxes);
        const double qa = dc.squaredNorm(), qb = 2.0 * oc.dot(dc), qc = oc.squaredNorm() - 1.0;
        const double disc = qb * qb - 4.0 * qa * qc;
        if (disc > 0.0) {
          const double e0 = std::max(0.0, (-qb - std::sqrt(disc)) / (2.0 * qa));
          const double e1 = (-qb + std::sqrt(disc)) / (2.0 * qa);
          if (e1 > e0) {
            const double depth = -std::log(1.0 - uniform(rng)) / kCanopyDensity;
            if (depth < e1 - e0 && e0 + depth < best) best = e0 + depth, label = kCanopy;
          }
        }
        if (label < 0) continue;
        const Eigen::Vector3d p = T_submap_world * (o + (best + noise(rng)) * d);
        auto [it, inserted] = first.emplace(ToVoxelKey(p, 0.2), static_cast<int>(out.points.size()));
        if (inserted) {
          out.points.push_back(p);
          out.labels.push_back(label);
        }
      }
    }
  }
  return out;
}

struct SessionData {
  Submap submap;
  std::vector<int> labels;
  std::vector<Eigen::Vector3d> origins_world;
};

// One session's submap; robot at x = x_offset, every 0.5 m along y in [-10, 10].
SessionData MakeSession(const Scene& scene, double x_offset, unsigned seed,
                        const Pose3& T_world_submap) {
  SessionData data;
  for (double y = -10.0; y <= 10.0 + 1e-9; y += 0.5) {
    data.origins_world.emplace_back(x_offset, y, 1.5);
  }
  LabelledCloud cloud = Scan(scene, data.origins_world, seed, T_world_submap);
  data.submap.points = std::move(cloud.points);
  data.labels = std::move(cloud.labels);
  for (std::size_t i = 0; i < data.origins_world.size(); ++i) {
    SubmapScanRecord record;
    record.stamp_s = 0.1 * i;
    record.T_submap_sensor = T_world_submap.inverse() * Eigen::Translation3d(data.origins_world[i]);
    data.submap.scans.push_back(record);
  }
  return data;
}

// The history submap has its own frame; the detector gets T_current_history (current = world).
Pose3 HistoryFrame() {
  return Eigen::Translation3d(2.0, -1.0, 0.1) * Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitZ());
}

int CountLabel(const std::vector<int>& labels, const std::vector<std::uint32_t>& indices,
               int label, bool equal) {
  int n = 0;
  for (std::uint32_t i : indices) n += (labels[i] == label) == equal ? 1 : 0;
  return n;
}

int CountLabel(const std::vector<int>& labels, int label) {
  return static_cast<int>(std::count(labels.begin(), labels.end(), label));
}

DynamicDetectionResult RunDetector(const SessionData& history, const SessionData& current,
                           const DynamicDetectionConfig& config) {
  StatusOr<DynamicDetector> detector = DynamicDetector::Create(config);
  EXPECT_TRUE(detector.ok()) << detector.status().message();
  StatusOr<DynamicDetectionResult> result =
      detector.value().Detect(history.submap, current.submap, HistoryFrame());
  EXPECT_TRUE(result.ok()) << result.status().message();
  return result.ok() ? result.value() : DynamicDetectionResult();
}

TEST(DynamicDetectionTest, CarThatLeftIsDynamicAndTheWallBehindItIsMended) {
  const SessionData history = MakeSession(Scene{true}, 0.0, 11, HistoryFrame());
  const SessionData current = MakeSession(Scene{false}, 0.3, 12, Pose3::Identity());
  const DynamicDetectionResult result = RunDetector(history, current, DynamicDetectionConfig());

  const int car_points = CountLabel(history.labels, kCar);
  ASSERT_GT(car_points, 100);
  const int car_found = CountLabel(history.labels, result.history_dynamic, kCar, true);
  const int false_history = CountLabel(history.labels, result.history_dynamic, kCar, false);
  std::printf("car %d/%d found, %d other history points, %zu current points dynamic, %.3f s\n",
              car_found, car_points, false_history, result.current_dynamic.size(),
              result.time_s);
  EXPECT_GE(car_found, 0.95 * car_points);
  EXPECT_LE(false_history, 3);
  EXPECT_LE(result.current_dynamic.size(), 3u);

  // The wall and ground that no history origin could see past the car must be mended: every
  // such point without a history point within mending_distance_m (at the rim of the shadow
  // the history has neighbours, nothing is missing there).
  std::vector<std::uint8_t> mended(current.submap.points.size(), 0);
  for (std::uint32_t i : result.current_mending) mended[i] = 1;
  PointVector history_world;
  for (const Eigen::Vector3d& p : history.submap.points) history_world.push_back(HistoryFrame() * p);
  const double mending_distance_m = DynamicDetectionConfig().mending_distance_m;
  int hidden = 0, hidden_mended = 0;
  for (std::size_t i = 0; i < current.submap.points.size(); ++i) {
    if (current.labels[i] != kWall && current.labels[i] != kGround) continue;
    const Eigen::Vector3d& p = current.submap.points[i];
    bool has_history_neighbour = false;
    for (const Eigen::Vector3d& h : history_world) {
      if ((h - p).squaredNorm() <= mending_distance_m * mending_distance_m) {
        has_history_neighbour = true;
        break;
      }
    }
    if (has_history_neighbour) continue;
    bool seen = false;
    for (const Eigen::Vector3d& o : history.origins_world) {
      if (!SegmentHitsBox(o, p, kCarBox)) {
        seen = true;
        break;
      }
    }
    if (seen) continue;
    ++hidden;
    hidden_mended += mended[i];
  }
  std::printf("hidden wall/ground points: %d, mended %d; mending total %zu\n", hidden,
              hidden_mended, result.current_mending.size());
  ASSERT_GT(hidden, 20);
  EXPECT_GE(hidden_mended, 0.95 * hidden);
}

// A car standing on the ground (its wheels and lower body reach down to it): its points
// within ground_tolerance_m of the ground and without a partner in the other session are taken
// with the object (bottom extension), down to bottom_min_height_m; the ground around it, seen by
// both sessions, stays.
TEST(DynamicDetectionTest, CarThatLeftIsRemovedDownToItsWheels) {
  // Its road-side face at x = 6.6: the -11 deg ring meets it 0.15-0.24 m above the ground (too
  // high for a partner on the other session's ground), the -9 deg ring 0.45 m up.
  Box grounded = kCarBox;
  grounded.lo.x() = 6.6;
  grounded.lo.z() = 0.0;
  const SessionData history = MakeSession(Scene{true, grounded}, 0.0, 11, HistoryFrame());
  const SessionData current = MakeSession(Scene{false}, 0.3, 12, Pose3::Identity());
  DynamicDetectionConfig config;
  config.low_residue_min_ground_points = 0;  // the extension alone (low residue: its own test)
  int low = 0;  // car points below the ground tolerance, too high for a ground partner
  for (std::size_t i = 0; i < history.submap.points.size(); ++i) {
    const double z = (HistoryFrame() * history.submap.points[i]).z();
    low += history.labels[i] == kCar && z >= 0.15 && z < config.ground_tolerance_m;
  }
  ASSERT_GT(low, 20);
  auto found_low = [&](const DynamicDetectionResult& result) {
    int n = 0;
    for (std::uint32_t i : result.history_dynamic) {
      const double z = (HistoryFrame() * history.submap.points[i]).z();
      n += history.labels[i] == kCar && z >= 0.15 && z < config.ground_tolerance_m;
    }
    return n;
  };
  const DynamicDetectionResult with = RunDetector(history, current, config);
  config.bottom_extension_radius_m = 0.0;
  const DynamicDetectionResult without = RunDetector(history, current, config);
  std::printf("low car points %d: found %d with the bottom extension, %d without; ground "
              "removed %d / %d\n",
              low, found_low(with), found_low(without),
              CountLabel(history.labels, with.history_dynamic, kGround, true),
              CountLabel(history.labels, without.history_dynamic, kGround, true));
  // Not all of them: those the common parts grew into from the ground seeds stay (the rule
  // that keeps the ground beside objects; 13 of 31 here are taken, 2 without the extension).
  EXPECT_GE(found_low(with), found_low(without) + 0.3 * low);
  EXPECT_LE(found_low(without), 0.2 * low);
  EXPECT_GE(CountLabel(history.labels, with.history_dynamic, kCar, true),
            CountLabel(history.labels, without.history_dynamic, kCar, true) + 0.3 * low);
  EXPECT_GE(CountLabel(history.labels, with.history_dynamic, kCar, true),
            0.8 * CountLabel(history.labels, kCar));
  EXPECT_LE(CountLabel(history.labels, with.history_dynamic, kCar, false), 3);
  EXPECT_LE(with.current_dynamic.size(), 3u);
}

// What the in-session filter leaves of a pedestrian's feet or a wheel: returns up to 0.22 m
// above the ground, below the ground tolerance, where no ray can see through. The other
// session measured the ground there and has nothing above it: the low residue rule takes
// them. A low object of the same shape in both sessions has partners and stays, and so does a
// long one (a curb the other session did not sample there).
TEST(DynamicDetectionTest, LowResidueGoesWhereTheOtherSessionSawBareGround) {
  DynamicDetectionConfig config;
  // Points of `label` in the band, among `indices` of a session whose submap frame is T.
  auto band = [&](const SessionData& s, const Pose3& T, const std::vector<std::uint32_t>& indices,
                  int label) {
    int n = 0;
    for (std::uint32_t i : indices) {
      const double z = (T * s.submap.points[i]).z();
      n += s.labels[i] == label && z >= config.bottom_min_height_m && z < config.ground_tolerance_m;
    }
    return n;
  };
  auto everything = [](const SessionData& s) {
    std::vector<std::uint32_t> all(s.submap.points.size());
    std::iota(all.begin(), all.end(), 0u);
    return all;
  };
  const Pose3 H = HistoryFrame();
  const Box foot{{6.0, -0.1, 0.0}, {6.2, 0.1, 0.22}};
  const SessionData history = MakeSession(Scene{true, foot}, 0.0, 61, H);
  const SessionData current = MakeSession(Scene{false}, 0.3, 62, Pose3::Identity());
  const int low = band(history, H, everything(history), kCar);
  ASSERT_GE(low, 4);
  config.low_residue_min_ground_points = 0;
  const DynamicDetectionResult off = RunDetector(history, current, config);
  config.low_residue_min_ground_points = 3;
  const DynamicDetectionResult on = RunDetector(history, current, config);
  std::printf("low residue: %d band points, %d taken with the rule, %d without; ground %d\n",
              low, band(history, H, on.history_dynamic, kCar),
              band(history, H, off.history_dynamic, kCar),
              CountLabel(history.labels, on.history_dynamic, kGround, true));
  EXPECT_EQ(band(history, H, off.history_dynamic, kCar), 0);
  EXPECT_GE(band(history, H, on.history_dynamic, kCar), 0.75 * low);
  EXPECT_LE(CountLabel(history.labels, on.history_dynamic, kCar, false),
            CountLabel(history.labels, off.history_dynamic, kCar, false) + 2);
  EXPECT_LE(on.current_dynamic.size(), off.current_dynamic.size() + 2);
  // Out of the rule's range of the other session's path: left alone.
  config.low_residue_range_m = 4.0;
  const DynamicDetectionResult far = RunDetector(history, current, config);
  EXPECT_EQ(band(history, H, far.history_dynamic, kCar), 0);
  config.low_residue_range_m = DynamicDetectionConfig().low_residue_range_m;
  // The same low object in both sessions: partners on both sides, nothing taken.
  const SessionData both_now = MakeSession(Scene{true, foot}, 0.3, 63, Pose3::Identity());
  const DynamicDetectionResult both = RunDetector(history, both_now, config);
  EXPECT_LE(band(history, H, both.history_dynamic, kCar), 1);
  EXPECT_LE(band(both_now, Pose3::Identity(), both.current_dynamic, kCar), 1);
  // A thin post in both sessions: the other session saw the ground all around its foot and
  // the post itself right above it, a partner.
  const Box post{{6.0, -0.05, 0.0}, {6.1, 0.05, 2.0}};
  const SessionData post_then = MakeSession(Scene{true, post}, 0.0, 65, H);
  const SessionData post_now = MakeSession(Scene{false, post}, 0.3, 66, Pose3::Identity());
  const SessionData post_now_too = MakeSession(Scene{true, post}, 0.3, 66, Pose3::Identity());
  const int post_band = band(post_then, H, everything(post_then), kCar);
  ASSERT_GE(post_band, 2);
  const DynamicDetectionResult post_gone = RunDetector(post_then, post_now, config);
  const DynamicDetectionResult post_kept = RunDetector(post_then, post_now_too, config);
  std::printf("post: %d band points, %d taken when it left, %d when it stayed\n", post_band,
              band(post_then, H, post_gone.history_dynamic, kCar),
              band(post_then, H, post_kept.history_dynamic, kCar));
  EXPECT_EQ(band(post_then, H, post_gone.history_dynamic, kCar), post_band);
  EXPECT_EQ(band(post_then, H, post_kept.history_dynamic, kCar), 0);
  EXPECT_EQ(band(post_now_too, Pose3::Identity(), post_kept.current_dynamic, kCar), 0);
  // The other session sampled only the post's upper part (from 0.3 m): still a partner.
  const Box upper_post{{6.0, -0.05, 0.3}, {6.1, 0.05, 2.0}};
  const SessionData upper_now = MakeSession(Scene{true, upper_post}, 0.3, 67, Pose3::Identity());
  EXPECT_EQ(band(post_then, H, RunDetector(post_then, upper_now, config).history_dynamic, kCar),
            0);
  // Fewer ground points of the other session around the foot than the rule asks for: kept.
  config.low_residue_min_ground_points = 50;
  EXPECT_EQ(band(history, H, RunDetector(history, current, config).history_dynamic, kCar), 0);
  config.low_residue_min_ground_points = DynamicDetectionConfig().low_residue_min_ground_points;
  // The same for a foot in the current session, where the history saw bare ground (in the
  // current frame the foot fills 8 voxels of the layer, one more than the blob limit: off).
  const SessionData bare_then = MakeSession(Scene{false}, 0.0, 68, H);
  const SessionData foot_now = MakeSession(Scene{true, foot}, 0.3, 69, Pose3::Identity());
  const int low_now = band(foot_now, Pose3::Identity(), everything(foot_now), kCar);
  ASSERT_GE(low_now, 3);
  config.low_residue_max_own_neighbours = 0;
  const DynamicDetectionResult now = RunDetector(bare_then, foot_now, config);
  config.low_residue_max_own_neighbours = DynamicDetectionConfig().low_residue_max_own_neighbours;
  EXPECT_GE(band(foot_now, Pose3::Identity(), now.current_dynamic, kCar), 0.75 * low_now);
  EXPECT_EQ(now.history_dynamic.size(), 0u);
  // A long low object in the history alone: taken only without the blob limit.
  const Box curb{{6.0, -1.5, 0.0}, {6.4, 1.5, 0.22}};
  const SessionData long_low = MakeSession(Scene{true, curb}, 0.0, 64, H);
  const int long_band = band(long_low, H, everything(long_low), kCar);
  ASSERT_GE(long_band, 15);
  const DynamicDetectionResult limited = RunDetector(long_low, current, config);
  config.low_residue_max_own_neighbours = 0;
  const DynamicDetectionResult unlimited = RunDetector(long_low, current, config);
  std::printf("long low object: %d band points, %d taken with the blob limit, %d without\n",
              long_band, band(long_low, H, limited.history_dynamic, kCar),
              band(long_low, H, unlimited.history_dynamic, kCar));
  EXPECT_LE(band(long_low, H, limited.history_dynamic, kCar), 0.1 * long_band);
  EXPECT_GE(band(long_low, H, unlimited.history_dynamic, kCar), 0.75 * long_band);
}

// The two sessions' grounds are rarely at the same height: the alignment and the odometry's
// height drift inside a submap leave 0.1-0.3 m. Measured against the lower of the two, the
// higher ground rose out of the ground tolerance, and the other session's grazing rays,
// which end on its own lower ground, passed through it: ground "seen through", removed as
// dynamic (on `small`, 17-21 thousand ground points per submap pair, most static losses).
// Each side's height is taken above its own ground.
TEST(DynamicDetectionTest, GroundOfAVerticallyOffsetSessionIsNotDynamic) {
  const SessionData history = MakeSession(Scene{true}, 0.0, 41, HistoryFrame());
  const SessionData current = MakeSession(Scene{false}, 0.3, 42, Pose3::Identity());
  StatusOr<DynamicDetector> detector = DynamicDetector::Create(DynamicDetectionConfig());
  ASSERT_TRUE(detector.ok()) << detector.status().message();
  // The history is placed 0.3 m too high (a vertical alignment error; with the ground of both
  // submaps together 10,577 of its ground points were removed).
  const Pose3 T_current_history = Eigen::Translation3d(0.0, 0.0, 0.3) * HistoryFrame();
  StatusOr<DynamicDetectionResult> result =
      detector.value().Detect(history.submap, current.submap, T_current_history);
  ASSERT_TRUE(result.ok()) << result.status().message();
  const int car_points = CountLabel(history.labels, kCar);
  const int car_found = CountLabel(history.labels, result.value().history_dynamic, kCar, true);
  const int ground_removed =
      CountLabel(history.labels, result.value().history_dynamic, kGround, true);
  std::printf("history 0.3 m high: car %d/%d found, %d ground points dynamic\n", car_found,
              car_points, ground_removed);
  EXPECT_LE(ground_removed, 3);
  EXPECT_GE(car_found, 0.9 * car_points);
}

TEST(DynamicDetectionTest, CarThatArrivedIsDynamicInTheCurrentSubmap) {
  const SessionData history = MakeSession(Scene{false}, 0.0, 21, HistoryFrame());
  const SessionData current = MakeSession(Scene{true}, 0.3, 22, Pose3::Identity());
  const DynamicDetectionResult result = RunDetector(history, current, DynamicDetectionConfig());
  const int car_points = CountLabel(current.labels, kCar);
  const int car_found = CountLabel(current.labels, result.current_dynamic, kCar, true);
  const int false_current = CountLabel(current.labels, result.current_dynamic, kCar, false);
  std::printf("points %zu/%zu\n", history.submap.points.size(), current.submap.points.size());
  std::printf("car %d/%d found, %d other current points, %zu history points dynamic\n",
              car_found, car_points, false_current, result.history_dynamic.size());
  ASSERT_GT(car_points, 100);
  EXPECT_GE(car_found, 0.95 * car_points);
  EXPECT_LE(false_current, 3);
  EXPECT_LE(result.history_dynamic.size(), 3u);
  // The new car is not mending material.
  for (std::uint32_t i : result.current_mending) EXPECT_NE(current.labels[i], kCar);
}

// A car that left, seen by the current session only from 29-31 m (it drives at x = -22): beyond
// max_range_m (25 m) it is not examined; with the far band (far_range_m) it is, and as it has a
// movable object's shape it is removed, with nothing else.
TEST(DynamicDetectionTest, FarCarThatLeftIsDynamicWithTheFarBand) {
  const SessionData history = MakeSession(Scene{true}, 0.0, 41, HistoryFrame());
  const SessionData current = MakeSession(Scene{false}, -22.0, 42, Pose3::Identity());
  const int car_points = CountLabel(history.labels, kCar);
  ASSERT_GT(car_points, 100);
  DynamicDetectionConfig near_only;
  near_only.far_range_m = 0.0;
  ASSERT_LT(near_only.max_range_m, 29.0);
  const DynamicDetectionResult without = RunDetector(history, current, near_only);
  DynamicDetectionConfig far = near_only;
  far.far_range_m = 40.0;
  const DynamicDetectionResult with = RunDetector(history, current, far);
  const int found_without = CountLabel(history.labels, without.history_dynamic, kCar, true);
  const int found_with = CountLabel(history.labels, with.history_dynamic, kCar, true);
  const int false_with = CountLabel(history.labels, with.history_dynamic, kCar, false);
  std::printf("far car %d/%d found without the far band, %d with it; %d other history and %zu "
              "current points dynamic, %zu mended\n",
              found_without, car_points, found_with, false_with, with.current_dynamic.size(),
              with.current_mending.size());
  EXPECT_EQ(found_without, 0);
  EXPECT_GE(found_with, 0.8 * car_points);
  EXPECT_LE(false_with, 3);
  EXPECT_LE(with.current_dynamic.size(), 3u);
  // The far band is never mending material: the mended points are those of the near band.
  EXPECT_EQ(with.current_mending, without.current_mending);
  // A far detection must have a movable object's shape: with a largest extent shorter than
  // the car the same detection is refused.
  DynamicDetectionConfig small_objects = far;
  small_objects.changed_max_extent_m = 1.0;
  const DynamicDetectionResult refused = RunDetector(history, current, small_objects);
  EXPECT_EQ(CountLabel(history.labels, refused.history_dynamic, kCar, true), 0);
}

// A parking place taken by another car in the current session: 0.3 m shorter, 0.4 m further
// along the street, 0.15 m taller, 0.1 m further from the road. Neither session sees through
// the other's car and their road-side faces are 0.1 m apart (common by d_beta), so the
// free-space steps find almost nothing; the changed-object step compares the surfaces.
TEST(DynamicDetectionTest, AnotherCarInTheSamePlaceIsDynamicInBothSubmaps) {
  Scene other_car{true};
  other_car.car_box = Box{{7.3, -1.45, 0.25}, {9.1, 2.75, 1.75}};
  const SessionData history = MakeSession(Scene{true}, 0.0, 51, HistoryFrame());
  const SessionData current = MakeSession(other_car, 0.3, 52, Pose3::Identity());
  const int history_car = CountLabel(history.labels, kCar);
  const int current_car = CountLabel(current.labels, kCar);
  ASSERT_GT(history_car, 100);
  ASSERT_GT(current_car, 100);

  DynamicDetectionConfig without;
  without.changed_objects_enabled = false;
  const DynamicDetectionResult free_space = RunDetector(history, current, without);
  const int history_found_without =
      CountLabel(history.labels, free_space.history_dynamic, kCar, true);
  const int current_found_without =
      CountLabel(current.labels, free_space.current_dynamic, kCar, true);

  const DynamicDetectionResult result = RunDetector(history, current, DynamicDetectionConfig());
  const int history_found = CountLabel(history.labels, result.history_dynamic, kCar, true);
  const int current_found = CountLabel(current.labels, result.current_dynamic, kCar, true);
  std::printf("history car %d/%d (%d without the step), current car %d/%d (%d without); other "
              "points dynamic: %d / %d\n",
              history_found, history_car, history_found_without, current_found, current_car,
              current_found_without,
              CountLabel(history.labels, result.history_dynamic, kCar, false),
              CountLabel(current.labels, result.current_dynamic, kCar, false));
  for (const auto& object : result.examined_objects) {
    std::printf("  examined side %d: %zu points, %d/%d off%s\n", object.side,
                object.points.size(), object.off_surface, object.compared,
                object.changed ? " changed" : "");
  }
  EXPECT_LT(history_found_without, 0.5 * history_car);  // the case the step is for
  EXPECT_GE(history_found, 0.95 * history_car);
  EXPECT_GE(current_found, 0.95 * current_car);
  EXPECT_LE(CountLabel(history.labels, result.history_dynamic, kCar, false), 3);
  EXPECT_LE(CountLabel(current.labels, result.current_dynamic, kCar, false), 3);
  // Neither car is mending material.
  for (std::uint32_t i : result.current_mending) EXPECT_NE(current.labels[i], kCar);
}

// A shorter car in the slot of a longer one: the longer car's free end makes it changed by its
// own comparison, while most of the shorter car lies on the longer one's surfaces. As the
// partner of a changed object it is changed too, but only when it contradicts the other
// session for at least changed_partner_min_fraction of its compared points.
TEST(DynamicDetectionTest, ShorterCarInTheSlotOfAChangedCarIsItsPartner) {
  Scene shorter{true};
  shorter.car_box = Box{{7.25, -2.25, 0.25}, {9.0, 0.25, 1.5}};
  const SessionData history = MakeSession(Scene{true}, 0.0, 71, HistoryFrame());
  const SessionData current = MakeSession(shorter, 0.3, 72, Pose3::Identity());
  auto car_object = [&](const DynamicDetectionResult& result, int side) {
    const DynamicDetectionResult::ExaminedObject* best = nullptr;
    int best_car = 0;
    for (const auto& object : result.examined_objects) {
      if (object.side != side) continue;
      const int car = CountLabel(side == 0 ? history.labels : current.labels, object.points,
                                 kCar, true);
      if (car > best_car) best_car = car, best = &object;
    }
    return best;
  };
  DynamicDetectionConfig off;
  off.changed_partner_min_fraction = off.changed_min_fraction;  // the rule is off
  const DynamicDetectionResult alone = RunDetector(history, current, off);
  const auto* longer_car = car_object(alone, 0);
  const auto* shorter_car = car_object(alone, 1);
  ASSERT_NE(longer_car, nullptr);
  ASSERT_NE(shorter_car, nullptr);
  const double fraction =
      static_cast<double>(shorter_car->off_surface) / std::max(1, shorter_car->compared);
  std::printf("longer car %d/%d off%s, shorter car %d/%d off (%.3f)%s\n",
              longer_car->off_surface, longer_car->compared, longer_car->changed ? " changed" : "",
              shorter_car->off_surface, shorter_car->compared, fraction,
              shorter_car->changed ? " changed" : "");
  // The case the rule is for: one side changed, its partner below the threshold but not zero.
  ASSERT_TRUE(longer_car->changed);
  ASSERT_FALSE(shorter_car->changed);
  ASSERT_GE(shorter_car->compared, off.changed_min_compared);
  ASSERT_GT(fraction, 0.02);
  ASSERT_LT(fraction + 0.02, off.changed_min_fraction);  // else the control below is the off rule
  const int shorter_points = CountLabel(current.labels, kCar);
  EXPECT_LT(CountLabel(current.labels, alone.current_dynamic, kCar, true), 0.5 * shorter_points);

  DynamicDetectionConfig partner = off;
  partner.changed_partner_min_fraction = fraction - 0.02;
  const DynamicDetectionResult with = RunDetector(history, current, partner);
  const auto* found = car_object(with, 1);
  ASSERT_NE(found, nullptr);
  EXPECT_TRUE(found->changed);
  EXPECT_TRUE(found->by_partner);
  EXPECT_GE(CountLabel(current.labels, with.current_dynamic, kCar, true), 0.9 * shorter_points);
  EXPECT_LE(CountLabel(current.labels, with.current_dynamic, kCar, false), 3);
  // The longer car is changed by itself, not by the rule.
  const auto* longer_with = car_object(with, 0);
  ASSERT_NE(longer_with, nullptr);
  EXPECT_FALSE(longer_with->by_partner);

  partner.changed_partner_min_fraction = fraction + 0.02;  // it agrees too well: stays
  const DynamicDetectionResult strict = RunDetector(history, current, partner);
  const auto* shorter_strict = car_object(strict, 1);
  ASSERT_NE(shorter_strict, nullptr);
  EXPECT_FALSE(shorter_strict->changed);
}

// Another car in the slot with its long sides where the first car's were: 0.3 m further
// along the street at one end and 0.25 m shorter at the other. The sides, most of either car,
// agree; only the ends contradict, too few for changed_min_fraction. With the end rule (the
// default) both cars are changed, by their ends.
TEST(DynamicDetectionTest, AnotherCarWithItsEndsElsewhereIsChangedByItsEnds) {
  Scene other_car{true};
  other_car.car_box = Box{{7.2, -2.55, 0.25}, {9.0, 2.0, 1.6}};
  const SessionData history = MakeSession(Scene{true}, 0.0, 81, HistoryFrame());
  const SessionData current = MakeSession(other_car, 0.3, 82, Pose3::Identity());
  const int history_car = CountLabel(history.labels, kCar);
  const int current_car = CountLabel(current.labels, kCar);
  ASSERT_GT(history_car, 100);
  ASSERT_GT(current_car, 100);
  DynamicDetectionConfig with;  // the defaults: the rule on
  ASSERT_GT(with.changed_end_min_compared, 0);
  DynamicDetectionConfig without = with;
  without.changed_end_min_compared = 0;
  std::array<int, 2> found_without{}, found_with{};
  for (const DynamicDetectionConfig* config : {&without, &with}) {
    const DynamicDetectionResult result = RunDetector(history, current, *config);
    std::array<int, 2>& found = config == &with ? found_with : found_without;
    found[0] = CountLabel(history.labels, result.history_dynamic, kCar, true);
    found[1] = CountLabel(current.labels, result.current_dynamic, kCar, true);
    for (const auto& object : result.examined_objects) {
      std::printf("  %s, examined side %d: %zu points, %d/%d off, ends %d/%d and %d/%d%s\n",
                  config == &with ? "with" : "without", object.side, object.points.size(),
                  object.off_surface, object.compared, object.end_off[0],
                  object.end_compared[0], object.end_off[1], object.end_compared[1],
                  object.changed ? " changed" : "");
    }
    EXPECT_LE(CountLabel(history.labels, result.history_dynamic, kCar, false), 3);
    EXPECT_LE(CountLabel(current.labels, result.current_dynamic, kCar, false), 3);
  }
  std::printf("history car %d/%d (%d without the rule), current car %d/%d (%d without)\n",
              found_with[0], history_car, found_without[0], found_with[1], current_car,
              found_without[1]);
  EXPECT_LT(found_without[0], 0.5 * history_car);  // the case the rule is for
  EXPECT_LT(found_without[1], 0.5 * current_car);
  EXPECT_GE(found_with[0], 0.95 * history_car);
  EXPECT_GE(found_with[1], 0.95 * current_car);
}

// The same car in both sessions (sampled from other places, different noise) is static, and
// it was examined (not just skipped as too small or too far).
TEST(DynamicDetectionTest, TheSameCarInBothSessionsIsStatic) {
  const SessionData history = MakeSession(Scene{true}, 0.0, 61, HistoryFrame());
  const SessionData current = MakeSession(Scene{true}, 0.3, 62, Pose3::Identity());
  DynamicDetectionConfig no_ends;  // also without the end rule of changed objects
  no_ends.changed_end_min_compared = 0;
  for (const DynamicDetectionConfig& config : {DynamicDetectionConfig(), no_ends}) {
    const DynamicDetectionResult result = RunDetector(history, current, config);
    int car_objects = 0;
    for (const auto& object : result.examined_objects) {
      const std::vector<int>& labels = object.side == 0 ? history.labels : current.labels;
      const int car = CountLabel(labels, object.points, kCar, true);
      std::printf("  examined side %d: %zu points (%d car), %d/%d off%s\n", object.side,
                  object.points.size(), car, object.off_surface, object.compared,
                  object.changed ? " changed" : "");
      if (car > 0.9 * object.points.size() && object.compared > 50) ++car_objects;
    }
    EXPECT_EQ(car_objects, 2);
    EXPECT_LE(CountLabel(history.labels, result.history_dynamic, kCar, true), 3);
    EXPECT_LE(CountLabel(current.labels, result.current_dynamic, kCar, true), 3);
  }
}

// The same car seen from its two sides: the history drove between the car and the wall, the
// current session on the road. Each session's rays pass voxels of the side only the other saw
// (its edges and top), and the free-space detection takes parts of the car; the
// changed-object step finds a quarter of the compared points off the other session's
// surfaces (the side it did not see), not enough for a change, and with
// changed_same_max_fraction the car keeps its points.
TEST(DynamicDetectionTest, TheSameCarSeenFromItsTwoSidesKeepsItsPoints) {
  const SessionData history = MakeSession(Scene{true}, 10.5, 63, HistoryFrame());
  const SessionData current = MakeSession(Scene{true}, 0.3, 64, Pose3::Identity());
  DynamicDetectionConfig off;
  DynamicDetectionConfig same = off;
  same.changed_same_max_fraction = 0.3;
  const DynamicDetectionResult without = RunDetector(history, current, off);
  const DynamicDetectionResult with = RunDetector(history, current, same);
  for (const auto& object : with.examined_objects) {
    const std::vector<int>& labels = object.side == 0 ? history.labels : current.labels;
    std::printf("  examined side %d: %zu points (%d car), %d/%d off%s\n", object.side,
                object.points.size(), CountLabel(labels, object.points, kCar, true),
                object.off_surface, object.compared, object.changed ? " changed" : "");
  }
  const int history_car = CountLabel(history.labels, kCar);
  const int current_car = CountLabel(current.labels, kCar);
  std::printf("  car points dynamic without / with the rule: history %d / %d of %d, current "
              "%d / %d of %d\n",
              CountLabel(history.labels, without.history_dynamic, kCar, true),
              CountLabel(history.labels, with.history_dynamic, kCar, true), history_car,
              CountLabel(current.labels, without.current_dynamic, kCar, true),
              CountLabel(current.labels, with.current_dynamic, kCar, true), current_car);
  // Without the rule the detection takes a fifth of the history's car (at least a tenth is
  // required here) and some of the current's; with it none.
  EXPECT_GE(CountLabel(history.labels, without.history_dynamic, kCar, true), history_car / 10);
  EXPECT_GE(CountLabel(current.labels, without.current_dynamic, kCar, true), 10);
  EXPECT_EQ(CountLabel(history.labels, with.history_dynamic, kCar, true), 0);
  EXPECT_EQ(CountLabel(current.labels, with.current_dynamic, kCar, true), 0);
  // Nothing else changes: the rule only keeps points of examined objects found the same.
  EXPECT_EQ(CountLabel(history.labels, with.history_dynamic, kCar, false),
            CountLabel(history.labels, without.history_dynamic, kCar, false));
  EXPECT_EQ(CountLabel(current.labels, with.current_dynamic, kCar, false),
            CountLabel(current.labels, without.current_dynamic, kCar, false));
  // At 0.2 the car (a quarter of its compared points off) is not the same: it keeps losing
  // what the free-space detection takes.
  DynamicDetectionConfig strict = off;
  strict.changed_same_max_fraction = 0.2;
  const DynamicDetectionResult with_strict = RunDetector(history, current, strict);
  EXPECT_EQ(with_strict.history_dynamic, without.history_dynamic);
  EXPECT_EQ(with_strict.current_dynamic, without.current_dynamic);
}

TEST(DynamicDetectionTest, PorousCanopyIsNotDynamicWithoutTheHeightGuard) {
  const SessionData history = MakeSession(Scene{false}, 0.0, 31, HistoryFrame());
  const SessionData current = MakeSession(Scene{false}, 0.3, 32, Pose3::Identity());
  ASSERT_GT(CountLabel(history.labels, kCanopy), 300);
  DynamicDetectionConfig config;
  config.height_guard_enabled = false;
  const DynamicDetectionResult result = RunDetector(history, current, config);
  std::printf("canopy points %d/%d, dynamic %zu/%zu\n", CountLabel(history.labels, kCanopy),
              CountLabel(current.labels, kCanopy), result.history_dynamic.size(),
              result.current_dynamic.size());
  EXPECT_TRUE(result.history_dynamic.empty());
  EXPECT_TRUE(result.current_dynamic.empty());

  // Control: with the consistency checks weakened to the plain method (any passing ray, no
  // support test, no cluster size, no ground rule), the same canopy does produce detections, so the scene
  // really exercises the porous-canopy failure.
  DynamicDetectionConfig plain = config;
  plain.min_passing_rays = 1;
  plain.max_support_points = 1000000;
  plain.min_cluster_points = 1;
  plain.min_cluster_coarse_points = 1;
  plain.max_object_bottom_m = 0.0;
  const DynamicDetectionResult weak = RunDetector(history, current, plain);
  const int canopy_weak = CountLabel(history.labels, weak.history_dynamic, kCanopy, true) +
                          CountLabel(current.labels, weak.current_dynamic, kCanopy, true);
  std::printf("plain method: %d canopy points dynamic\n", canopy_weak);
  EXPECT_GT(canopy_weak, 10);
}

// Scan origins of a hand-made submap: along y at x = 0, every 0.5 m, at height z [m].
void AddOriginsAlongY(double z, Submap* submap) {
  for (double y = -6.0; y <= 6.0 + 1e-9; y += 0.5) {
    SubmapScanRecord record;
    record.T_submap_sensor = Pose3(Eigen::Translation3d(0.0, y, z));
    submap->scans.push_back(record);
  }
}

// A hand-made street: ground at z = 0 up to x = ground_end_m and a wall at x = 12 from 0.2 m
// up to wall_top_m, every 0.2 m.
void AddStreet(double wall_top_m, PointVector* out, double ground_end_m = 11.8) {
  for (double x = -2.0; x <= ground_end_m + 1e-9; x += 0.2) {
    for (double y = -6.0; y <= 6.0 + 1e-9; y += 0.2) out->emplace_back(x, y, 0.0);
  }
  for (double y = -6.0; y <= 6.0 + 1e-9; y += 0.2) {
    for (double z = 0.2; z <= wall_top_m + 1e-9; z += 0.2) out->emplace_back(12.0, y, z);
  }
}

// A far parked car is crossed by the other session's rays mostly low, under its roof (rays to
// the ground and walls behind it), not through the voxels of the surface that its own session
// saw. Hand-made submaps: the history saw only a roof (2 x 2 m at 1.4 m, from a high sensor)
// and the ground around it; the current session, with a low sensor, saw the ground under the
// roof and a low wall behind it, through the place under the roof.
TEST(DynamicDetectionTest, RoofIsDynamicWhenTheOtherSessionSawThroughTheSpaceBelowIt) {
  auto grid = [](double x0, double x1, double y0, double y1, double z, bool skip_roof,
                 PointVector* out) {
    for (double x = x0; x <= x1 + 1e-9; x += 0.2) {
      for (double y = y0; y <= y1 + 1e-9; y += 0.2) {
        if (skip_roof && x > 6.9 && x < 9.1 && y > -1.1 && y < 1.1) continue;
        out->emplace_back(x, y, z);
      }
    }
  };
  auto wall = [](PointVector* out) {  // a 1 m wall behind the roof, seen by both sessions
    for (double y = -6.0; y <= 6.0 + 1e-9; y += 0.2) {
      for (double z = 0.2; z <= 1.0 + 1e-9; z += 0.2) out->emplace_back(12.0, y, z);
    }
  };
  Submap history, current;
  grid(-2.0, 11.8, -6.0, 6.0, 0.0, true, &history.points);  // ground, hidden under the roof
  wall(&history.points);
  const std::size_t roof_begin = history.points.size();
  grid(7.0, 9.0, -1.0, 1.0, 1.4, false, &history.points);
  const std::size_t roof_points = history.points.size() - roof_begin;
  AddOriginsAlongY(3.0, &history);
  grid(-2.0, 11.8, -6.0, 6.0, 0.0, false, &current.points);  // ground, also under the roof
  wall(&current.points);
  AddOriginsAlongY(1.0, &current);

  auto roof_found = [&](const DynamicDetectionConfig& config) {
    StatusOr<DynamicDetector> detector = DynamicDetector::Create(config);
    EXPECT_TRUE(detector.ok());
    StatusOr<DynamicDetectionResult> result =
        detector.value().Detect(history, current, Pose3::Identity());
    EXPECT_TRUE(result.ok());
    int roof = 0, other = 0;
    for (std::uint32_t i : result.value().history_dynamic) (i >= roof_begin ? roof : other)++;
    EXPECT_EQ(other, 0);
    EXPECT_TRUE(result.value().current_dynamic.empty());
    return roof;
  };
  const int with_columns = roof_found(DynamicDetectionConfig());
  DynamicDetectionConfig voxel_only;
  voxel_only.free_column_depth_m = 0.0;
  const int without = roof_found(voxel_only);
  std::printf("roof points %zu: dynamic %d with free columns, %d with the voxel test only\n",
              roof_points, with_columns, without);
  EXPECT_GE(with_columns, 0.9 * roof_points);
  EXPECT_EQ(without, 0);  // no ray of the current session passes through the roof's voxels
}

// A low wall (a garden wall, a hedge) that the current session sees 0.25 m off (as a far
// surface's alignment error puts it), from origins at x = 0, y in [-1, 1]. Only the part within
// changed_compare_range_m of both sessions' origins is compared by the changed-object step.
// Of a 30 m wall that part is about 8 m long: car-sized. The shape is judged on the whole
// object, so the long wall is neither examined nor dynamic, while a wall that really is
// 8 m long (the control) is a changed object: the comparison itself does flag it.
struct LowWallPair {
  Submap history, current;
  std::vector<int> history_labels, current_labels;  // kGround / kWall
};

// lift_m raises the wall off the ground, and the ground ends ground_gap_m before it.
LowWallPair MakeLowWallPair(double half_length_m, double lift_m = 0.0,
                            double ground_gap_m = 0.2) {
  LowWallPair pair;
  const auto make = [&](double wall_x, Submap* submap, std::vector<int>* labels) {
    for (double x = -2.0; x <= wall_x - ground_gap_m + 1e-9; x += 0.2) {
      for (double y = -16.0; y <= 16.0 + 1e-9; y += 0.2) {
        submap->points.emplace_back(x, y, 0.0);
        labels->push_back(kGround);
      }
    }
    for (double y = -half_length_m; y <= half_length_m + 1e-9; y += 0.2) {
      for (double z = 0.2; z <= 1.4 + 1e-9; z += 0.2) {
        submap->points.emplace_back(wall_x, y, z + lift_m);
        labels->push_back(kWall);
      }
    }
    for (double y = -1.0; y <= 1.0 + 1e-9; y += 0.5) {
      SubmapScanRecord record;
      record.T_submap_sensor = Pose3(Eigen::Translation3d(0.0, y, 1.8));
      submap->scans.push_back(record);
    }
  };
  make(10.0, &pair.history, &pair.history_labels);
  make(10.25, &pair.current, &pair.current_labels);
  return pair;
}

TEST(DynamicDetectionTest, LongLowWallCutByTheCompareRangeIsNoChangedObject) {
  DynamicDetectionConfig config;
  config.changed_compare_range_m = 10.5;
  StatusOr<DynamicDetector> detector = DynamicDetector::Create(config);
  ASSERT_TRUE(detector.ok()) << detector.status().message();
  // The long wall's cut by the range has a movable object's extent (the case of the test).
  const LowWallPair long_wall = MakeLowWallPair(15.0);
  double y_lo = 1e9, y_hi = -1e9;
  for (std::size_t i = 0; i < long_wall.history.points.size(); ++i) {
    const Eigen::Vector3d& p = long_wall.history.points[i];
    if (long_wall.history_labels[i] != kWall || p.z() < config.ground_tolerance_m) continue;
    for (const SubmapScanRecord& scan : long_wall.history.scans) {
      if ((p - scan.T_submap_sensor.translation()).norm() <= config.changed_compare_range_m) {
        y_lo = std::min(y_lo, p.y());
        y_hi = std::max(y_hi, p.y());
      }
    }
  }
  ASSERT_GT(y_hi - y_lo, 4.0);
  ASSERT_LT(y_hi - y_lo, config.changed_max_extent_m);

  StatusOr<DynamicDetectionResult> result =
      detector.value().Detect(long_wall.history, long_wall.current, Pose3::Identity());
  ASSERT_TRUE(result.ok()) << result.status().message();
  EXPECT_EQ(CountLabel(long_wall.history_labels, result.value().history_dynamic, kWall, true), 0);
  EXPECT_EQ(CountLabel(long_wall.current_labels, result.value().current_dynamic, kWall, true), 0);
  for (const auto& object : result.value().examined_objects) {
    const auto& labels = object.side == 0 ? long_wall.history_labels : long_wall.current_labels;
    EXPECT_EQ(CountLabel(labels, object.points, kWall, true), 0) << "the long wall was examined";
  }

  // Control: a wall as long as that cut is examined and changed on both sides.
  const LowWallPair short_wall = MakeLowWallPair(0.5 * (y_hi - y_lo));
  result = detector.value().Detect(short_wall.history, short_wall.current, Pose3::Identity());
  ASSERT_TRUE(result.ok()) << result.status().message();
  EXPECT_GE(CountLabel(short_wall.history_labels, result.value().history_dynamic, kWall, true),
            0.5 * CountLabel(short_wall.history_labels, kWall));
  EXPECT_GT(CountLabel(short_wall.current_labels, result.value().current_dynamic, kWall, true),
            0);
}

// Seen from afar, the lower part of a tree crown can have no measured ground under it: its own
// lowest points are then its local ground and a fragment of the crown passes for a car-sized
// object standing on the ground, which the crowns' day-to-day scatter makes changed. Here a
// 4 m wall like the control above, lifted 2.5 m, with the ground ending 2 m before it, in the
// far band (max_range_m 8 m, the wall 10 m away): with far_ground_cell_m off it is examined
// and changed; with the rule on it is not examined, while the same wall on the ground still
// is and is changed, and so is the lifted wall in the near band (the rule is the far band's).
TEST(DynamicDetectionTest, FarObjectAboveTheGroundAroundItIsNoChangedObject) {
  const auto examined_wall = [](const LowWallPair& pair, const DynamicDetectionConfig& config,
                                bool* changed) {
    StatusOr<DynamicDetector> detector = DynamicDetector::Create(config);
    EXPECT_TRUE(detector.ok()) << detector.status().message();
    StatusOr<DynamicDetectionResult> result =
        detector.value().Detect(pair.history, pair.current, Pose3::Identity());
    EXPECT_TRUE(result.ok()) << result.status().message();
    int points = 0;
    *changed = false;
    for (const auto& object : result.value().examined_objects) {
      const auto& labels = object.side == 0 ? pair.history_labels : pair.current_labels;
      const int wall = CountLabel(labels, object.points, kWall, true);
      points += wall;
      *changed = *changed || (wall > 0 && object.changed);
    }
    return points;
  };
  DynamicDetectionConfig near;
  near.far_ground_cell_m = 2.0;
  near.far_max_bottom_m = 1.2;
  DynamicDetectionConfig on = near;
  on.max_range_m = 8.0;
  DynamicDetectionConfig off = on;
  off.far_ground_cell_m = 0.0;
  const LowWallPair lifted = MakeLowWallPair(2.0, 2.5, 2.0);
  const LowWallPair standing = MakeLowWallPair(2.0, 0.0, 2.0);
  bool changed = false;
  EXPECT_GT(examined_wall(lifted, off, &changed), 0);
  EXPECT_TRUE(changed) << "the lifted wall must be a changed object without the rule";
  EXPECT_EQ(examined_wall(lifted, on, &changed), 0);
  EXPECT_GT(examined_wall(lifted, near, &changed), 0);
  EXPECT_TRUE(changed);
  EXPECT_GT(examined_wall(standing, on, &changed), 0);
  EXPECT_TRUE(changed);
  // The bound, on the object's lowest point out of the ground tolerance of its own local
  // ground (the wall's third row, 0.4 m above its lowest): lifted 0.5 m, that point is 1.1 m
  // above the ground around it and the wall is examined; lifted 0.7 m, 1.3 m, it is not.
  EXPECT_GT(examined_wall(MakeLowWallPair(2.0, 0.5, 2.0), on, &changed), 0);
  EXPECT_EQ(examined_wall(MakeLowWallPair(2.0, 0.7, 2.0), on, &changed), 0);
}

// A truck that left: its side (0.4-3.2 m high, facing the road) was seen through by the other
// session only low, under 1 m; above the 2 m height guard its points are no seeds but belong
// to the object grown from below, up to guard_object_height_m.
TEST(DynamicDetectionTest, TallObjectIsRemovedAboveTheGuardUpToTheObjectHeight) {
  Submap history, current;
  AddStreet(1.0, &history.points);
  const std::size_t truck_begin = history.points.size();
  for (double y = -2.0; y <= 2.0 + 1e-9; y += 0.2) {
    for (double z = 0.4; z <= 3.2 + 1e-9; z += 0.2) history.points.emplace_back(8.0, y, z);
  }
  AddOriginsAlongY(3.0, &history);
  AddStreet(1.0, &current.points);
  AddOriginsAlongY(1.0, &current);

  // Truck points found below / above the guard.
  auto found = [&](const DynamicDetectionConfig& config, int* low, int* high) {
    StatusOr<DynamicDetector> detector = DynamicDetector::Create(config);
    ASSERT_TRUE(detector.ok());
    StatusOr<DynamicDetectionResult> result =
        detector.value().Detect(history, current, Pose3::Identity());
    ASSERT_TRUE(result.ok());
    *low = *high = 0;
    for (std::uint32_t i : result.value().history_dynamic) {
      ASSERT_GE(i, truck_begin);  // nothing but the truck
      (history.points[i].z() > config.height_guard_m ? *high : *low)++;
    }
  };
  const int truck_points = static_cast<int>(history.points.size() - truck_begin);
  int low = 0, high = 0;
  found(DynamicDetectionConfig(), &low, &high);
  std::printf("truck side %d points: %d at or below the guard, %d above found\n", truck_points,
              low, high);
  EXPECT_EQ(low + high, truck_points);
  EXPECT_EQ(high, 6 * 21);  // rows 2.2 .. 3.2 m of 21 points
  DynamicDetectionConfig plain_guard;
  plain_guard.guard_object_height_m = plain_guard.height_guard_m;
  found(plain_guard, &low, &high);
  std::printf("plain guard: %d at or below, %d above found\n", low, high);
  EXPECT_EQ(low + high, truck_points - 6 * 21);
  EXPECT_EQ(high, 0);
}

// Without the height guard, something the other session saw through that floats above the
// ground (a porous tree crown, the upper part of a facade) must not become dynamic: movable
// objects stand on the ground. Hand-made submaps: the history saw a 2 x 2 m patch at
// 2.6-3.4 m with nothing below it, the current session saw the tall wall behind it through
// that space. The same patch at car height (0.4-1.2 m) is a removed object.
// A floating patch: the history saw the street (AddStreet with a 4 m wall, its ground up to
// ground_end_m) and a 2 x 0.8 m patch at x = 8 m from bottom_m up; the current session saw the
// street alone, its wall through the patch's place; both from sensors 3 m up. Returns the
// history's dynamic points; *patch_begin is the index of the patch's first point.
std::vector<std::uint32_t> FloatingPatchDynamic(double bottom_m, double ground_end_m,
                                                const DynamicDetectionConfig& config,
                                                std::size_t* patch_begin) {
  Submap history, current;
  AddStreet(4.0, &history.points, ground_end_m);
  *patch_begin = history.points.size();
  for (double y = -1.0; y <= 1.0 + 1e-9; y += 0.2) {
    for (double z = bottom_m; z <= bottom_m + 0.8 + 1e-9; z += 0.2) {
      history.points.emplace_back(8.0, y, z);
    }
  }
  AddOriginsAlongY(3.0, &history);
  AddStreet(4.0, &current.points, ground_end_m);
  AddOriginsAlongY(3.0, &current);
  StatusOr<DynamicDetector> detector = DynamicDetector::Create(config);
  EXPECT_TRUE(detector.ok()) << detector.status().message();
  if (!detector.ok()) return {};
  StatusOr<DynamicDetectionResult> result =
      detector.value().Detect(history, current, Pose3::Identity());
  EXPECT_TRUE(result.ok()) << result.status().message();
  if (!result.ok()) return {};
  return result.value().history_dynamic;
}

TEST(DynamicDetectionTest, FloatingObjectIsNotDynamicWithoutTheHeightGuard) {
  // Patch points of the history found dynamic (anything else found fails the test).
  auto patch_found = [&](double bottom_m, const DynamicDetectionConfig& config, int* patch) {
    std::size_t patch_begin = 0;
    const std::vector<std::uint32_t> dynamic =
        FloatingPatchDynamic(bottom_m, 11.8, config, &patch_begin);
    for (std::uint32_t i : dynamic) ASSERT_GE(i, patch_begin);
    *patch = static_cast<int>(dynamic.size());
  };
  constexpr int kPatchPoints = 11 * 5;
  DynamicDetectionConfig config;
  config.height_guard_enabled = false;
  ASSERT_GT(config.max_object_bottom_m, 0.0);
  DynamicDetectionConfig no_ground_rule = config;
  no_ground_rule.max_object_bottom_m = 0.0;
  int high = 0, high_plain = 0, low = 0;
  patch_found(2.6, config, &high);
  patch_found(2.6, no_ground_rule, &high_plain);
  patch_found(0.4, config, &low);
  std::printf("patch of %d points: floating %d found (%d without the rule), at car height %d\n",
              kPatchPoints, high, high_plain, low);
  EXPECT_EQ(high, 0);
  EXPECT_GE(high_plain, 0.9 * kPatchPoints);  // the scene does exercise the floating case
  EXPECT_GE(low, 0.9 * kPatchPoints);
}

// The far band's ground around an object, for the free-space detection: a 2 x 0.8 m patch
// floating 2.6 m up, 8 m away in the far band (max_range_m 6 m), with the ground measured only
// up to 6.8 m (its local ground is its own lowest points, as under a crown seen from afar). The
// current session sees the wall behind it through it. Without the rule the patch is a far
// detection of a movable object's shape; with it, it is not; the same patch 0.4 m up still
// is (the ground around it is the street's).
TEST(DynamicDetectionTest, FarPatchAboveTheGroundAroundItIsNotDynamic) {
  const auto patch_found = [](double bottom_m, const DynamicDetectionConfig& config) {
    std::size_t patch_begin = 0;
    int patch = 0;
    for (std::uint32_t i : FloatingPatchDynamic(bottom_m, 6.8, config, &patch_begin)) {
      patch += i >= patch_begin;
    }
    return patch;
  };
  DynamicDetectionConfig on;
  on.max_range_m = 6.0;
  on.low_residue_range_m = 5.0;
  on.far_ground_cell_m = 2.0;
  on.far_max_bottom_m = 1.2;
  DynamicDetectionConfig off = on;
  off.far_ground_cell_m = 0.0;
  const int floating_off = patch_found(2.6, off), floating_on = patch_found(2.6, on);
  const int standing_on = patch_found(0.4, on);
  std::printf("far patch of 55 points: floating %d found without the rule, %d with it; 0.4 m "
              "up %d with it\n", floating_off, floating_on, standing_on);
  // At least 4 of the patch's 5 rows of 11 points (its lowest row floating is ground to its
  // own local ground).
  EXPECT_GE(floating_off, 44);  // the scene does exercise the far floating case
  EXPECT_EQ(floating_on, 0);
  EXPECT_GE(standing_on, 44);
}

// Step 2 grows the common parts over whole surfaces: a wall that the history saw only in
// part (y <= 0) and the current session saw to y = 2.9 m is one surface, so the current's rest
// of it joins the common part through the chain of compatible neighbours, also where no
// history point is within a seed's reach (seed distance + grow radius: y > 0.45 m; the wall
// starts 0.7 m above the ground, beyond that reach of the history's ground).
TEST(DynamicDetectionTest, CommonPartsGrowOverTheWholeOfASurface) {
  const auto make = [](double wall_end_y) {
    Submap submap;
    for (double x = 0.0; x <= 8.0 + 1e-9; x += 0.1) {
      for (double y = -5.0; y <= 5.0 + 1e-9; y += 0.1) submap.points.emplace_back(x, y, 0.0);
    }
    // (A last column alone in its 0.6 m normal voxel would be a line, not a plane.)
    for (int column = 0; -3.0 + 0.1 * column <= wall_end_y + 1e-9; ++column) {
      for (int row = 0; row <= 13; ++row) {
        submap.points.emplace_back(6.05, -3.0 + 0.1 * column, 0.7 + 0.1 * row);
      }
    }
    for (double y = -3.0; y <= 3.0 + 1e-9; y += 1.0) {
      SubmapScanRecord record;
      record.T_submap_sensor = Pose3(Eigen::Translation3d(0.0, y, 1.5));
      submap.scans.push_back(record);
    }
    return submap;
  };
  const Submap history = make(0.0);
  const Submap current = make(2.9);
  StatusOr<DynamicDetector> detector = DynamicDetector::Create(DynamicDetectionConfig());
  ASSERT_TRUE(detector.ok());
  const StatusOr<DynamicDetectionResult> result =
      detector.value().Detect(history, current, Pose3::Identity());
  ASSERT_TRUE(result.ok()) << result.status().message();
  const DynamicDetectionConfig defaults;
  const double reach_m = defaults.seed_distance_m + defaults.grow_radius_m;
  ASSERT_LT(reach_m, 0.7);  // the wall's bottom row stays out of reach of the ground
  std::size_t beyond_seeds = 0, beyond_reach = 0;  // current wall points without a partner
  for (const Eigen::Vector3d& p : current.points) {
    if (p.z() <= 0.0) continue;
    beyond_seeds += p.y() > defaults.seed_distance_m + 1e-6;
    beyond_reach += p.y() > reach_m + 1e-6;
  }
  std::printf("current wall points without a partner %zu (%zu beyond a seed's reach), grown %zu"
              "; history grown %zu\n",
              beyond_seeds, beyond_reach, result.value().common_grown[1],
              result.value().common_grown[0]);
  ASSERT_GT(beyond_reach, 300u);
  EXPECT_EQ(result.value().common_grown[1], beyond_seeds);
  EXPECT_EQ(result.value().common_grown[0], 0u);  // every history point has its twin: seeds
  EXPECT_TRUE(result.value().history_dynamic.empty());
  EXPECT_TRUE(result.value().current_dynamic.empty());
}

TEST(DynamicDetectionTest, RejectsInvalidConfigsAndMissingOrigins) {
  DynamicDetectionConfig config;
  config.voxel_size_m = 0.0;
  EXPECT_FALSE(DynamicDetector::Create(config).ok());
  // The low residue's settings (step 6).
  const std::vector<std::function<void(DynamicDetectionConfig*)>> bad_low_residue = {
      [](DynamicDetectionConfig* c) { c->low_residue_min_ground_points = -1; },
      [](DynamicDetectionConfig* c) { c->low_residue_max_own_neighbours = -1; },
      [](DynamicDetectionConfig* c) { c->low_residue_radius_m = 0.0; },
      [](DynamicDetectionConfig* c) { c->low_residue_partner_distance_m = -0.1; },
      [](DynamicDetectionConfig* c) { c->low_residue_range_m = std::nan(""); },
      [](DynamicDetectionConfig* c) { c->low_residue_range_m = c->max_range_m + 1.0; },
      [](DynamicDetectionConfig* c) { c->low_residue_blob_radius_m = 0.0; },
  };
  for (const auto& spoil : bad_low_residue) {
    config = DynamicDetectionConfig();
    spoil(&config);
    EXPECT_FALSE(DynamicDetector::Create(config).ok());
  }
  config = DynamicDetectionConfig();
  config.low_residue_min_ground_points = 0;  // off
  config.low_residue_max_own_neighbours = 0;  // no limit
  EXPECT_TRUE(DynamicDetector::Create(config).ok());
  // The far band's ground around an object.
  for (const double bad_cell : {-1.0, 0.1, std::nan(""), HUGE_VAL}) {
    config = DynamicDetectionConfig();
    config.far_ground_cell_m = bad_cell;
    EXPECT_FALSE(DynamicDetector::Create(config).ok()) << bad_cell;
  }
  config = DynamicDetectionConfig();
  for (const double bad_bottom : {0.0, std::nan(""), HUGE_VAL}) {
    config.far_max_bottom_m = bad_bottom;
    EXPECT_FALSE(DynamicDetector::Create(config).ok()) << bad_bottom;
  }
  config.far_max_bottom_m = 1.2;
  config.far_ground_cell_m = 0.0;  // off
  EXPECT_TRUE(DynamicDetector::Create(config).ok());
  config = DynamicDetectionConfig();
  config.seed_distance_m = std::nan("");
  EXPECT_FALSE(DynamicDetector::Create(config).ok());
  config = DynamicDetectionConfig();
  config.min_cluster_coarse_points = config.min_cluster_points + 1;
  EXPECT_FALSE(DynamicDetector::Create(config).ok());
  config = DynamicDetectionConfig();
  config.grow_max_normal_angle_rad = 2.0;
  EXPECT_FALSE(DynamicDetector::Create(config).ok());
  config = DynamicDetectionConfig();
  config.min_passing_rays = 0;
  EXPECT_FALSE(DynamicDetector::Create(config).ok());
  config = DynamicDetectionConfig();
  config.guard_object_height_m = -1.0;
  EXPECT_FALSE(DynamicDetector::Create(config).ok());
  config = DynamicDetectionConfig();
  config.free_column_depth_m = -1.0;
  EXPECT_FALSE(DynamicDetector::Create(config).ok());
  config = DynamicDetectionConfig();
  config.column_clearance_m = std::nan("");
  EXPECT_FALSE(DynamicDetector::Create(config).ok());
  config = DynamicDetectionConfig();
  config.max_object_bottom_m = -0.5;
  EXPECT_FALSE(DynamicDetector::Create(config).ok());
  config = DynamicDetectionConfig();
  config.far_range_m = -1.0;
  EXPECT_FALSE(DynamicDetector::Create(config).ok());
  config.far_range_m = std::nan("");
  EXPECT_FALSE(DynamicDetector::Create(config).ok());
  for (double bad : {-0.1, 1.5, std::nan("")}) {
    config = DynamicDetectionConfig();
    config.changed_partner_min_fraction = bad;
    EXPECT_FALSE(DynamicDetector::Create(config).ok()) << bad;
  }
  config.changed_partner_min_fraction = 0.0;  // the bounds themselves are valid
  EXPECT_TRUE(DynamicDetector::Create(config).ok());
  config.changed_partner_min_fraction = 1.0;
  EXPECT_TRUE(DynamicDetector::Create(config).ok());
  // changed_same_max_fraction: 0 (off) or in (0, changed_min_fraction).
  for (double bad : {-0.1, 0.4, 0.9, std::nan("")}) {
    config = DynamicDetectionConfig();
    config.changed_same_max_fraction = bad;
    EXPECT_FALSE(DynamicDetector::Create(config).ok()) << bad;
  }
  config.changed_same_max_fraction = 0.39;
  EXPECT_TRUE(DynamicDetector::Create(config).ok());

  StatusOr<DynamicDetector> detector = DynamicDetector::Create(DynamicDetectionConfig());
  ASSERT_TRUE(detector.ok());
  Submap with_points;
  with_points.points = {Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(2, 0, 0)};
  Submap no_origins = with_points;
  with_points.scans.resize(1);
  const StatusOr<DynamicDetectionResult> missing =
      detector.value().Detect(no_origins, with_points, Pose3::Identity());
  EXPECT_FALSE(missing.ok());
  const StatusOr<DynamicDetectionResult> empty =
      detector.value().Detect(Submap(), with_points, Pose3::Identity());
  ASSERT_TRUE(empty.ok());
  EXPECT_TRUE(empty.value().history_dynamic.empty());
  EXPECT_TRUE(empty.value().current_dynamic.empty());
}

// The car scene of the shared-index tests, detected once with the indices built inside.
class SharedIndexTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(detector.ok());
    own = detector.value().Detect(history.submap, current.submap, HistoryFrame());
    ASSERT_TRUE(own.ok()) << own.status().message();
  }
  const SessionData history = MakeSession(Scene{true}, 0.0, 11, HistoryFrame());
  const SessionData current = MakeSession(Scene{false}, 0.3, 12, Pose3::Identity());
  const StatusOr<DynamicDetector> detector = DynamicDetector::Create(DynamicDetectionConfig());
  StatusOr<DynamicDetectionResult> own = Status::Error("not run");
};

// The merge builds one neighbour index per current submap and shares it between that
// submap's pairs: the result is the same as with the index built inside; an index over other
// points is refused.
TEST_F(SharedIndexTest, SharedCurrentIndexGivesTheSameResult) {
  StatusOr<PointIndex> index = PointIndex::Create(current.submap.points);
  ASSERT_TRUE(index.ok());
  for (int pair = 0; pair < 2; ++pair) {  // used twice, as by two pairs
    const StatusOr<DynamicDetectionResult> shared =
        detector.value().Detect(history.submap, current.submap, HistoryFrame(), index.value());
    ASSERT_TRUE(shared.ok()) << shared.status().message();
    EXPECT_FALSE(shared.value().history_dynamic.empty());
    EXPECT_EQ(shared.value().history_dynamic, own.value().history_dynamic);
    EXPECT_EQ(shared.value().current_dynamic, own.value().current_dynamic);
    EXPECT_EQ(shared.value().current_mending, own.value().current_mending);
  }
  StatusOr<PointIndex> other = PointIndex::Create(history.submap.points);
  ASSERT_TRUE(other.ok());
  ASSERT_NE(history.submap.points.size(), current.submap.points.size());
  const StatusOr<DynamicDetectionResult> wrong =
      detector.value().Detect(history.submap, current.submap, HistoryFrame(), other.value());
  ASSERT_FALSE(wrong.ok());
  EXPECT_NE(wrong.status().message().find("index"), std::string::npos);
}

// The merge can also share one index per history submap, built in that submap's own frame
// (the detection moves its queries there): the same result as with both indices built inside,
// with a non-trivial rotation between the frames; a history index of another size is refused.
// The steps' times add up to no more than the whole detection.
TEST_F(SharedIndexTest, SharedIndicesOfBothSubmapsGiveTheSameResult) {
  StatusOr<PointIndex> history_index = PointIndex::Create(history.submap.points);
  StatusOr<PointIndex> current_index = PointIndex::Create(current.submap.points);
  ASSERT_TRUE(history_index.ok() && current_index.ok());
  const StatusOr<DynamicDetectionResult> shared = detector.value().Detect(
      history.submap, current.submap, HistoryFrame(), history_index.value(),
      current_index.value());
  ASSERT_TRUE(shared.ok()) << shared.status().message();
  EXPECT_FALSE(shared.value().history_dynamic.empty());
  EXPECT_FALSE(shared.value().current_mending.empty());
  EXPECT_EQ(shared.value().history_dynamic, own.value().history_dynamic);
  EXPECT_EQ(shared.value().current_dynamic, own.value().current_dynamic);
  EXPECT_EQ(shared.value().current_mending, own.value().current_mending);
  EXPECT_EQ(shared.value().examined_objects.size(), own.value().examined_objects.size());

  const DynamicDetectionResult::StageTimes& st = own.value().stage;
  double steps = 0.0;
  for (const auto& step : st.Named()) steps += step.second;
  EXPECT_GT(st.index_s, 0.0);
  EXPECT_GT(st.rays_s, 0.0);
  EXPECT_LE(steps, own.value().time_s + 1e-9);
  EXPECT_EQ(shared.value().stage.index_s, 0.0);  // nothing built inside

  const StatusOr<DynamicDetectionResult> wrong =
      detector.value().Detect(history.submap, current.submap, HistoryFrame(),
                              current_index.value(), current_index.value());
  ASSERT_FALSE(wrong.ok());
  ASSERT_NE(history.submap.points.size(), current.submap.points.size());
  EXPECT_NE(wrong.status().message().find(
                "the submap " + std::to_string(history.submap.points.size())),
            std::string::npos)
      << wrong.status().message();
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
