// Runs an Odometry on its own thread so that the odometry of scan k+1 overlaps the submap
// building and place recognition of scan k (the offline runner's pipeline: the first 1500
// campus s00 scans in 75-80 s against 101-107 s with `offline_mapper --sequential`, idle
// 2-core machine, two runs each). Results
// come back in input order and are exactly those of Odometry::ProcessScan called in the same
// order.
//
// Ownership: the Odometry and the queues belong to this object; the worker thread touches
// the Odometry only, and the queues only under mutex_. Push/Pop/pending are called from one
// (the owner's) thread.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>

#include "multisession_mapper/core/odometry.h"
#include "multisession_mapper/core/status.h"
#include "multisession_mapper/core/types.h"

namespace multisession_mapper {
namespace core {

class OdometryWorker {
 public:
  /// `max_pending`: scans queued or being processed before Push blocks (bounds the memory;
  /// results waiting to be popped do not count, so the owner may push before it pops).
  static StatusOr<std::unique_ptr<OdometryWorker>> Create(const OdometryConfig& config,
                                                          std::size_t max_pending = 4);
  ~OdometryWorker();
  OdometryWorker(const OdometryWorker&) = delete;
  OdometryWorker& operator=(const OdometryWorker&) = delete;

  /// Queues a scan; blocks while max_pending scans wait for or are in the odometry.
  void Push(LidarScan scan);
  /// The next result in input order when it is ready (wait = false) or once it is
  /// (wait = true); nullopt when none is pending (or, without wait, not ready yet).
  std::optional<StatusOr<OdometryResult>> Pop(bool wait);
  /// Scans pushed whose result was not popped yet.
  std::size_t pending() const;

 private:
  explicit OdometryWorker(Odometry odometry, std::size_t max_pending);
  void Run();

  Odometry odometry_;
  const std::size_t max_pending_;
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<LidarScan> input_;
  std::deque<StatusOr<OdometryResult>> output_;
  std::size_t in_flight_ = 0;  // taken by the worker, result not in output_ yet
  bool stop_ = false;
  std::thread thread_;
};

}  // namespace core
}  // namespace multisession_mapper
