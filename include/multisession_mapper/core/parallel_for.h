// A minimal parallel loop for independent work items (submap pair registrations, dynamic
// detections) on a fixed number of std::threads. Items are handed out one at a time, so long
// and short items balance; body(i) must not touch state shared with other items.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <thread>
#include <vector>

namespace multisession_mapper {
namespace core {

/// Runs body(i) for every i in [0, n) on up to `threads` threads (1: in the calling thread).
template <typename Body>
void ParallelFor(std::size_t n, int threads, const Body& body) {
  const std::size_t workers =
      std::max<std::size_t>(1, std::min<std::size_t>(static_cast<std::size_t>(std::max(threads, 1)), n));
  if (workers <= 1) {
    for (std::size_t i = 0; i < n; ++i) body(i);
    return;
  }
  std::atomic<std::size_t> next{0};
  std::vector<std::thread> pool;
  pool.reserve(workers);
  for (std::size_t w = 0; w < workers; ++w) {
    pool.emplace_back([&] {
      for (std::size_t i = next++; i < n; i = next++) body(i);
    });
  }
  for (std::thread& t : pool) t.join();
}

}  // namespace core
}  // namespace multisession_mapper
