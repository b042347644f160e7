#include "multisession_mapper/ros/bag_scan_reader.h"

#include <set>

#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/PointCloud2.h>

#include "multisession_mapper/ros/conversions.h"

namespace multisession_mapper {
namespace conversions {

struct BagScanReader::Impl {
  std::string path;
  std::string topic;
  rosbag::Bag bag;
  std::size_t messages = 0;
  double duration_s = 0.0;
  bool has_frame = false;
  std::string frame_id;  // of the first convertible scan
};

BagScanReader::BagScanReader(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
BagScanReader::BagScanReader(BagScanReader&&) noexcept = default;
BagScanReader& BagScanReader::operator=(BagScanReader&&) noexcept = default;
BagScanReader::~BagScanReader() = default;

core::StatusOr<BagScanReader> BagScanReader::Open(const std::string& bag_path,
                                                  const std::string& topic) {
  auto impl = std::make_unique<Impl>();
  impl->path = bag_path;
  impl->topic = topic;
  try {
    impl->bag.open(bag_path, rosbag::bagmode::Read);
    rosbag::View all(impl->bag);
    std::set<std::string> topics;
    std::string type_on_topic;
    for (const rosbag::ConnectionInfo* info : all.getConnections()) {
      topics.insert(info->topic + " [" + info->datatype + "]");
      if (info->topic == topic) type_on_topic = info->datatype;
    }
    if (type_on_topic.empty()) {
      std::string list;
      for (const std::string& t : topics) list += "\n  " + t;
      return core::Status::Error("bag '" + bag_path + "' has no topic '" + topic +
                                 "'; its topics are:" + (list.empty() ? " (none)" : list));
    }
    if (type_on_topic != "sensor_msgs/PointCloud2") {
      return core::Status::Error("topic '" + topic + "' in '" + bag_path + "' carries " +
                                 type_on_topic + ", expected sensor_msgs/PointCloud2");
    }
    rosbag::View view(impl->bag, rosbag::TopicQuery(topic));
    impl->messages = view.size();
    if (impl->messages > 0) impl->duration_s = (view.getEndTime() - view.getBeginTime()).toSec();
  } catch (const std::exception& e) {
    return core::Status::Error("cannot read bag '" + bag_path + "': " + e.what());
  }
  return BagScanReader(std::move(impl));
}

std::size_t BagScanReader::num_messages() const { return impl_->messages; }
double BagScanReader::duration_s() const { return impl_->duration_s; }
const std::string& BagScanReader::frame_id() const { return impl_->frame_id; }

core::Status BagScanReader::ForEach(
    const std::function<bool(const core::StatusOr<core::LidarScan>&, std::size_t)>& on_scan) {
  std::size_t index = 0;
  try {
    rosbag::View view(impl_->bag, rosbag::TopicQuery(impl_->topic));
    for (const rosbag::MessageInstance& m : view) {
      sensor_msgs::PointCloud2::ConstPtr msg = m.instantiate<sensor_msgs::PointCloud2>();
      core::StatusOr<core::LidarScan> scan =
          msg ? FromPointCloud2(*msg)
              : core::StatusOr<core::LidarScan>(
                    core::Status::Error("message is not a sensor_msgs/PointCloud2"));
      if (scan.ok()) {
        // The first convertible scan fixes the sensor frame; a scan in another frame would be
        // placed as if it were in it (there is no tf offline), so it is refused.
        if (!impl_->has_frame) {
          impl_->frame_id = msg->header.frame_id;
          impl_->has_frame = true;
        } else if (msg->header.frame_id != impl_->frame_id) {
          scan = core::Status::Error("frame_id '" + msg->header.frame_id +
                                     "' differs from the sensor frame '" + impl_->frame_id +
                                     "' of the session's first scan");
        }
      }
      if (!on_scan(scan, index++)) break;
    }
  } catch (const std::exception& e) {
    return core::Status::Error("error reading bag '" + impl_->path + "' at message " +
                               std::to_string(index) + ": " + e.what());
  }
  return core::Status::Ok();
}

BagReadAhead::BagReadAhead(BagScanReader* reader, std::size_t capacity, std::size_t max_scans)
    : scans_(capacity), thread_([this, reader, max_scans] {
        status_ = reader->ForEach(
            [this, max_scans](const core::StatusOr<core::LidarScan>& scan, std::size_t index) {
              if (max_scans > 0 && index >= max_scans) return false;
              return scans_.Push(ReadScan{index, scan});
            });
        scans_.Close();
      }) {}

BagReadAhead::~BagReadAhead() {
  scans_.Close();
  if (thread_.joinable()) thread_.join();
}

core::Status BagReadAhead::Finish() {
  if (thread_.joinable()) thread_.join();
  return status_;
}

}  // namespace conversions
}  // namespace multisession_mapper
