// A first-in first-out queue between one producing and one consuming thread, with a bound on
// the items it holds: the producer waits while it is full. The offline runner reads and
// converts the bag's scans on a thread of its own into one (the thread that builds the
// submaps is the critical path of a whole run, and reading took ~3 s of it per campus
// session); the consumer takes them in bag order.
//
// Close() ends the stream: Push refuses items from then on (so a producer that waits on a full
// queue is released when the consumer gives up), and Pop(true) returns nullopt once the items
// still queued are taken. All members are thread-safe.
#pragma once

#include <algorithm>
#include <condition_variable>
#include <cstddef>
#include <deque>
#include <mutex>
#include <optional>
#include <utility>

namespace multisession_mapper {
namespace core {

template <typename T>
class BoundedQueue {
 public:
  /// `capacity` (>= 1; 0 is taken as 1): items queued before Push waits.
  explicit BoundedQueue(std::size_t capacity) : capacity_(std::max<std::size_t>(capacity, 1)) {}
  BoundedQueue(const BoundedQueue&) = delete;
  BoundedQueue& operator=(const BoundedQueue&) = delete;

  /// Appends an item, waiting while the queue is full; false (the item is dropped) once the
  /// queue is closed.
  bool Push(T item) {
    std::unique_lock<std::mutex> lock(mutex_);
    changed_.wait(lock, [this] { return closed_ || items_.size() < capacity_; });
    if (closed_) return false;
    items_.push_back(std::move(item));
    changed_.notify_all();
    return true;
  }

  /// The oldest item: if there is one now (wait = false), or once one arrives (wait = true).
  /// nullopt without wait when the queue is empty; with wait only when it is closed and empty.
  std::optional<T> Pop(bool wait) {
    std::unique_lock<std::mutex> lock(mutex_);
    if (wait) changed_.wait(lock, [this] { return closed_ || !items_.empty(); });
    if (items_.empty()) return std::nullopt;
    std::optional<T> item(std::move(items_.front()));
    items_.pop_front();
    changed_.notify_all();
    return item;
  }

  /// No more items: wakes a waiting producer (its Push returns false) and a waiting consumer.
  void Close() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      closed_ = true;
    }
    changed_.notify_all();
  }

 private:
  const std::size_t capacity_;
  std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<T> items_;
  bool closed_ = false;
};

}  // namespace core
}  // namespace multisession_mapper
