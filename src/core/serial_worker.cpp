#include "multisession_mapper/core/serial_worker.h"

#include <algorithm>
#include <utility>

namespace multisession_mapper {
namespace core {

SerialWorker::SerialWorker(std::size_t max_pending)
    : max_pending_(std::max<std::size_t>(max_pending, 1)), thread_([this] { Run(); }) {}

SerialWorker::~SerialWorker() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  changed_.notify_all();
  thread_.join();
}

void SerialWorker::Post(std::function<void()> task) {
  std::unique_lock<std::mutex> lock(mutex_);
  changed_.wait(lock, [this] { return queue_.size() + running_ < max_pending_; });
  queue_.push_back(std::move(task));
  changed_.notify_all();
}

void SerialWorker::Wait() {
  std::unique_lock<std::mutex> lock(mutex_);
  changed_.wait(lock, [this] { return queue_.empty() && running_ == 0; });
}

void SerialWorker::Run() {
  std::unique_lock<std::mutex> lock(mutex_);
  for (;;) {
    changed_.wait(lock, [this] { return stop_ || !queue_.empty(); });
    if (queue_.empty()) return;  // stop_ and nothing left to run
    std::function<void()> task = std::move(queue_.front());
    queue_.pop_front();
    running_ = 1;
    lock.unlock();
    task();
    lock.lock();
    running_ = 0;
    changed_.notify_all();
  }
}

}  // namespace core
}  // namespace multisession_mapper
