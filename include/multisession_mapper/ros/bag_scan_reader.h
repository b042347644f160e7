// Reads LiDAR scans from a bag with the rosbag C++ API, as fast as the disk allows (no roscore,
// no playback). Opening checks that the topic exists and carries sensor_msgs/PointCloud2, and
// names the topics that do exist when it does not; a truncated or unreadable bag gives an error,
// never a crash. The first convertible scan's frame_id is the sensor frame of the session: a
// later scan in another frame is passed on as an error (skipped by the caller), since offline
// there is no tf to bring it into the sensor frame.
#pragma once

#include <cstddef>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <thread>

#include "multisession_mapper/core/bounded_queue.h"
#include "multisession_mapper/core/status.h"
#include "multisession_mapper/core/types.h"

namespace multisession_mapper {
namespace conversions {

class BagScanReader {
 public:
  static core::StatusOr<BagScanReader> Open(const std::string& bag_path, const std::string& topic);
  BagScanReader(BagScanReader&&) noexcept;
  BagScanReader& operator=(BagScanReader&&) noexcept;
  ~BagScanReader();

  std::size_t num_messages() const;
  /// Time between the first and the last message on the topic [s].
  double duration_s() const;
  /// Sensor frame: frame_id of the first convertible scan (empty before ForEach found one).
  const std::string& frame_id() const;

  /// Calls `on_scan(scan_or_error, index)` for every message in bag time order; a message that
  /// cannot be converted, or whose frame_id differs from the first scan's, is passed as an
  /// error (the caller decides to skip it). Stops early
  /// when `on_scan` returns false. Fails when the bag cannot be read (e.g. truncated).
  core::Status ForEach(
      const std::function<bool(const core::StatusOr<core::LidarScan>&, std::size_t)>& on_scan);

 private:
  struct Impl;
  explicit BagScanReader(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

/// A scan read from a bag (or why it could not be used) with its index in the bag.
struct ReadScan {
  std::size_t index = 0;
  core::StatusOr<core::LidarScan> scan;
};

/// Reads a bag (BagScanReader::ForEach) on a thread of its own, `capacity` scans ahead of the
/// thread that takes them with Next: the offline runner's thread that builds the submaps, the
/// critical path of a whole run (reading and converting took ~3 s of it per campus session).
/// Destroying it stops the reading and joins the thread; the reader must outlive it.
class BagReadAhead {
 public:
  /// Reads the first `max_scans` messages (0: all).
  BagReadAhead(BagScanReader* reader, std::size_t capacity, std::size_t max_scans);
  ~BagReadAhead();
  BagReadAhead(const BagReadAhead&) = delete;
  BagReadAhead& operator=(const BagReadAhead&) = delete;

  /// The next scan in bag order: if read already (wait = false) or once it is (wait = true);
  /// nullopt with wait once the reading ended (the bag's end, max_scans, or an error that
  /// Finish returns).
  std::optional<ReadScan> Next(bool wait) { return scans_.Pop(wait); }
  /// Waits for the reading to end; its outcome (an error for an unreadable bag).
  core::Status Finish();

 private:
  core::BoundedQueue<ReadScan> scans_;
  core::Status status_ = core::Status::Ok();  // written by the thread, read after the join
  std::thread thread_;                         // last: starts once the members above exist
};

}  // namespace conversions
}  // namespace multisession_mapper
