#include "multisession_mapper/sim/counter_rng.h"

#include <cmath>
#include <set>

#include <gtest/gtest.h>

namespace multisession_mapper {
namespace sim {
namespace {

TEST(SimCounterRngTest, KeysAreDeterministicAndDistinct) {
  EXPECT_EQ(MakeKey(1, 2, 3, 4), MakeKey(1, 2, 3, 4));
  std::set<std::uint64_t> keys;
  for (std::uint64_t a = 0; a < 20; ++a) {
    for (std::uint64_t b = 0; b < 20; ++b) keys.insert(MakeKey(7, a, b));
  }
  EXPECT_EQ(keys.size(), 400u);
  EXPECT_NE(MakeKey(1, 2), MakeKey(2, 1));
}

TEST(SimCounterRngTest, UniformAndGaussianMoments) {
  CounterRng rng(42);
  const int n = 100000;
  double sum = 0.0, sum_sq = 0.0, gsum = 0.0, gsum_sq = 0.0;
  int in_range = 0;
  for (int i = 0; i < n; ++i) {
    const double u = rng.Uniform();
    ASSERT_GE(u, 0.0);
    ASSERT_LT(u, 1.0);
    sum += u;
    sum_sq += u * u;
    const double g = rng.Gaussian();
    gsum += g;
    gsum_sq += g * g;
    const int k = rng.UniformInt(3, 5);
    in_range += (k >= 3 && k <= 5);
  }
  EXPECT_NEAR(sum / n, 0.5, 0.01);
  EXPECT_NEAR(sum_sq / n - 0.25, 1.0 / 12.0, 0.005);
  EXPECT_NEAR(gsum / n, 0.0, 0.02);
  EXPECT_NEAR(gsum_sq / n, 1.0, 0.02);
  EXPECT_EQ(in_range, n);
  double usum = 0.0;
  for (int i = 0; i < n; ++i) usum += UniformFromKey(MakeKey(9, i));
  EXPECT_NEAR(usum / n, 0.5, 0.01);
  // Same key, same stream.
  CounterRng a(5), b(5);
  for (int i = 0; i < 10; ++i) EXPECT_EQ(a.NextU64(), b.NextU64());
}

}  // namespace
}  // namespace sim
}  // namespace multisession_mapper
