#include "multisession_mapper/core/worker_pool.h"

#include <atomic>
#include <chrono>
#include <cstddef>
#include <thread>
#include <utility>
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

// A pool made for one Run (the wall normals make one per submap) must share that very
// first Run: its helpers start while the Run is already handing out items. Each pool's two
// items wait (up to 2 s) for each other, which only two threads running at once can see.
TEST(WorkerPoolTest, HelpersJoinTheRunRightAfterTheConstructor) {
  int runs_in_parallel = 0;
  constexpr int kPools = 10;
  for (int p = 0; p < kPools; ++p) {
    WorkerPool pool(2);
    std::atomic<int> started{0};
    std::atomic<int> saw_partner{0};  // items that saw the other one start while waiting
    pool.Run(2, [&](std::size_t) {
      ++started;
      const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(1);
      while (started.load() < 2 && std::chrono::steady_clock::now() < deadline) {
        std::this_thread::yield();
      }
      if (started.load() == 2) ++saw_partner;
    });
    if (saw_partner.load() == 2) ++runs_in_parallel;
  }
  EXPECT_EQ(runs_in_parallel, kPools);
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

// Blocks tile [begin, end) exactly, on the pool; without a pool, or with one block, the caller
// runs the whole range in one call.
TEST(WorkerPoolTest, RunBlocksTilesTheRange) {
  WorkerPool pool(3);
  std::vector<std::atomic<int>> hits(1000);
  std::atomic<int> calls{0};
  WorkerPool::RunBlocks(&pool, 10, 1000, 64, [&](std::size_t first, std::size_t last) {
    EXPECT_LE(last - first, 64u);
    EXPECT_EQ((first - 10) % 64, 0u);
    for (std::size_t i = first; i < last; ++i) ++hits[i];
    ++calls;
  });
  for (std::size_t i = 0; i < hits.size(); ++i) EXPECT_EQ(hits[i].load(), i >= 10 ? 1 : 0) << i;
  EXPECT_EQ(calls.load(), 16);  // 990 items in blocks of 64
  std::vector<std::pair<std::size_t, std::size_t>> ranges;
  const auto record = [&](std::size_t first, std::size_t last) {
    ranges.emplace_back(first, last);
  };
  WorkerPool::RunBlocks(nullptr, 5, 500, 64, record);
  WorkerPool::RunBlocks(&pool, 5, 40, 64, record);
  WorkerPool::RunBlocks(&pool, 7, 7, 64, record);
  ASSERT_EQ(ranges.size(), 2u);
  EXPECT_EQ(ranges[0], std::make_pair(std::size_t{5}, std::size_t{500}));
  EXPECT_EQ(ranges[1], std::make_pair(std::size_t{5}, std::size_t{40}));
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
