// Reads LiDAR scans from a bag with the rosbag C++ API, as fast as the disk allows (no roscore,
// no playback). Opening checks that the topic exists and carries sensor_msgs/PointCloud2, and
// names the topics that do exist when it does not; a truncated or unreadable bag gives an error,
// never a crash.
#pragma once

#include <cstddef>
#include <functional>
#include <memory>
#include <string>

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

  /// Calls `on_scan(scan_or_error, index)` for every message in bag time order; a message that
  /// cannot be converted is passed as an error (the caller decides to skip it). Stops early
  /// when `on_scan` returns false. Fails when the bag cannot be read (e.g. truncated).
  core::Status ForEach(
      const std::function<bool(const core::StatusOr<core::LidarScan>&, std::size_t)>& on_scan);

 private:
  struct Impl;
  explicit BagScanReader(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace conversions
}  // namespace multisession_mapper
