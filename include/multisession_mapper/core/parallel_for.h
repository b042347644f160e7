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

/// Runs body(i) for every i in [0, n) on up to `threads` threads, the calling thread among
/// them (1: only the calling thread).
template <typename Body>
void ParallelFor(std::size_t n, int threads, const Body& body) {
  const std::size_t workers =
      std::max<std::size_t>(1, std::min<std::size_t>(static_cast<std::size_t>(std::max(threads, 1)), n));
  if (workers <= 1) {
    for (std::size_t i = 0; i < n; ++i) body(i);
    return;
  }
  std::atomic<std::size_t> next{0};
  const auto work = [&] {
    for (std::size_t i = next++; i < n; i = next++) body(i);
  };
  // The calling thread is one of the workers: one thread start less per call. (Short loops
  // run very often want a WorkerPool instead: no thread start at all.)
  std::vector<std::thread> pool;
  pool.reserve(workers - 1);
  for (std::size_t w = 1; w < workers; ++w) pool.emplace_back(work);
  work();
  for (std::thread& t : pool) t.join();
}

}  // namespace core
}  // namespace multisession_mapper
