// Neighbour indices (PointIndex) of many point sets, each built once on first use and shared by
// all its users, then freed after its last use. The merge's dynamic detection pairs every
// history submap with one to several current submaps; with the pool each history submap's
// index is built once instead of once per pair, and since the pairs come in the order of the
// current session's submaps, only the indices of the submaps near the one being processed are
// alive at a time. Thread-safe: users of different items never wait for each other, users of
// the same item wait while it is built.
#pragma once

#include <cstddef>
#include <functional>
#include <memory>
#include <mutex>
#include <vector>

#include "multisession_mapper/core/point_index.h"
#include "multisession_mapper/core/status.h"
#include "multisession_mapper/core/types.h"

namespace multisession_mapper {
namespace core {

class PointIndexPool {
 public:
  /// One item per entry of `uses`: uses[k] is how many times Acquire(k) will be called (0: the
  /// item is never built). `points(k)` gives item k's points; they must outlive the pool.
  PointIndexPool(std::vector<int> uses, std::function<const PointVector&(std::size_t)> points);

  struct Lease {
    std::shared_ptr<const PointIndex> index;  ///< valid as long as the lease is held
    /// This use's share of the construction time: build seconds / uses[k] [s].
    double build_share_s = 0.0;
  };
  /// The index of item k, built by the first call; the pool lets go of it at the last of the
  /// announced uses (the lease keeps it alive until dropped). An error of the construction (a
  /// non-finite point) is returned to every use of the item; a use beyond the announced number
  /// or an item out of range is an error.
  StatusOr<Lease> Acquire(std::size_t k);

  /// Items whose index is held by the pool now, and the most held at any one time.
  std::size_t alive() const;
  std::size_t peak_alive() const;

 private:
  struct Slot {
    std::mutex mutex;
    std::shared_ptr<const PointIndex> index;
    Status error = Status::Ok();
    bool built = false;
    int uses = 0;
    int remaining = 0;
    double build_s = 0.0;
  };
  std::function<const PointVector&(std::size_t)> points_;
  std::vector<std::unique_ptr<Slot>> slots_;
  mutable std::mutex count_mutex_;
  std::size_t alive_ = 0;
  std::size_t peak_alive_ = 0;
};

}  // namespace core
}  // namespace multisession_mapper
