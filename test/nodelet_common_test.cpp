// The nodelets' shared helpers that need no running ROS master.
#include "multisession_mapper/nodelets/nodelet_common.h"

#include <cstring>
#include <memory>
#include <thread>

#include <gtest/gtest.h>

namespace multisession_mapper {
namespace nodelets {
namespace {

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
constexpr bool kAllocatorReplaced = true;  // the sanitizer's allocator, not glibc's arenas
#else
constexpr bool kAllocatorReplaced = false;
#endif

TEST(NodeletCommon, SessionNameAppendsTheRunIndexFromTheSecondSession) {
  EXPECT_EQ(SessionName("day3", 0), "day3");
  EXPECT_EQ(SessionName("day3", 1), "day3_2");
  EXPECT_EQ(SessionName("", 0).rfind("session_", 0), 0u);
}

// The live heap that scripts/stress.sh checks for leaks counts the allocations of every thread
// (glibc gives each thread its own arena) and falls back when they are freed.
TEST(NodeletCommon, HeapInUseFollowsAllocationsOfAnyThread) {
#ifndef __GLIBC__
  GTEST_SKIP() << "HeapInUseBytes reads glibc's allocator";
#endif
  if (kAllocatorReplaced) GTEST_SKIP() << "a sanitizer replaces glibc's allocator";
  constexpr std::size_t kBlock = 64 * 1024;  // below the mmap threshold: an arena chunk
  constexpr int kBlocks = 800;                // 50 MB
  const std::size_t before = HeapInUseBytes();
  std::unique_ptr<std::unique_ptr<char[]>[]> blocks(new std::unique_ptr<char[]>[kBlocks]);
  std::thread worker([&] {
    for (int i = 0; i < kBlocks; ++i) {
      blocks[i].reset(new char[kBlock]);
      std::memset(blocks[i].get(), 1, kBlock);
    }
  });
  worker.join();
  const std::size_t during = HeapInUseBytes();
  EXPECT_GE(during, before + kBlocks * kBlock);
  blocks.reset();
  ReleaseFreeHeap();
  const std::size_t after = HeapInUseBytes();
  EXPECT_LT(after, during - kBlocks * kBlock / 2);
}

}  // namespace
}  // namespace nodelets
}  // namespace multisession_mapper
