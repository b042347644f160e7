// One thread that runs posted tasks one after the other, in the order they were posted: a
// pipeline stage off its owner's thread. The offline runner computes the place descriptors of
// the registered scans on one (the thread that builds the submaps is the critical path of a
// whole run), so that they come out in scan order as if computed in place.
//
// Ownership: the tasks run on the worker thread only; the owner must not touch what a
// pending task touches until Wait() returns. Post and Wait are thread-safe; tasks run in the
// order their Post calls returned. A task must not call Post or Wait (it would wait for
// itself), and no thread may still be in Post when the worker is destroyed.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <functional>
#include <mutex>
#include <thread>

namespace multisession_mapper {
namespace core {

class SerialWorker {
 public:
  /// `max_pending` (>= 1): tasks queued or running before Post blocks (bounds the memory the
  /// tasks hold).
  explicit SerialWorker(std::size_t max_pending);
  /// Runs the tasks still queued, then stops the thread.
  ~SerialWorker();
  SerialWorker(const SerialWorker&) = delete;
  SerialWorker& operator=(const SerialWorker&) = delete;

  /// Queues a task; blocks while max_pending tasks wait or run. The task must not throw.
  void Post(std::function<void()> task);
  /// Returns once every posted task has run.
  void Wait();

 private:
  void Run();

  const std::size_t max_pending_;
  std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<std::function<void()>> queue_;
  std::size_t running_ = 0;  // 1 while a task runs
  bool stop_ = false;
  std::thread thread_;
};

}  // namespace core
}  // namespace multisession_mapper
