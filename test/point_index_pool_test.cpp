#include "multisession_mapper/core/point_index_pool.h"

#include <atomic>
#include <cmath>
#include <limits>
#include <random>

#include <gtest/gtest.h>

#include "multisession_mapper/core/parallel_for.h"

namespace multisession_mapper {
namespace core {
namespace {

std::vector<PointVector> RandomSets(int sets, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-5.0, 5.0);
  std::vector<PointVector> out(sets);
  for (int s = 0; s < sets; ++s) {
    for (int i = 0; i < 200 + 50 * s; ++i) out[s].emplace_back(u(rng), u(rng), u(rng));
  }
  return out;
}

// Each item is built once, shared by its announced uses, and let go of after the last; the
// lease keeps it usable after that; a use beyond the announced number is refused.
TEST(PointIndexPoolTest, BuildsOnceSharesAndFreesAfterTheLastUse) {
  const std::vector<PointVector> sets = RandomSets(3, 1);
  std::atomic<int> builds[3] = {{0}, {0}, {0}};
  PointIndexPool pool({2, 1, 0}, [&](std::size_t k) -> const PointVector& {
    ++builds[k];
    return sets[k];
  });
  StatusOr<PointIndexPool::Lease> first = pool.Acquire(0);
  ASSERT_TRUE(first.ok()) << first.status().message();
  EXPECT_EQ(pool.alive(), 1u);
  StatusOr<PointIndexPool::Lease> second = pool.Acquire(0);
  ASSERT_TRUE(second.ok());
  EXPECT_EQ(first.value().index.get(), second.value().index.get());
  EXPECT_EQ(builds[0].load(), 1);
  EXPECT_EQ(pool.alive(), 0u);  // the pool let go; the leases still hold it
  EXPECT_EQ(second.value().index->size(), sets[0].size());
  EXPECT_GE(first.value().build_share_s, 0.0);
  EXPECT_DOUBLE_EQ(first.value().build_share_s, second.value().build_share_s);
  // Same answers as an index built directly.
  StatusOr<PointIndex> direct = PointIndex::Create(sets[0]);
  ASSERT_TRUE(direct.ok());
  std::uint32_t a = 0, b = 0;
  double da = 0.0, db = 0.0;
  ASSERT_TRUE(second.value().index->Nearest(Eigen::Vector3d(0.1, 0.2, 0.3), &a, &da));
  ASSERT_TRUE(direct.value().Nearest(Eigen::Vector3d(0.1, 0.2, 0.3), &b, &db));
  EXPECT_EQ(a, b);

  EXPECT_FALSE(pool.Acquire(0).ok());  // a third use of two announced
  EXPECT_EQ(builds[0].load(), 1);
  EXPECT_FALSE(pool.Acquire(2).ok());  // never announced
  EXPECT_EQ(builds[2].load(), 0);
  EXPECT_FALSE(pool.Acquire(3).ok());  // out of range
  ASSERT_TRUE(pool.Acquire(1).ok());
  EXPECT_EQ(pool.peak_alive(), 1u);
}

// A set with a non-finite point: every use gets the construction's error.
TEST(PointIndexPoolTest, ConstructionErrorReachesEveryUse) {
  std::vector<PointVector> sets = RandomSets(1, 2);
  sets[0][7].x() = std::numeric_limits<double>::quiet_NaN();
  PointIndexPool pool({2}, [&](std::size_t k) -> const PointVector& { return sets[k]; });
  EXPECT_FALSE(pool.Acquire(0).ok());
  EXPECT_FALSE(pool.Acquire(0).ok());
  EXPECT_EQ(pool.alive(), 0u);
}

// Many threads using few items, as the merge's pairs: every item is built exactly once, every
// use gets the item's index, and everything is let go of in the end.
TEST(PointIndexPoolTest, ConcurrentUsesBuildEachItemOnce) {
  constexpr int kItems = 6, kUsesEach = 5;
  const std::vector<PointVector> sets = RandomSets(kItems, 3);
  std::atomic<int> builds[kItems];
  for (auto& b : builds) b = 0;
  PointIndexPool pool(std::vector<int>(kItems, kUsesEach), [&](std::size_t k) -> const PointVector& {
    ++builds[k];
    return sets[k];
  });
  std::atomic<int> wrong{0};
  ParallelFor(kItems * kUsesEach, 4, [&](std::size_t i) {
    const std::size_t item = i / kUsesEach;  // uses of one item are neighbours in the order
    StatusOr<PointIndexPool::Lease> lease = pool.Acquire(item);
    if (!lease.ok() || lease.value().index->size() != sets[item].size()) ++wrong;
  });
  EXPECT_EQ(wrong.load(), 0);
  for (int k = 0; k < kItems; ++k) EXPECT_EQ(builds[k].load(), 1) << "item " << k;
  EXPECT_EQ(pool.alive(), 0u);
  EXPECT_GE(pool.peak_alive(), 1u);
  EXPECT_LE(pool.peak_alive(), static_cast<std::size_t>(kItems));
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
