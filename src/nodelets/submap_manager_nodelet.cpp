// SubmapManagerNodelet: submaps with in-session dynamic filtering, intra-session loops and the
// pose graph (core::SessionMapper, split path: the odometry ran in ScanMatchingNodelet).
//   in:  registered_scan (in-process), finish_request (std_msgs/String, from MapMergingNodelet)
//   out: submaps (SubmapInfo, each finished submap; all again when the graph moved),
//        submap_cloud (latched, finished submaps in the map frame, only while subscribed),
//        path (nav_msgs/Path, optimised, only while subscribed), intra_loops
//        (LoopCandidateArray, latched), tf map -> odom, scan_in_submap and finished_session
//        (in-process, for PlaceRecognitionNodelet and MapMergingNodelet).
//   During mapping the map frame is the session frame (the sensor at the first scan, moved to
//   the base frame by base_to_sensor); MapMergingNodelet aligns it with the stored map.
//   dynamic_reconfigure: cfg/SubmapManager.cfg (initial values from the `config` YAML).
// Threading / ownership: every callback (registered_scan, finish_request, dynamic_reconfigure)
// runs on this nodelet's single-threaded queue; mutex_ guards mapper_, config_ and the
// session bookkeeping additionally against onInit. A finished SessionResult is handed over as
// shared_ptr<const> and never touched here again.
// Sessions: after a finish the next session (name "<session>_<n>") starts in the same process.
// finished_session tells ScanMatching to restart its odometry; a registered scan carries the
// index of the session its odometry belongs to, and scans of an earlier session's odometry
// (in flight while the session was finished) are dropped, not mapped in the wrong frame.
#include <memory>
#include <mutex>

#include <dynamic_reconfigure/server.h>
#include <multisession_mapper/LoopCandidateArray.h>
#include <multisession_mapper/SubmapInfo.h>
#include <nav_msgs/Path.h>
#include <nodelet/nodelet.h>
#include <pluginlib/class_list_macros.hpp>
#include <std_msgs/String.h>
#include <tf2_eigen/tf2_eigen.h>
#include <tf2_ros/transform_broadcaster.h>

#include "multisession_mapper/core/session_mapper.h"
#include "multisession_mapper/nodelets/in_process_messages.h"
#include "multisession_mapper/nodelets/nodelet_common.h"
#include "multisession_mapper/ros/conversions.h"
#include "multisession_mapper/ros/parameter_mapping.h"

namespace multisession_mapper {
namespace nodelets {

class SubmapManagerNodelet : public nodelet::Nodelet {
 private:
  void onInit() override {
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    core::PipelineConfig pipeline;
    std::string path;
    if (!LoadConfigParam(pnh, &pipeline, &path) || !BaseToSensorParam(pnh, &T_base_sensor_)) {
      NODELET_FATAL("SubmapManager: bad parameters, not started");
      return;
    }
    config_ = pipeline.session;
    frames_ = FramesParam(pnh);
    session_base_ = SearchString(pnh, "session", "");
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (!StartSession()) return;
    }
    SubmapManagerConfig initial = ros_params::ToSubmapManagerConfig(config_);
    server_ = StartReconfigureServer(
        reconfigure_mutex_, pnh, initial,
        [this](SubmapManagerConfig& c, uint32_t) { Reconfigure(&c); });

    tf_broadcaster_ = std::make_unique<tf2_ros::TransformBroadcaster>();
    info_pub_ = nh.advertise<SubmapInfo>("submaps", 100);
    cloud_pub_ = nh.advertise<sensor_msgs::PointCloud2>("submap_cloud", 1, true);
    path_pub_ = nh.advertise<nav_msgs::Path>("path", 1, true);
    loops_pub_ = nh.advertise<LoopCandidateArray>("intra_loops", 1, true);
    scan_pub_ = nh.advertise<ScanInSubmap>("scan_in_submap", 200);
    finished_pub_ = nh.advertise<FinishedSession>("finished_session", 2);
    scan_sub_ = nh.subscribe("registered_scan", 200, &SubmapManagerNodelet::OnScan, this);
    finish_sub_ = nh.subscribe("finish_request", 2, &SubmapManagerNodelet::OnFinish, this);
  }

  bool StartSession() {
    session_ = SessionName(session_base_, session_index_);
    core::StatusOr<core::SessionMapper> mapper = core::SessionMapper::Create(config_, session_);
    if (!mapper.ok()) {
      NODELET_ERROR_STREAM("SubmapManager: " << mapper.status().message());
      return false;
    }
    mapper_ = std::make_unique<core::SessionMapper>(std::move(mapper.value()));
    scans_.clear();
    published_submaps_ = 0;
    published_optimisations_ = 0;
    NODELET_INFO_STREAM("SubmapManager: session '" << session_ << "' started");
    return true;
  }

  // A refused change leaves the configuration as it was, and `*c` shows it (the server sends
  // `*c` back to the client and keeps it as its current configuration).
  void Reconfigure(SubmapManagerConfig* c) {
    std::lock_guard<std::mutex> lock(mutex_);
    core::SessionMapperConfig changed = config_;
    ros_params::ApplySubmapManagerConfig(*c, &changed);
    const core::Status s = mapper_ ? mapper_->UpdateConfig(changed) : changed.Validate();
    if (!s.ok()) {
      NODELET_WARN_STREAM("SubmapManager: reconfigure refused: " << s.message());
      *c = ros_params::ToSubmapManagerConfig(config_);
      return;
    }
    config_ = changed;
    NODELET_INFO("SubmapManager: reconfigured from the next scan: submap %.1f m / %.2f rad, "
                 "voxel %.2f m, dynamics %s, intra loops %s (radius %.1f m, overlap >= %.2f)",
                 config_.submaps.max_translation_m, config_.submaps.max_rotation_rad,
                 config_.submaps.voxel_size_m, config_.submaps.dynamic_filter.enabled ? "on" : "off",
                 config_.intra_loops.enabled ? "on" : "off", config_.intra_loops.search_radius_m,
                 config_.intra_loops.registration.min_overlap_ratio);
  }

  void OnScan(const boost::shared_ptr<const RegisteredScan>& msg) {
    const ros::WallTime start = ros::WallTime::now();
    std::lock_guard<std::mutex> lock(mutex_);
    if (!mapper_ || !msg->odometry) return;
    if (msg->session_index != static_cast<std::uint32_t>(session_index_)) {
      // Registered before ScanMatching restarted its odometry for this session (a scan in
      // flight while the session was finished): its pose is in the finished session's frame.
      NODELET_WARN_STREAM_THROTTLE(5.0, "SubmapManager: scan dropped: registered by the odometry of session index "
                                            << msg->session_index << ", mapping session index "
                                            << session_index_ << " ('" << session_ << "')");
      return;
    }
    const core::Status s = mapper_->AddRegisteredScan(*msg->odometry);
    if (!s.ok()) {
      NODELET_WARN_STREAM_THROTTLE(5.0, "SubmapManager: " << s.message());
      return;
    }
    core::StampedPose sp;
    sp.stamp_s = msg->odometry->stamp_s;
    sp.pose = msg->odometry->pose;
    scans_.push_back(sp);

    boost::shared_ptr<ScanInSubmap> out = boost::make_shared<ScanInSubmap>();
    out->header = msg->header;
    out->session = session_;
    out->submap_id = mapper_->current_submap_id();
    out->odometry = msg->odometry;
    scan_pub_.publish(out);

    // map -> odom (REP-105); map and odom are the base frame at the first scan, the session
    // and odometry frames the sensor frame there: T_map_odom = T_bs * T_session_odomS * T_bs^-1.
    geometry_msgs::TransformStamped tf = tf2::eigenToTransform(
        MapFromSession() * mapper_->SessionFromOdometry() * T_base_sensor_.inverse());
    tf.header.stamp = msg->header.stamp;
    tf.header.frame_id = frames_.map;
    tf.child_frame_id = frames_.odom;
    tf_broadcaster_->sendTransform(tf);

    PublishSubmaps(msg->header.stamp);
    const double ms = (ros::WallTime::now() - start).toSec() * 1e3;
    if (ms > 100.0) NODELET_INFO("SubmapManager: scan %.3f took %.1f ms", msg->header.stamp.toSec(), ms);
  }

  // New submaps (and all of them when the graph moved): SubmapInfo, clouds, path, loops.
  void PublishSubmaps(const ros::Time& stamp) {
    const std::size_t finished = mapper_->num_finished_submaps();
    const bool moved = mapper_->num_optimisations() != published_optimisations_;
    if (finished == published_submaps_ && !moved) return;
    const std::size_t first = moved ? 0 : published_submaps_;
    for (std::size_t id = first; id < finished; ++id) {
      const core::Submap& submap = mapper_->finished_submap(static_cast<std::uint32_t>(id));
      SubmapInfo info;
      info.header.stamp = conversions::ToRosTime(submap.last_stamp_s());
      info.header.frame_id = frames_.map;
      info.session = session_;
      info.id = submap.id;
      info.origin = conversions::ToPoseMsg(MapFromSession() * mapper_->SubmapOrigin(submap.id));
      info.num_scans = static_cast<std::uint32_t>(submap.scans.size());
      info.num_points = static_cast<std::uint32_t>(submap.points.size());
      info.length_m = submap.length_m;
      if (id > 0) info.neighbour_ids.push_back(submap.id - 1);
      if (id + 1 < finished) info.neighbour_ids.push_back(submap.id + 1);
      for (const core::LoopRecord& loop : mapper_->loops()) {
        if (loop.status != core::LoopStatus::kAccepted) continue;
        if (loop.current_submap == submap.id) info.neighbour_ids.push_back(loop.history_submap);
        if (loop.history_submap == submap.id) info.neighbour_ids.push_back(loop.current_submap);
      }
      info_pub_.publish(info);
    }
    published_submaps_ = finished;
    published_optimisations_ = mapper_->num_optimisations();

    LoopCandidateArray loops;
    loops.header.stamp = stamp;
    loops.header.frame_id = frames_.map;
    for (const core::LoopRecord& loop : mapper_->loops()) {
      loops.candidates.push_back(conversions::ToLoopCandidateMsg(loop));
      loops.current_origins.push_back(
          conversions::ToPoseMsg(MapFromSession() * mapper_->SubmapOrigin(loop.current_submap)).position);
      loops.history_origins.push_back(
          conversions::ToPoseMsg(MapFromSession() * mapper_->SubmapOrigin(loop.history_submap)).position);
    }
    loops_pub_.publish(loops);

    if (cloud_pub_.getNumSubscribers() > 0) {
      core::PointVector points;
      for (std::size_t id = 0; id < finished; ++id) {
        const core::Submap& submap = mapper_->finished_submap(static_cast<std::uint32_t>(id));
        const core::Pose3 T = MapFromSession() * mapper_->SubmapOrigin(submap.id);
        for (const Eigen::Vector3d& p : submap.points) points.push_back(T * p);
      }
      cloud_pub_.publish(conversions::ToPointCloud2(points, frames_.map, stamp));
    }
    if (path_pub_.getNumSubscribers() > 0) PublishPath(stamp);
  }

  // Optimised poses of scans in finished submaps, corrected odometry for the rest.
  void PublishPath(const ros::Time& stamp) {
    nav_msgs::Path path;
    path.header.stamp = stamp;
    path.header.frame_id = frames_.map;
    const core::Pose3 T_map_session = MapFromSession();
    double last_stamp = -1.0;
    for (std::size_t id = 0; id < mapper_->num_finished_submaps(); ++id) {
      const core::Submap& submap = mapper_->finished_submap(static_cast<std::uint32_t>(id));
      const core::Pose3 T = T_map_session * mapper_->SubmapOrigin(submap.id);
      for (const core::SubmapScanRecord& scan : submap.scans) {
        if (scan.stamp_s <= last_stamp) continue;  // submaps overlap in time at their ends
        geometry_msgs::PoseStamped ps;
        ps.header.stamp = conversions::ToRosTime(scan.stamp_s);
        ps.header.frame_id = frames_.map;
        ps.pose = conversions::ToPoseMsg(T * scan.T_submap_sensor * T_base_sensor_.inverse());
        path.poses.push_back(ps);
        last_stamp = scan.stamp_s;
      }
    }
    const core::Pose3 correction = T_map_session * mapper_->SessionFromOdometry();
    for (const core::StampedPose& sp : scans_) {
      if (sp.stamp_s <= last_stamp) continue;
      geometry_msgs::PoseStamped ps;
      ps.header.stamp = conversions::ToRosTime(sp.stamp_s);
      ps.header.frame_id = frames_.map;
      ps.pose = conversions::ToPoseMsg(correction * sp.pose * T_base_sensor_.inverse());
      path.poses.push_back(ps);
    }
    path_pub_.publish(path);
  }

  // The map frame is the base frame at the first scan: T_map_session = T_base_sensor.
  core::Pose3 MapFromSession() const { return T_base_sensor_; }

  void OnFinish(const std_msgs::String::ConstPtr& request) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!mapper_) return;
    NODELET_INFO_STREAM("SubmapManager: finishing session '" << session_ << "' ("
                        << request->data << ")");
    boost::shared_ptr<FinishedSession> out = boost::make_shared<FinishedSession>();
    out->session = session_;
    out->index = static_cast<std::uint32_t>(session_index_);
    core::StatusOr<core::SessionResult> result = mapper_->Finish();
    if (result.ok()) {
      out->result = std::make_shared<const core::SessionResult>(std::move(result.value()));
      // The submaps closed by Finish (and the final optimised origins of all).
      for (const core::Submap& submap : out->result->submaps) {
        SubmapInfo info;
        info.header.stamp = conversions::ToRosTime(submap.last_stamp_s());
        info.header.frame_id = frames_.map;
        info.session = session_;
        info.id = submap.id;
        info.origin = conversions::ToPoseMsg(MapFromSession() * submap.T_map_submap);
        info.num_scans = static_cast<std::uint32_t>(submap.scans.size());
        info.num_points = static_cast<std::uint32_t>(submap.points.size());
        info.length_m = submap.length_m;
        info_pub_.publish(info);
      }
      NODELET_INFO("SubmapManager: session '%s': %zu scans, %zu submaps, %zu intra loop records",
                   session_.c_str(), out->result->scans_processed, out->result->submaps.size(),
                   out->result->loops.size());
    } else {
      out->error = result.status().message();
      NODELET_WARN_STREAM("SubmapManager: " << out->error);
    }
    finished_pub_.publish(out);
    ++session_index_;
    StartSession();
  }

  std::mutex mutex_;
  boost::recursive_mutex reconfigure_mutex_;
  std::unique_ptr<dynamic_reconfigure::Server<SubmapManagerConfig>> server_;
  core::SessionMapperConfig config_;
  std::unique_ptr<core::SessionMapper> mapper_;
  std::string session_base_, session_;
  int session_index_ = 0;
  core::Trajectory scans_;  ///< odometry poses of this session's scans
  std::size_t published_submaps_ = 0;
  std::size_t published_optimisations_ = 0;
  core::Pose3 T_base_sensor_ = core::Pose3::Identity();
  Frames frames_;
  std::unique_ptr<tf2_ros::TransformBroadcaster> tf_broadcaster_;
  ros::Subscriber scan_sub_, finish_sub_;
  ros::Publisher info_pub_, cloud_pub_, path_pub_, loops_pub_, scan_pub_, finished_pub_;
};

}  // namespace nodelets
}  // namespace multisession_mapper

PLUGINLIB_EXPORT_CLASS(multisession_mapper::nodelets::SubmapManagerNodelet, nodelet::Nodelet)
