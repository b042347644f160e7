// ScanMatchingNodelet: LiDAR odometry (input filter, de-skew, scan-to-map ICP; core::Odometry).
//   in:  points (sensor_msgs/PointCloud2, remap to the driver's topic), finished_session
//        (in-process, from SubmapManager: restart the odometry for the next session)
//   out: odom (nav_msgs/Odometry, odom -> base frame), tf odom -> base frame (REP-105;
//        sensor extrinsic from the `base_to_sensor` parameter), registered_points (the
//        de-skewed scan in the sensor frame, only while subscribed), registered_scan
//        (in-process, zero-copy: the core OdometryResult for SubmapManagerNodelet).
//   dynamic_reconfigure: cfg/ScanMatching.cfg (initial values from the `config` YAML).
// Threading / ownership: every callback (points, finished_session, dynamic_reconfigure) runs
// on this nodelet's single-threaded queue (getNodeHandle / getPrivateNodeHandle); mutex_
// additionally guards odometry_, config_, the scan counters, the session index and
// sensor_frame_ against onInit (the reconfigure server calls back from onInit). Published
// OdometryResults are immutable once published (shared_ptr<const>).
// Sessions: when SubmapManager has finished a session, the odometry restarts at the identity
// (the next session's frame is its first scan's sensor frame, as for the first session), with
// no previous stamp (a bag played again starts at earlier stamps) and no sensor frame yet;
// each registered scan carries the index of its session.
// Bad input: a cloud that cannot be converted (no x/y/z, truncated data, big-endian), one
// without a usable point, with a stamp not after the previous one, or with another frame_id
// than the first scan's is skipped with a (throttled) warning naming the problem; mapping
// goes on with the next scan. After a gap longer than odometry.max_scan_gap_s the motion model
// is reset. Test: launch/test/bad_input.test.
#include <memory>
#include <mutex>

#include <dynamic_reconfigure/server.h>
#include <nav_msgs/Odometry.h>
#include <nodelet/nodelet.h>
#include <pluginlib/class_list_macros.hpp>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_eigen/tf2_eigen.h>
#include <tf2_ros/transform_broadcaster.h>

#include "multisession_mapper/core/odometry.h"
#include "multisession_mapper/nodelets/in_process_messages.h"
#include "multisession_mapper/nodelets/nodelet_common.h"
#include "multisession_mapper/ros/conversions.h"
#include "multisession_mapper/ros/parameter_mapping.h"

namespace multisession_mapper {
namespace nodelets {

class ScanMatchingNodelet : public nodelet::Nodelet {
 private:
  void onInit() override {
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    core::PipelineConfig pipeline;
    std::string path;
    if (!LoadConfigParam(pnh, &pipeline, &path) || !BaseToSensorParam(pnh, &T_base_sensor_)) {
      NODELET_FATAL("ScanMatching: bad parameters, not started");
      return;
    }
    config_ = pipeline.session.odometry;
    frames_ = FramesParam(pnh);
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (!Restart(core::Pose3::Identity())) return;
    }
    ScanMatchingConfig initial = ros_params::ToScanMatchingConfig(config_);
    server_ = StartReconfigureServer(
        reconfigure_mutex_, pnh, initial,
        [this](ScanMatchingConfig& c, uint32_t) { Reconfigure(&c); });

    tf_broadcaster_ = std::make_unique<tf2_ros::TransformBroadcaster>();
    odom_pub_ = nh.advertise<nav_msgs::Odometry>("odom", 100);
    points_pub_ = nh.advertise<sensor_msgs::PointCloud2>("registered_points", 10);
    scan_pub_ = nh.advertise<RegisteredScan>("registered_scan", 200);
    points_sub_ = nh.subscribe("points", 200, &ScanMatchingNodelet::OnPoints, this);
    finished_sub_ = nh.subscribe("finished_session", 2, &ScanMatchingNodelet::OnSessionFinished, this);
    NODELET_INFO_STREAM("ScanMatching: config " << (path.empty() ? "(defaults)" : path)
                        << ", frames " << frames_.odom << " -> " << frames_.base);
  }

  bool Restart(const core::Pose3& pose) {
    core::StatusOr<core::Odometry> odometry = core::Odometry::Create(config_, pose);
    if (!odometry.ok()) {
      NODELET_ERROR_STREAM("ScanMatching: " << odometry.status().message());
      return false;
    }
    odometry_ = std::make_unique<core::Odometry>(std::move(odometry.value()));
    return true;
  }

  // A refused change leaves the configuration as it was, and `*c` shows it (the server sends
  // `*c` back to the client and keeps it as its current configuration).
  void Reconfigure(ScanMatchingConfig* c) {
    std::lock_guard<std::mutex> lock(mutex_);
    core::OdometryConfig changed = config_;
    ros_params::ApplyScanMatchingConfig(*c, &changed);
    const core::Status valid = changed.Validate();
    if (!valid.ok()) {
      NODELET_WARN_STREAM("ScanMatching: reconfigure refused: " << valid.message());
      *c = ros_params::ToScanMatchingConfig(config_);
      return;
    }
    if (!odometry_ || session_scans_ == 0) {
      config_ = changed;
      if (odometry_) Restart(core::Pose3::Identity());
      return;
    }
    const core::OdometryConfig old = config_;
    config_ = changed;
    // core::Odometry takes its configuration at creation: restart it at the current pose (the
    // local map is rebuilt from the next scans).
    if (Restart(odometry_->pose())) {
      NODELET_INFO("ScanMatching: reconfigured (range %.2f-%.2f m, voxels %.2f/%.2f m, gap %.2f s); "
                   "odometry restarted at the current pose from the next scan",
                   config_.input_filter.min_range_m, config_.input_filter.max_range_m,
                   config_.map_voxel_size_m, config_.registration_voxel_size_m,
                   config_.max_scan_gap_s);
    } else {
      config_ = old;
      *c = ros_params::ToScanMatchingConfig(config_);
    }
  }

  // SubmapManager finished session `index`: the odometry of the next one starts afresh.
  void OnSessionFinished(const boost::shared_ptr<const FinishedSession>& finished) {
    std::lock_guard<std::mutex> lock(mutex_);
    session_index_ = finished->index + 1;
    session_scans_ = 0;
    sensor_frame_.clear();
    if (Restart(core::Pose3::Identity())) {
      NODELET_INFO("ScanMatching: session '%s' finished: odometry restarted for the next session",
                   finished->session.c_str());
    }
  }

  void OnPoints(const sensor_msgs::PointCloud2::ConstPtr& msg) {
    const ros::WallTime start = ros::WallTime::now();
    core::StatusOr<core::LidarScan> scan = conversions::FromPointCloud2(*msg);
    if (!scan.ok()) {
      NODELET_WARN_STREAM_THROTTLE(5.0, "ScanMatching: scan skipped: " << scan.status().message());
      return;
    }
    std::shared_ptr<core::OdometryResult> result;
    std::uint32_t session_index = 0;
    std::size_t scans = 0;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (!odometry_) return;
      if (sensor_frame_.empty()) sensor_frame_ = msg->header.frame_id;
      if (msg->header.frame_id != sensor_frame_) {
        NODELET_WARN_STREAM_THROTTLE(5.0, "ScanMatching: scan skipped: frame_id '"
                                              << msg->header.frame_id << "' is not the sensor frame '"
                                              << sensor_frame_ << "' of the first scan");
        return;
      }
      core::StatusOr<core::OdometryResult> r = odometry_->ProcessScan(scan.value());
      if (!r.ok()) {
        NODELET_WARN_STREAM_THROTTLE(5.0, "ScanMatching: scan skipped: " << r.status().message());
        return;
      }
      scans = ++scans_;
      ++session_scans_;
      session_index = session_index_;
      result = std::make_shared<core::OdometryResult>(std::move(r.value()));
    }
    const std::string sensor_frame = msg->header.frame_id;
    // odom frame = base frame at the first scan: T_odom_base = T_bs * T_odomS_sensor * T_bs^-1.
    const core::Pose3 T_odom_base = T_base_sensor_ * result->pose * T_base_sensor_.inverse();
    boost::shared_ptr<RegisteredScan> out = boost::make_shared<RegisteredScan>();
    out->header = msg->header;
    out->odometry = result;
    out->session_index = session_index;
    scan_pub_.publish(out);

    nav_msgs::Odometry odom;
    odom.header.stamp = msg->header.stamp;
    odom.header.frame_id = frames_.odom;
    odom.child_frame_id = frames_.base;
    odom.pose.pose = conversions::ToPoseMsg(T_odom_base);
    odom_pub_.publish(odom);
    geometry_msgs::TransformStamped tf = tf2::eigenToTransform(T_odom_base);
    tf.header = odom.header;
    tf.child_frame_id = frames_.base;
    tf_broadcaster_->sendTransform(tf);
    if (points_pub_.getNumSubscribers() > 0) {
      sensor_msgs::PointCloud2Ptr cloud = boost::make_shared<sensor_msgs::PointCloud2>(
          conversions::ToPointCloud2(result->deskewed_scan, sensor_frame));
      cloud->header.stamp = msg->header.stamp;
      points_pub_.publish(cloud);
    }
    const double latency_ms = (ros::WallTime::now() - start).toSec() * 1e3;
    NODELET_DEBUG("ScanMatching: scan %.3f in %.1f ms (odometry %.1f ms)%s",
                  msg->header.stamp.toSec(), latency_ms, result->timing.total_ms,
                  result->registered ? "" : " (not registered)");
    if (scans % 100 == 0) {
      NODELET_INFO("ScanMatching: %zu scans, last %.1f ms per scan", scans, latency_ms);
    }
  }

  std::mutex mutex_;
  boost::recursive_mutex reconfigure_mutex_;
  std::unique_ptr<dynamic_reconfigure::Server<ScanMatchingConfig>> server_;
  core::OdometryConfig config_;
  std::unique_ptr<core::Odometry> odometry_;
  std::size_t scans_ = 0;          ///< registered since the start of the manager
  std::size_t session_scans_ = 0;  ///< registered by the current odometry's session
  std::uint32_t session_index_ = 0;  ///< see RegisteredScan::session_index
  std::string sensor_frame_;  ///< frame_id of the session's first scan; others are refused
  core::Pose3 T_base_sensor_ = core::Pose3::Identity();
  Frames frames_;
  ros::Subscriber points_sub_, finished_sub_;
  ros::Publisher odom_pub_, points_pub_, scan_pub_;
  std::unique_ptr<tf2_ros::TransformBroadcaster> tf_broadcaster_;
};

}  // namespace nodelets
}  // namespace multisession_mapper

PLUGINLIB_EXPORT_CLASS(multisession_mapper::nodelets::ScanMatchingNodelet, nodelet::Nodelet)
