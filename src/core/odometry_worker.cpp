#include "multisession_mapper/core/odometry_worker.h"

#include <utility>

namespace multisession_mapper {
namespace core {

StatusOr<std::unique_ptr<OdometryWorker>> OdometryWorker::Create(const OdometryConfig& config,
                                                                 std::size_t max_pending) {
  if (max_pending < 1) return Status::Error("odometry worker: max_pending must be >= 1");
  StatusOr<Odometry> odometry = Odometry::Create(config);
  if (!odometry.ok()) return odometry.status();
  return std::unique_ptr<OdometryWorker>(
      new OdometryWorker(std::move(odometry.value()), max_pending));
}

OdometryWorker::OdometryWorker(Odometry odometry, std::size_t max_pending)
    : odometry_(std::move(odometry)), max_pending_(max_pending) {
  thread_ = std::thread([this] { Run(); });
}

OdometryWorker::~OdometryWorker() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  changed_.notify_all();
  thread_.join();
}

void OdometryWorker::Push(LidarScan scan) {
  std::unique_lock<std::mutex> lock(mutex_);
  changed_.wait(lock, [this] {
    return input_.size() + in_flight_ < max_pending_;
  });
  input_.push_back(std::move(scan));
  changed_.notify_all();
}

std::optional<StatusOr<OdometryResult>> OdometryWorker::Pop(bool wait) {
  std::unique_lock<std::mutex> lock(mutex_);
  if (wait) {
    changed_.wait(lock, [this] {
      return !output_.empty() || (input_.empty() && in_flight_ == 0);
    });
  }
  if (output_.empty()) return std::nullopt;
  std::optional<StatusOr<OdometryResult>> result(std::move(output_.front()));
  output_.pop_front();
  changed_.notify_all();
  return result;
}

std::size_t OdometryWorker::pending() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return input_.size() + in_flight_ + output_.size();
}

void OdometryWorker::Run() {
  while (true) {
    LidarScan scan;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      changed_.wait(lock, [this] { return stop_ || !input_.empty(); });
      if (input_.empty()) return;  // stop_ and nothing left
      scan = std::move(input_.front());
      input_.pop_front();
      ++in_flight_;
    }
    StatusOr<OdometryResult> result = odometry_.ProcessScan(scan);
    {
      std::lock_guard<std::mutex> lock(mutex_);
      output_.push_back(std::move(result));
      --in_flight_;
    }
    changed_.notify_all();
  }
}

}  // namespace core
}  // namespace multisession_mapper
