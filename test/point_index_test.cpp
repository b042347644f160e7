#include "multisession_mapper/core/point_index.h"

#include <algorithm>
#include <limits>
#include <random>

#include <gtest/gtest.h>

namespace multisession_mapper {
namespace core {
namespace {

PointVector RandomPoints(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-5.0, 5.0);
  PointVector pts;
  for (int i = 0; i < n; ++i) pts.emplace_back(u(rng), u(rng), u(rng));
  return pts;
}

TEST(PointIndexTest, QueriesAgreeWithBruteForce) {
  const PointVector pts = RandomPoints(3000, 1);
  StatusOr<PointIndex> index = PointIndex::Create(pts);
  ASSERT_TRUE(index.ok());
  const PointVector queries = RandomPoints(200, 2);
  std::vector<std::uint32_t> found;
  for (const Eigen::Vector3d& q : queries) {
    std::uint32_t best = 0;
    double best_d2 = std::numeric_limits<double>::max();
    std::vector<std::uint32_t> within;
    for (std::uint32_t i = 0; i < pts.size(); ++i) {
      const double d2 = (pts[i] - q).squaredNorm();
      if (d2 < best_d2) {
        best_d2 = d2;
        best = i;
      }
      if (d2 <= 0.8 * 0.8) within.push_back(i);
    }
    std::uint32_t index_found = 0;
    double d2 = 0.0;
    ASSERT_TRUE(index.value().Nearest(q, &index_found, &d2));
    EXPECT_EQ(index_found, best);
    EXPECT_NEAR(d2, best_d2, 1e-12);

    const bool within_half = index.value().NearestWithin(q, 0.5, &index_found, &d2);
    EXPECT_EQ(within_half, best_d2 <= 0.25);
    if (within_half) {
      EXPECT_EQ(index_found, best);
      EXPECT_NEAR(d2, best_d2, 1e-12);
    }

    index.value().Radius(q, 0.8, &found);
    std::sort(found.begin(), found.end());
    EXPECT_EQ(found, within);
    EXPECT_EQ(index.value().CountWithin(q, 0.8, 1000000), within.size());
    EXPECT_EQ(index.value().CountWithin(q, 0.8, 1), std::min<std::size_t>(within.size(), 1));

    index.value().Nearest(q, 5, 100.0, &found);
    ASSERT_EQ(found.size(), 5u);
    EXPECT_EQ(found[0], best);
    index.value().Nearest(q, 5, std::sqrt(best_d2) * 0.5, &found);
    EXPECT_TRUE(found.empty());
    // k nearest within a radius, nearest first: fewer than k where the radius holds fewer.
    std::vector<std::pair<double, std::uint32_t>> by_distance;
    for (std::uint32_t i : within) by_distance.push_back({(pts[i] - q).squaredNorm(), i});
    std::sort(by_distance.begin(), by_distance.end());
    for (std::size_t k : {std::size_t{3}, std::size_t{40}}) {
      std::vector<std::uint32_t> expected;
      for (std::size_t j = 0; j < std::min(k, by_distance.size()); ++j) {
        expected.push_back(by_distance[j].second);
      }
      index.value().Nearest(q, k, 0.8, &found);
      EXPECT_EQ(found, expected) << "k " << k;
    }
  }
}

TEST(PointIndexTest, EmptySetFindsNothingAndNonFiniteIsRejected) {
  StatusOr<PointIndex> empty = PointIndex::Create({});
  ASSERT_TRUE(empty.ok());
  std::uint32_t i = 0;
  double d2 = 0.0;
  EXPECT_FALSE(empty.value().Nearest(Eigen::Vector3d::Zero(), &i, &d2));
  std::vector<std::uint32_t> found{1, 2};
  empty.value().Radius(Eigen::Vector3d::Zero(), 1.0, &found);
  EXPECT_TRUE(found.empty());
  EXPECT_FALSE(PointIndex::Create({Eigen::Vector3d(0.0, std::nan(""), 0.0)}).ok());
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
