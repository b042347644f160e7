#include "multisession_mapper/core/worker_pool.h"

#include <atomic>
#include <chrono>
#include <cstddef>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

namespace multisession_mapper {
namespace core {
namespace {

TEST(WorkerPoolTest, RunsEveryItemExactlyOnceOverManyRuns) {
  WorkerPool pool(3);
  EXPECT_EQ(pool.threads(), 3);
  for (std::size_t n : {0u, 1u, 2u, 7u, 1000u}) {
    for (int run = 0; run < 200; ++run) {
      std::vector<int> hits(n, 0);  // each item written by exactly one thread
      pool.Run(n, [&](std::size_t i) { ++hits[i]; });
      for (std::size_t i = 0; i < n; ++i) ASSERT_EQ(hits[i], 1) << "n " << n << " item " << i;
    }
  }
}

TEST(WorkerPoolTest, HelpersShareTheWork) {
  WorkerPool pool(2);
  std::atomic<int> by_caller{0};
  const std::thread::id caller = std::this_thread::get_id();
  int runs_shared = 0;
  for (int run = 0; run < 50 && runs_shared == 0; ++run) {
    std::atomic<int> by_helper{0};
    pool.Run(64, [&](std::size_t) {
      // Long enough items that the helper wakes before the caller has done them all.
      std::this_thread::sleep_for(std::chrono::microseconds(200));
      (std::this_thread::get_id() == caller ? by_caller : by_helper)++;
    });
    if (by_helper > 0) ++runs_shared;
  }
  EXPECT_GT(runs_shared, 0);
  EXPECT_GT(by_caller.load(), 0);
}

TEST(WorkerPoolTest, OneThreadRunsOnTheCaller) {
  WorkerPool pool(1);
  EXPECT_EQ(pool.threads(), 1);
  const std::thread::id caller = std::this_thread::get_id();
  int others = 0;
  pool.Run(100, [&](std::size_t) { others += std::this_thread::get_id() != caller; });
  EXPECT_EQ(others, 0);
}

TEST(WorkerPoolTest, RunsFromSeveralThreadsTakeTurns) {
  WorkerPool pool(2);
  std::vector<std::thread> callers;
  std::atomic<long> total{0};
  for (int c = 0; c < 3; ++c) {
    callers.emplace_back([&] {
      for (int run = 0; run < 100; ++run) {
        std::vector<int> items(50, 0);
        pool.Run(items.size(), [&](std::size_t i) { items[i] = static_cast<int>(i); });
        long sum = 0;
        for (int v : items) sum += v;
        total += sum;
      }
    });
  }
  for (std::thread& t : callers) t.join();
  EXPECT_EQ(total.load(), 3L * 100L * (49L * 50L / 2L));
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
