#include "multisession_mapper/core/voxel_hash_map.h"

#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "multisession_mapper/core/local_plane.h"
#include "multisession_mapper/core/worker_pool.h"

namespace multisession_mapper {
namespace core {
namespace {

TEST(VoxelHashMapTest, NearestNeighbourMatchesBruteForceWithinOneVoxel) {
  VoxelHashMapConfig config;
  config.voxel_size_m = 1.0;
  config.max_points_per_voxel = 1000;  // keep every point so brute force sees the same set
  config.min_point_spacing_m = 0.0;
  VoxelHashMap map = VoxelHashMap::Create(config).value();
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-10.0, 10.0);
  PointVector pts;
  for (int i = 0; i < 5000; ++i) pts.emplace_back(u(rng), u(rng), u(rng) * 0.3);
  map.AddPoints(pts);
  ASSERT_EQ(map.NumPoints(), pts.size());

  const double max_dist = 1.0;  // = voxel edge: the 27-voxel search is exact up to this
  int found = 0;
  for (int q = 0; q < 2000; ++q) {
    const Eigen::Vector3d query(u(rng), u(rng), u(rng) * 0.3);
    double best = std::numeric_limits<double>::infinity();
    for (const Eigen::Vector3d& p : pts) best = std::min(best, (p - query).squaredNorm());
    TargetMatch match;
    const bool ok = map.FindMatch(query, max_dist, &match);
    ASSERT_EQ(ok, best <= max_dist * max_dist) << "query " << query.transpose();
    if (ok) {
      ++found;
      EXPECT_NEAR(match.distance_sq, best, 1e-12);
      EXPECT_NEAR((match.point - query).squaredNorm(), best, 1e-12);
    }
  }
  EXPECT_GT(found, 1000);
}

// The searches cache each center voxel's 27 neighbour ids; points added in new voxels
// between searches (the odometry adds a scan after each registration) must enter the cached
// neighbourhoods: the matches stay those of a map built at once, scan after scan.
TEST(VoxelHashMapTest, SearchesBetweenInsertionsSeeTheNewVoxels) {
  VoxelHashMapConfig config;
  config.max_points_per_voxel = 1000;
  config.min_point_spacing_m = 0.0;
  VoxelHashMap grown = VoxelHashMap::Create(config).value();
  VoxelHashMap fresh = VoxelHashMap::Create(config).value();
  grown.SetNormalsEnabled(false);
  fresh.SetNormalsEnabled(false);
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> u(-6.0, 6.0);
  PointVector queries;
  for (int i = 0; i < 3000; ++i) queries.emplace_back(u(rng), u(rng), u(rng) * 0.5);
  PointVector all;
  for (int batch = 0; batch < 6; ++batch) {
    PointVector points;  // sparse batches: most land in voxels that were empty
    for (int i = 0; i < 150; ++i) points.emplace_back(u(rng), u(rng), u(rng) * 0.5);
    grown.AddPoints(points);
    all.insert(all.end(), points.begin(), points.end());
    fresh = VoxelHashMap::Create(config).value();
    fresh.SetNormalsEnabled(false);
    fresh.AddPoints(all);
    std::vector<std::uint8_t> found_grown, found_fresh;
    std::vector<TargetMatch> grown_matches, fresh_matches;
    grown.FindMatches(queries, 1.0, false, nullptr, &found_grown, &grown_matches);
    fresh.FindMatches(queries, 1.0, false, nullptr, &found_fresh, &fresh_matches);
    int found = 0;
    for (std::size_t i = 0; i < queries.size(); ++i) {
      ASSERT_EQ(found_grown[i], found_fresh[i]) << "batch " << batch << " query " << i;
      if (found_grown[i] == 0) continue;
      ++found;
      ASSERT_EQ(grown_matches[i].point, fresh_matches[i].point) << "batch " << batch;
    }
    if (batch == 5) {
      EXPECT_GT(found, 1000);
    }
  }
}

TEST(VoxelHashMapTest, RepeatedSearchesAcrossRemovalsMatchBruteForce) {
  // A search reuses each query's neighbourhood from the previous search while the query
  // stays in its voxel. Insertions add voxels and removals move the ids: searches of the same
  // queries between them must still find the nearest map point (brute force over Points()),
  // on the sequential and the parallel path.
  VoxelHashMapConfig config;
  config.max_points_per_voxel = 1000;  // keep every point
  config.min_point_spacing_m = 0.0;
  config.max_distance_m = 12.0;
  std::mt19937 rng(33);
  std::uniform_real_distribution<double> u(-12.0, 12.0);
  PointVector queries;
  for (int i = 0; i < 1500; ++i) queries.emplace_back(u(rng), u(rng), u(rng) * 0.2);
  for (const int threads : {1, 2}) {
    WorkerPool pool(threads);
    VoxelHashMap map = VoxelHashMap::Create(config).value();
    map.SetNormalsEnabled(false);
    Eigen::Vector3d robot = Eigen::Vector3d::Zero();
    int compared = 0;
    for (int step = 0; step < 4; ++step) {
      PointVector points;
      for (int i = 0; i < 1500; ++i) points.emplace_back(u(rng), u(rng), u(rng) * 0.2);
      map.AddPoints(points);  // after a search: new voxels in reused neighbourhoods
      std::vector<std::uint8_t> found;
      std::vector<TargetMatch> matches;
      for (const bool remove : {false, true}) {
        if (remove) {
          robot += Eigen::Vector3d(3.0, -2.0, 0.0);
          map.RemoveFarVoxels(robot);
        }
        map.FindMatches(queries, 1.0, false, &pool, &found, &matches);
        const PointVector content = map.Points();
        ASSERT_EQ(found.size(), queries.size());
        for (std::size_t i = 0; i < queries.size(); ++i) {
          double best = std::numeric_limits<double>::infinity();
          for (const Eigen::Vector3d& p : content) {
            best = std::min(best, (p - queries[i]).squaredNorm());
          }
          ASSERT_EQ(found[i] != 0, best < 1.0)
              << threads << " threads, step " << step << ", query " << i;
          if (found[i] == 0) continue;
          ++compared;
          ASSERT_NEAR(matches[i].distance_sq, best, 1e-12) << threads << " threads";
        }
      }
    }
    EXPECT_LT(map.NumPoints(), 4u * 1500u) << "the removals removed nothing";
    EXPECT_GT(compared, 4000) << threads << " threads";
  }
}

TEST(VoxelHashMapTest, RecalledMatchesAreTheSearchedOnes) {
  // What an ICP does: the same queries, moved a little at each iteration, searched again and
  // again in an unchanged map. Most matches are then recalled without a search; every one must
  // be exactly what FindMatch (which never recalls) gives, also for queries that move by more
  // than the recall allows, move into another voxel, or out of reach, and after the map changed.
  VoxelHashMapConfig config;
  config.min_point_spacing_m = 0.0;
  config.max_distance_m = 20.0;  // the removal at iteration 11 drops the far side
  std::mt19937 rng(41);
  std::uniform_real_distribution<double> u(-15.0, 15.0);
  std::normal_distribution<double> thin(0.0, 0.01);
  // Surfaces, as scans see them: a ground plane and walls every 3 m (thin voxel boxes, so
  // the search skips most neighbour voxels on their boxes), and scattered points.
  PointVector pts;
  for (int i = 0; i < 12000; ++i) pts.emplace_back(u(rng), u(rng), thin(rng));
  for (int i = 0; i < 8000; ++i) {
    pts.emplace_back(3.0 * std::round(u(rng) / 3.0) + thin(rng), u(rng), 0.1 * (u(rng) + 15.0));
  }
  for (int i = 0; i < 2000; ++i) pts.emplace_back(u(rng), u(rng), 0.1 * (u(rng) + 15.0));
  for (int i = 0; i < 2000; ++i) pts.push_back(pts[i * 7]);  // exact ties: never recalled
  PointVector start;
  for (int i = 0; i < 3000; ++i) {
    start.emplace_back(u(rng), u(rng), i % 2 == 0 ? 0.1 * u(rng) : 0.1 * (u(rng) + 15.0));
  }
  for (const int threads : {1, 2}) {
    WorkerPool pool(threads);
    VoxelHashMap map = VoxelHashMap::Create(config).value();
    map.SetNormalsEnabled(false);
    map.AddPoints(pts);
    PointVector queries = start;
    std::vector<std::uint8_t> found;
    std::vector<TargetMatch> matches;
    std::uint64_t searched = 0;
    for (int iteration = 0; iteration < 16; ++iteration) {
      // Millimetre steps, every fifth iteration 5 cm, every 7th query 0.3 m.
      const double sigma = iteration % 5 == 4 ? 0.05 : 0.002;
      std::normal_distribution<double> step(0.0, sigma);
      for (std::size_t i = 0; i < queries.size(); ++i) {
        const double scale = i % 7 == 0 ? 0.3 / sigma : 1.0;
        queries[i] += scale * Eigen::Vector3d(step(rng), step(rng), step(rng));
      }
      if (iteration == 8) {  // a change of the map: nothing may be recalled from before it
        PointVector more;
        for (int i = 0; i < 2000; ++i) more.emplace_back(u(rng), u(rng), u(rng) * 0.2);
        map.AddPoints(more);
      }
      if (iteration == 11) {
        const std::size_t before = map.NumPoints();
        map.RemoveFarVoxels(Eigen::Vector3d(12.0, 0.0, 0.0));
        ASSERT_LT(map.NumPoints(), before) << "the removal must remove something";
      }
      if (iteration == 13) map.SetNormalsEnabled(true);  // searched, with normals
      if (iteration == 14) map.SetNormalsEnabled(false);
      const std::uint64_t recalled_before = map.recalled_matches();
      // Warm start presumes the previous matches are still in the map: not after a removal.
      map.FindMatches(queries, 0.6, iteration > 0 && iteration != 11, &pool, &found, &matches);
      if (iteration == 0 || iteration == 8 || iteration == 11 || iteration == 13) {
        EXPECT_EQ(map.recalled_matches(), recalled_before) << "iteration " << iteration;
      }
      searched += queries.size();
      for (std::size_t i = 0; i < queries.size(); ++i) {
        TargetMatch expected;
        const bool ok = map.FindMatch(queries[i], 0.6, &expected);
        ASSERT_EQ(found[i] != 0, ok) << threads << " threads, iteration " << iteration;
        if (!ok) continue;
        ASSERT_EQ(matches[i].point, expected.point) << threads << " threads";
        ASSERT_EQ(matches[i].distance_sq, expected.distance_sq) << threads << " threads";
      }
    }
    // Many of the millimetre steps are recalled (a third here: dense surfaces).
    EXPECT_GT(map.recalled_matches(), searched / 4) << threads << " threads";
  }
}

TEST(VoxelHashMapTest, WarmStartedFindMatchesGivesTheColdMatches) {
  // What an ICP does: search, move the queries a little, search again bounded by the previous
  // matches. The bound must not change a single match, on the parallel and the sequential
  // path, also for queries that move away from their previous match or out of reach.
  VoxelHashMap map = VoxelHashMap::Create(VoxelHashMapConfig()).value();
  std::mt19937 rng(21);
  std::uniform_real_distribution<double> u(-15.0, 15.0);
  std::normal_distribution<double> step(0.0, 0.15);
  PointVector pts;
  for (int i = 0; i < 20000; ++i) pts.emplace_back(u(rng), u(rng), u(rng) * 0.2);
  map.AddPoints(pts);
  PointVector queries;
  for (int i = 0; i < 3000; ++i) queries.emplace_back(u(rng), u(rng), u(rng) * 0.3);
  for (const bool normals : {false, true}) {
    map.SetNormalsEnabled(normals);
    WorkerPool pool(2);
    std::vector<std::uint8_t> found;
    std::vector<TargetMatch> matches;
    map.FindMatches(queries, 0.6, false, &pool, &found, &matches);
    PointVector moved = queries;
    for (Eigen::Vector3d& q : moved) q += Eigen::Vector3d(step(rng), step(rng), step(rng));
    map.FindMatches(moved, 0.6, /*warm_start=*/true, &pool, &found, &matches);
    std::vector<std::uint8_t> cold_found;
    std::vector<TargetMatch> cold;
    map.FindMatches(moved, 0.6, false, &pool, &cold_found, &cold);
    int hits = 0;
    int changed = 0;  // queries whose nearest point is not the previous one: the bound matters
    std::vector<std::uint8_t> first_found;
    std::vector<TargetMatch> first;
    map.FindMatches(queries, 0.6, false, &pool, &first_found, &first);
    for (std::size_t i = 0; i < moved.size(); ++i) {
      ASSERT_EQ(found[i], cold_found[i]) << "query " << i;
      if (found[i] == 0) continue;
      ++hits;
      EXPECT_EQ(matches[i].point, cold[i].point);
      EXPECT_EQ(matches[i].distance_sq, cold[i].distance_sq);
      EXPECT_EQ(matches[i].has_normal, cold[i].has_normal);
      if (first_found[i] != 0 && first[i].point != cold[i].point) ++changed;
    }
    EXPECT_GT(hits, 1000);
    EXPECT_GT(changed, 100);
  }
}

TEST(VoxelHashMapTest, ParallelFindMatchesGivesTheSequentialMatches) {
  VoxelHashMap map = VoxelHashMap::Create(VoxelHashMapConfig()).value();
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> u(-15.0, 15.0);
  PointVector pts;
  for (int i = 0; i < 20000; ++i) pts.emplace_back(u(rng), u(rng), u(rng) * 0.2);
  map.AddPoints(pts);
  PointVector queries;
  for (int i = 0; i < 3000; ++i) queries.emplace_back(u(rng), u(rng), u(rng) * 0.2);
  for (const bool normals : {false, true}) {  // with normals: the sequential path
    map.SetNormalsEnabled(normals);
    std::vector<std::uint8_t> found;
    std::vector<TargetMatch> matches;
    WorkerPool pool(2);
    map.FindMatches(queries, 0.6, /*warm_start=*/false, &pool, &found, &matches);
    ASSERT_EQ(found.size(), queries.size());
    ASSERT_EQ(matches.size(), queries.size());
    int hits = 0;
    for (std::size_t i = 0; i < queries.size(); ++i) {
      TargetMatch expected;
      const bool ok = map.FindMatch(queries[i], 0.6, &expected);
      ASSERT_EQ(found[i] != 0, ok) << "query " << i;
      if (!ok) continue;
      ++hits;
      EXPECT_EQ(matches[i].point, expected.point);
      EXPECT_EQ(matches[i].distance_sq, expected.distance_sq);
      EXPECT_EQ(matches[i].has_normal, expected.has_normal);
      if (expected.has_normal) {
        EXPECT_EQ(matches[i].normal, expected.normal);
      }
    }
    EXPECT_GT(hits, 1000);
  }
}

TEST(VoxelHashMapTest, RespectsMaxPointsAndSpacing) {
  VoxelHashMapConfig config;
  config.max_points_per_voxel = 5;
  config.min_point_spacing_m = 0.1;
  VoxelHashMap map = VoxelHashMap::Create(config).value();
  PointVector pts;
  for (int i = 0; i < 50; ++i) pts.emplace_back(0.5, 0.5, 0.5 + 0.001 * i);  // all too close
  map.AddPoints(pts);
  EXPECT_EQ(map.NumPoints(), 1u);
  pts.clear();
  for (int i = 0; i < 9; ++i) pts.emplace_back(0.05 + 0.11 * i, 0.5, 0.5);
  map.AddPoints(pts);
  EXPECT_EQ(map.NumPoints(), 5u);
  EXPECT_EQ(map.NumVoxels(), 1u);
}

TEST(VoxelHashMapTest, RemovesVoxelsFarFromTheRobot) {
  VoxelHashMapConfig config;
  config.max_distance_m = 10.0;
  VoxelHashMap map = VoxelHashMap::Create(config).value();
  map.Update({{1.0, 0.0, 0.0}, {9.5, 0.0, 0.0}, {15.0, 0.0, 0.0}, {-30.0, 2.0, 0.0}},
             Eigen::Vector3d::Zero());
  EXPECT_EQ(map.NumPoints(), 2u);
  map.RemoveFarVoxels(Eigen::Vector3d(-5.0, 0.0, 0.0));
  EXPECT_EQ(map.NumPoints(), 1u);  // 9.5 is now 14.5 m away
  map.Clear();
  EXPECT_TRUE(map.empty());
}

TEST(VoxelHashMapTest, UpdateRemovesFarVoxelsOnlyAfterTheRemovalStep) {
  VoxelHashMapConfig config;
  config.max_distance_m = 10.0;
  config.removal_step_m = 2.0;
  VoxelHashMap map = VoxelHashMap::Create(config).value();
  map.Update({{9.5, 0.0, 0.0}}, Eigen::Vector3d::Zero());  // the first update removes
  EXPECT_EQ(map.NumPoints(), 1u);
  map.Update({}, Eigen::Vector3d(-1.5, 0.0, 0.0));  // 11 m away, but moved only 1.5 m
  EXPECT_EQ(map.NumPoints(), 1u);
  map.Update({}, Eigen::Vector3d(-2.0, 0.0, 0.0));  // moved 2 m: removed
  EXPECT_EQ(map.NumPoints(), 0u);
  config.removal_step_m = -1.0;
  EXPECT_FALSE(config.Validate().ok());
}

TEST(VoxelHashMapTest, PlaneGivesNormalAndUpdatesInvalidateIt) {
  VoxelHashMap map = VoxelHashMap::Create(VoxelHashMapConfig()).value();
  PointVector ground;
  for (double x = -3.0; x <= 3.0; x += 0.25) {
    for (double y = -3.0; y <= 3.0; y += 0.25) ground.emplace_back(x, y, 0.0);
  }
  map.AddPoints(ground);
  TargetMatch match;
  ASSERT_TRUE(map.FindMatch(Eigen::Vector3d(0.1, 0.1, 0.3), 1.0, &match));
  ASSERT_TRUE(match.has_normal);
  EXPECT_GT(std::abs(match.normal.z()), 0.999);
  EXPECT_NEAR(match.distance_sq, 0.1 * 0.1 + 0.1 * 0.1 + 0.3 * 0.3, 1e-9);

  // A nearest point in empty space far from the plane has no query result within 0.5 m.
  EXPECT_FALSE(map.FindMatch(Eigen::Vector3d(0.0, 0.0, 0.8), 0.5, &match));

  // A wall below the ground next to the matched point changes its neighbourhood: the cached
  // normal must be recomputed, not returned again.
  PointVector wall;
  for (double y = -1.0; y <= 1.0; y += 0.2) {
    for (double z = -1.0; z <= -0.2; z += 0.2) wall.emplace_back(-0.3, y, z);
  }
  map.AddPoints(wall);
  ASSERT_TRUE(map.FindMatch(Eigen::Vector3d(0.1, 0.1, 0.3), 1.0, &match));
  EXPECT_NEAR(match.distance_sq, 0.1 * 0.1 + 0.1 * 0.1 + 0.3 * 0.3, 1e-9);  // same point
  EXPECT_TRUE(!match.has_normal || std::abs(match.normal.z()) < 0.999);
}

TEST(VoxelHashMapTest, PlaneNormalAtNeedsMoreThanOneRingLine) {
  VoxelHashMap map = VoxelHashMap::Create(VoxelHashMapConfig()).value();
  map.SetNormalsEnabled(false);  // PlaneNormalAt does not depend on it
  // One ring arc on flat ground 20 m away: a line with 2 cm of range jitter, no plane.
  PointVector ring;
  for (int k = -40; k <= 40; ++k) {
    const double a = k * 0.0035, r = 20.0 + 0.02 * ((k + 42) % 3 - 1);  // +-2 cm
    ring.emplace_back(r * std::cos(a), r * std::sin(a), -1.8);
  }
  map.AddPoints(ring);
  Eigen::Vector3d n;
  EXPECT_FALSE(map.PlaneNormalAt(Eigen::Vector3d(20.0, 0.0, -1.8), &n));
  // The same ground seen from two more places: three ring arcs 0.4 m apart make a plane.
  for (double dr : {0.4, 0.8}) {
    PointVector more;
    for (const Eigen::Vector3d& p : ring) more.push_back(p * (1.0 + dr / 20.0));
    for (Eigen::Vector3d& p : more) p.z() = -1.8;
    map.AddPoints(more);
  }
  ASSERT_TRUE(map.PlaneNormalAt(Eigen::Vector3d(20.2, 0.0, -1.8), &n));
  EXPECT_GT(std::abs(n.z()), 0.99);
  EXPECT_FALSE(map.PlaneNormalAt(Eigen::Vector3d(0.0, 0.0, -1.8), &n));  // nothing there
}

// PlaneNormalAt reads the 27 voxels around the point from the search's neighbour cache when
// a search filled it, from the table otherwise, and skips voxels whose box lies beyond the
// radius: the same normal either way, bit for bit, and that of every point within the radius.
TEST(VoxelHashMapTest, PlaneNormalAtIsTheSameWithTheNeighbourCache) {
  VoxelHashMap map = VoxelHashMap::Create(VoxelHashMapConfig()).value();
  map.SetNormalsEnabled(false);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-6.0, 6.0);
  std::normal_distribution<double> noise(0.0, 0.02);
  PointVector points;  // ground with a slight slope and a wall, 2 cm of noise
  for (int i = 0; i < 3000; ++i) {
    const double x = u(rng), y = u(rng);
    points.emplace_back(x, y, -1.8 + 0.05 * x + noise(rng));
    if (i % 3 == 0) points.emplace_back(4.2 + noise(rng), y, -1.8 + 0.4 * (u(rng) + 6.0));
  }
  map.AddPoints(points);
  const PointVector kept = map.Points();  // (at most 20 per voxel, 0.2 m apart)
  const double radius_sq = std::pow(map.config().normal_radius_m, 2);
  const VoxelHashMap table_only = map;  // never searched: its neighbour cache stays empty
  int planar = 0;
  for (int q = 0; q < 200; ++q) {
    const Eigen::Vector3d p(u(rng) * 0.9, u(rng) * 0.9, -1.8 + 0.05 * u(rng));
    Eigen::Vector3d from_table, from_cache, brute;
    const bool table_ok = table_only.PlaneNormalAt(p, &from_table);
    TargetMatch match;
    map.FindMatch(p, 1.0, &match);  // fills the neighbour cache around p
    const bool cache_ok = map.PlaneNormalAt(p, &from_cache);
    CovarianceAccumulator acc;
    for (const Eigen::Vector3d& x : kept) {
      if ((x - p).squaredNorm() <= radius_sq) acc.Add(x - p);
    }
    const bool brute_ok = acc.Normal(map.config().plane, &brute);
    ASSERT_EQ(table_ok, cache_ok) << "query " << p.transpose();
    ASSERT_EQ(table_ok, brute_ok) << "query " << p.transpose();
    if (!table_ok) continue;
    ++planar;
    EXPECT_EQ(from_table, from_cache);
    EXPECT_LT(std::min((from_table - brute).norm(), (from_table + brute).norm()), 1e-9);
  }
  EXPECT_GT(planar, 100);
}

TEST(VoxelHashMapTest, ValidateNamesTheBadField) {
  VoxelHashMapConfig config;
  config.voxel_size_m = 0.0;
  const Status status = VoxelHashMap::Create(config).status();
  EXPECT_FALSE(status.ok());
  EXPECT_NE(status.message().find("voxel_size_m"), std::string::npos);
  config = VoxelHashMapConfig();
  config.normal_radius_m = 4.0;  // beyond 3 voxels: the neighbourhood search would be too slow
  EXPECT_FALSE(config.Validate().ok());
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
