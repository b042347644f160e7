#include "multisession_mapper/core/kdtree_target.h"

#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

namespace multisession_mapper {
namespace core {
namespace {

// 3000 points uniform in a 40 m cube around the origin.
PointVector RandomCloud(std::mt19937* rng) {
  std::uniform_real_distribution<double> u(-20.0, 20.0);
  PointVector pts;
  for (int i = 0; i < 3000; ++i) pts.emplace_back(u(*rng), u(*rng), u(*rng));
  return pts;
}

TEST(KdTreeTargetTest, NearestMatchesBruteForce) {
  std::mt19937 rng(6);
  std::uniform_real_distribution<double> u(-20.0, 20.0);
  const PointVector pts = RandomCloud(&rng);
  const KdTreeTarget target = KdTreeTarget::Create(pts).value();
  for (int q = 0; q < 500; ++q) {
    const Eigen::Vector3d query(u(rng), u(rng), u(rng));
    double best = std::numeric_limits<double>::infinity();
    for (const Eigen::Vector3d& p : pts) best = std::min(best, (p - query).squaredNorm());
    TargetMatch match;
    const bool ok = target.FindMatch(query, 2.0, &match);
    ASSERT_EQ(ok, best <= 4.0);
    if (ok) {
      EXPECT_NEAR(match.distance_sq, best, 1e-9);
    }
  }
}

TEST(KdTreeTargetTest, NearestWithinAgreesWithNearestInsideTheRadiusOnly) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-20.0, 20.0);
  const PointVector pts = RandomCloud(&rng);
  const KdTreeTarget target = KdTreeTarget::Create(pts).value();
  int inside = 0;
  for (int q = 0; q < 500; ++q) {
    // Queries up to 15 m outside the cloud too: nothing within the radius there.
    const Eigen::Vector3d query(1.5 * u(rng), 1.5 * u(rng), 1.5 * u(rng));
    std::size_t nearest = 0, within = 0;
    double d_nearest = std::numeric_limits<double>::infinity(), d_within = 0.0;
    for (std::size_t i = 0; i < pts.size(); ++i) {  // brute force
      const double d = (pts[i] - query).squaredNorm();
      if (d < d_nearest) {
        d_nearest = d;
        nearest = i;
      }
    }
    const bool ok = target.NearestWithin(query, 1.5, &within, &d_within);
    ASSERT_EQ(ok, d_nearest <= 1.5 * 1.5) << "query " << q;
    if (ok) {
      ++inside;
      EXPECT_EQ(within, nearest);
      EXPECT_DOUBLE_EQ(d_within, d_nearest);
    }
  }
  EXPECT_GT(inside, 50);
  EXPECT_LT(inside, 450);
}

TEST(KdTreeTargetTest, WarmStartedFindMatchesGivesTheColdMatches) {
  // An ICP's second search: the queries moved a little, the previous matches bound the search.
  std::mt19937 rng(8);
  std::uniform_real_distribution<double> u(-20.0, 20.0);
  std::normal_distribution<double> step(0.0, 0.5);
  const KdTreeTarget target = KdTreeTarget::Create(RandomCloud(&rng)).value();
  PointVector queries;
  for (int q = 0; q < 2000; ++q) queries.emplace_back(u(rng), u(rng), u(rng));
  std::vector<std::uint8_t> found;
  std::vector<TargetMatch> matches;
  target.FindMatches(queries, 3.0, false, nullptr, &found, &matches);
  const std::vector<TargetMatch> first = matches;
  const std::vector<std::uint8_t> first_found = found;
  PointVector moved = queries;
  for (Eigen::Vector3d& q : moved) q += Eigen::Vector3d(step(rng), step(rng), step(rng));
  target.FindMatches(moved, 3.0, /*warm_start=*/true, nullptr, &found, &matches);
  int hits = 0;
  int changed = 0;  // nearest point differs from the previous one: the bound is not the answer
  for (std::size_t i = 0; i < moved.size(); ++i) {
    TargetMatch cold;
    const bool ok = target.FindMatch(moved[i], 3.0, &cold);
    ASSERT_EQ(found[i] != 0, ok) << "query " << i;
    if (!ok) continue;
    ++hits;
    EXPECT_EQ(matches[i].point, cold.point);
    EXPECT_EQ(matches[i].distance_sq, cold.distance_sq);
    EXPECT_EQ(matches[i].has_normal, cold.has_normal);
    if (first_found[i] != 0 && first[i].point != cold.point) ++changed;
  }
  EXPECT_GT(hits, 1000);
  EXPECT_GT(changed, 200);
}

TEST(KdTreeTargetTest, WarmStartedMissesGiveTheColdAnswersAsTheyMoveIntoReach) {
  // Queries that start without a match keep, as misses, how far their nearest point was, and
  // are not searched again while they moved too little to reach one. They walk towards the
  // cloud in steps of 0.05-0.6 m (an ICP's searches), some jittering on the spot, and after
  // each step every answer must be the cold one.
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> u(-20.0, 20.0);
  std::uniform_real_distribution<double> step_length(0.05, 0.6);
  std::normal_distribution<double> jitter(0.0, 0.05);
  const KdTreeTarget target = KdTreeTarget::Create(RandomCloud(&rng)).value();
  PointVector queries, velocity;
  for (int q = 0; q < 1500; ++q) {
    const Eigen::Vector3d start(1.6 * u(rng), 1.6 * u(rng), 1.6 * u(rng));
    queries.push_back(start);
    velocity.push_back(q % 3 == 0 ? Eigen::Vector3d::Zero()
                                  : Eigen::Vector3d(-start.normalized() * step_length(rng)));
  }
  std::vector<std::uint8_t> found;
  std::vector<TargetMatch> matches;
  int misses = 0, became_hits = 0;
  std::vector<std::uint8_t> was_hit(queries.size(), 0);
  for (int search = 0; search < 25; ++search) {
    target.FindMatches(queries, 1.0, /*warm_start=*/search > 0, nullptr, &found, &matches);
    for (std::size_t i = 0; i < queries.size(); ++i) {
      TargetMatch cold;
      const bool ok = target.FindMatch(queries[i], 1.0, &cold);
      ASSERT_EQ(found[i] != 0, ok) << "search " << search << " query " << i;
      if (!ok) {
        ++misses;
        continue;
      }
      if (!was_hit[i] && search > 0) ++became_hits;
      was_hit[i] = 1;
      EXPECT_EQ(matches[i].point, cold.point);
      EXPECT_EQ(matches[i].distance_sq, cold.distance_sq);
    }
    for (std::size_t i = 0; i < queries.size(); ++i) {
      queries[i] += velocity[i] + Eigen::Vector3d(jitter(rng), jitter(rng), jitter(rng));
    }
  }
  EXPECT_GT(misses, 5000);
  EXPECT_GT(became_hits, 200);
}

TEST(KdTreeTargetTest, WallPointsGetWallNormals) {
  PointVector pts;
  for (double y = -5.0; y <= 5.0; y += 0.2) {
    for (double z = 0.0; z <= 3.0; z += 0.2) pts.emplace_back(4.0, y, z);
  }
  const KdTreeTarget target = KdTreeTarget::Create(pts).value();
  EXPECT_GT(target.PlanarFraction(), 0.99);
  TargetMatch match;
  ASSERT_TRUE(target.FindMatch(Eigen::Vector3d(3.7, 0.05, 1.0), 1.0, &match));
  ASSERT_TRUE(match.has_normal);
  EXPECT_GT(std::abs(match.normal.x()), 0.999);
}

TEST(KdTreeTargetTest, NormalsFittedOnFirstUseAreTheSameFromConcurrentQueries) {
  // Normals are fitted when a point is first matched. Two threads matching the same points in
  // opposite orders (each fits some first, some are fitted by the other) must get the normals
  // of a target whose normals were all fitted up front.
  std::mt19937 rng(9);
  std::normal_distribution<double> noise(0.0, 0.02);
  PointVector pts;
  for (double x = -6.0; x <= 6.0; x += 0.25) {
    for (double y = -6.0; y <= 6.0; y += 0.25) pts.emplace_back(x, y, noise(rng));  // ground
    for (double z = 0.0; z <= 3.0; z += 0.25) pts.emplace_back(x, 6.5 + noise(rng), z);  // wall
  }
  const KdTreeTarget lazy = KdTreeTarget::Create(pts).value();
  const KdTreeTarget eager = KdTreeTarget::Create(pts).value();
  ASSERT_GT(eager.PlanarFraction(), 0.9);  // fits every normal
  std::vector<TargetMatch> forward(pts.size()), backward(pts.size());
  std::vector<std::uint8_t> ok_forward(pts.size()), ok_backward(pts.size());
  std::thread a([&] {
    for (std::size_t i = 0; i < pts.size(); ++i) {
      ok_forward[i] = lazy.FindMatch(pts[i], 0.1, &forward[i]);
    }
  });
  std::thread b([&] {
    for (std::size_t i = pts.size(); i-- > 0;) {
      ok_backward[i] = lazy.FindMatch(pts[i], 0.1, &backward[i]);
    }
  });
  a.join();
  b.join();
  int with_normal = 0;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    TargetMatch expected;
    ASSERT_TRUE(eager.FindMatch(pts[i], 0.1, &expected));
    ASSERT_TRUE(ok_forward[i] && ok_backward[i]);
    for (const TargetMatch* m : {&forward[i], &backward[i]}) {
      ASSERT_EQ(m->has_normal, expected.has_normal) << "point " << i;
      EXPECT_EQ(m->normal, expected.normal) << "point " << i;
    }
    with_normal += expected.has_normal ? 1 : 0;
  }
  EXPECT_GT(with_normal, static_cast<int>(pts.size() * 9 / 10));
  EXPECT_DOUBLE_EQ(lazy.PlanarFraction(), eager.PlanarFraction());
}

TEST(KdTreeTargetTest, RejectsEmptyAndNonFiniteInput) {
  EXPECT_FALSE(KdTreeTarget::Create(PointVector()).ok());
  PointVector bad = {{0, 0, 0}, {std::nan(""), 0, 0}};
  EXPECT_FALSE(KdTreeTarget::Create(bad).ok());
  KdTreeTargetConfig config;
  config.normal_neighbors = 2;
  EXPECT_FALSE(KdTreeTarget::Create({{0, 0, 0}}, config).ok());
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
