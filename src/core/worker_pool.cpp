#include "multisession_mapper/core/worker_pool.h"

#include <algorithm>
#include <atomic>

namespace multisession_mapper {
namespace core {

struct WorkerPool::Job {
  std::size_t n = 0;
  const std::function<void(std::size_t)>* body = nullptr;
  std::atomic<std::size_t> next{0};

  void Work() {
    for (std::size_t i = next++; i < n; i = next++) (*body)(i);
  }
};

WorkerPool::WorkerPool(int threads) {
  for (int t = 1; t < threads; ++t) helpers_.emplace_back([this] { HelperLoop(); });
}

void WorkerPool::RunBlocks(WorkerPool* pool, std::size_t begin, std::size_t end,
                           std::size_t block,
                           const std::function<void(std::size_t, std::size_t)>& body) {
  if (begin >= end) return;
  const std::size_t blocks = (end - begin + block - 1) / block;
  if (pool == nullptr || blocks == 1) {
    body(begin, end);
    return;
  }
  pool->Run(blocks, [&](std::size_t b) {
    body(begin + b * block, std::min(end, begin + (b + 1) * block));
  });
}

WorkerPool::~WorkerPool() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  work_cv_.notify_all();
  for (std::thread& helper : helpers_) helper.join();
}

void WorkerPool::HelperLoop() {
  std::unique_lock<std::mutex> lock(mutex_);
  // Generation 0 is the constructor's, not what generation_ holds when this thread gets to
  // run: a Run right after the constructor often bumps it first, and a helper that took
  // that as seen slept through the Run (a pool made for one Run, as the wall normals' per
  // submap, then ran it on the caller alone).
  std::uint64_t seen = 0;
  while (true) {
    work_cv_.wait(lock, [&] { return stop_ || generation_ != seen; });
    if (stop_) return;
    seen = generation_;
    // A helper that wakes after its Run has finished finds no job and waits again.
    Job* job = job_;
    if (job == nullptr) continue;
    ++busy_;
    lock.unlock();
    job->Work();
    lock.lock();
    if (--busy_ == 0) done_cv_.notify_all();
  }
}

void WorkerPool::Run(std::size_t n, const std::function<void(std::size_t)>& body) {
  std::lock_guard<std::mutex> run_lock(run_mutex_);
  if (helpers_.empty() || n <= 1) {
    for (std::size_t i = 0; i < n; ++i) body(i);
    return;
  }
  Job job;
  job.n = n;
  job.body = &body;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    job_ = &job;
    ++generation_;
  }
  work_cv_.notify_all();
  job.Work();
  std::unique_lock<std::mutex> lock(mutex_);
  job_ = nullptr;  // helpers not yet started on it will not start
  done_cv_.wait(lock, [&] { return busy_ == 0; });
}

}  // namespace core
}  // namespace multisession_mapper
