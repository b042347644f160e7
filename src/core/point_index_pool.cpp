#include "multisession_mapper/core/point_index_pool.h"

#include <algorithm>
#include <chrono>
#include <string>
#include <utility>

#include "multisession_mapper/core/stopwatch.h"

namespace multisession_mapper {
namespace core {

PointIndexPool::PointIndexPool(std::vector<int> uses,
                               std::function<const PointVector&(std::size_t)> points)
    : points_(std::move(points)) {
  slots_.reserve(uses.size());
  for (int n : uses) {
    auto slot = std::make_unique<Slot>();
    slot->uses = std::max(n, 0);
    slot->remaining = slot->uses;
    slots_.push_back(std::move(slot));
  }
}

StatusOr<PointIndexPool::Lease> PointIndexPool::Acquire(std::size_t k) {
  if (k >= slots_.size()) {
    return Status::Error("point index pool: item " + std::to_string(k) + " of " +
                         std::to_string(slots_.size()));
  }
  Slot& slot = *slots_[k];
  std::lock_guard<std::mutex> lock(slot.mutex);
  if (slot.remaining <= 0) {
    return Status::Error("point index pool: item " + std::to_string(k) + " used more than the " +
                         std::to_string(slot.uses) + " announced times");
  }
  if (!slot.built) {
    slot.built = true;
    const auto start = std::chrono::steady_clock::now();
    StatusOr<PointIndex> index = PointIndex::Create(points_(k));
    slot.build_s = SecondsSince(start);
    if (index.ok()) {
      slot.index = std::make_shared<const PointIndex>(std::move(index.value()));
      std::lock_guard<std::mutex> count_lock(count_mutex_);
      peak_alive_ = std::max(peak_alive_, ++alive_);
    } else {
      slot.error = index.status();
    }
  }
  --slot.remaining;
  if (!slot.error.ok()) return slot.error;
  Lease lease;
  lease.index = slot.index;
  lease.build_share_s = slot.build_s / slot.uses;
  if (slot.remaining == 0) {
    slot.index.reset();
    std::lock_guard<std::mutex> count_lock(count_mutex_);
    --alive_;
  }
  return lease;
}

std::size_t PointIndexPool::alive() const {
  std::lock_guard<std::mutex> lock(count_mutex_);
  return alive_;
}

std::size_t PointIndexPool::peak_alive() const {
  std::lock_guard<std::mutex> lock(count_mutex_);
  return peak_alive_;
}

}  // namespace core
}  // namespace multisession_mapper
