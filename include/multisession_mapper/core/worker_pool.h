// A fixed set of threads for short parallel loops that run very often (the ICP's
// correspondence search, ~17 times per scan): ParallelFor starts its threads per call, and a
// thread start (~0.1 ms here) is as long as half a search, so the started thread found the
// work already done. The pool's threads wait on a condition variable between loops.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace multisession_mapper {
namespace core {

class WorkerPool {
 public:
  /// `threads` - 1 threads are started (the caller of Run is the last one); threads <= 1
  /// starts none and Run loops on the calling thread.
  explicit WorkerPool(int threads);
  ~WorkerPool();
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  /// Threads that work in Run, the caller included.
  int threads() const { return static_cast<int>(helpers_.size()) + 1; }

  /// Runs body(i) for every i in [0, n) on the pool's threads and the calling thread, items
  /// handed out one at a time; returns when all are done. body must not throw and must not
  /// touch state shared with other items. Calls from several threads are served one after
  /// the other.
  void Run(std::size_t n, const std::function<void(std::size_t)>& body);

  /// body(first, last) for the blocks [first, last) of `block` items that [begin, end) splits
  /// into, on `pool`; on the calling thread alone, in order, when `pool` is null or there is
  /// one block. The same rules for body as Run's.
  static void RunBlocks(WorkerPool* pool, std::size_t begin, std::size_t end, std::size_t block,
                        const std::function<void(std::size_t, std::size_t)>& body);

 private:
  struct Job;
  void HelperLoop();

  std::mutex run_mutex_;  // one Run at a time
  std::mutex mutex_;      // guards the fields below
  std::condition_variable work_cv_;
  std::condition_variable done_cv_;
  std::uint64_t generation_ = 0;  // incremented per Run
  Job* job_ = nullptr;            // the current Run's job while it hands out work
  int busy_ = 0;                  // helpers working on job_
  bool stop_ = false;
  std::vector<std::thread> helpers_;
};

}  // namespace core
}  // namespace multisession_mapper
