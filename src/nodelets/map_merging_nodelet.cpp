// MapMergingNodelet: ends a session and merges it into the stored map (core::SessionMerger:
// inter-session loops, joint optimisation, low-dynamic detection, map update), then saves the
// map atomically (core::MapStore).
//   services (in the nodelet's namespace): finish_session (FinishSession), save_map (SaveMap),
//        load_map (LoadMap)
//   in:  odom (only to notice that input stopped: the session is finished automatically after
//        idle_finish_s of wall time without a scan, e.g. when the bag ends), finished_session and
//        finished_recognition (in-process, from SubmapManager / PlaceRecognition)
//   out: finish_request (std_msgs/String, to SubmapManager), dynamic_points (DynamicPoints per
//        changed history submap), merged_map (latched, downsampled, map frame), change_summary
//        (std_msgs/String, latched, one-line summary), map_changed (std_msgs/String, latched:
//        the map directory after a save / load, PlaceRecognition reloads its database).
//   The map at map_dir is loaded at start when it exists (view_map.launch uses only this).
//   dynamic_reconfigure: cfg/MapMerging.cfg (initial values from the `config` YAML).
// Threading / ownership: odom, the finished_* handoffs, the idle timer and
// dynamic_reconfigure run on this nodelet's single-threaded queue; the three services run on
// the multi-threaded queue (getMTNodeHandle) so that finish_session can wait for the
// handoffs. mutex_ guards map_, the configs, the pending handoffs and the merge counters;
// merged_ (condition variable, with mutex_) wakes a waiting finish_session. The merge itself
// runs in the handoff callback holding mutex_ (save_map / load_map wait for it).
#include <algorithm>
#include <condition_variable>
#include <ctime>
#include <memory>
#include <mutex>
#include <sstream>

#include <dynamic_reconfigure/server.h>
#include <multisession_mapper/DynamicPoints.h>
#include <multisession_mapper/FinishSession.h>
#include <multisession_mapper/LoadMap.h>
#include <multisession_mapper/SaveMap.h>
#include <nav_msgs/Odometry.h>
#include <nodelet/nodelet.h>
#include <pluginlib/class_list_macros.hpp>
#include <std_msgs/String.h>

#include "multisession_mapper/core/map_store.h"
#include "multisession_mapper/core/session_merger.h"
#include "multisession_mapper/core/timing_record.h"
#include "multisession_mapper/core/voxel_downsample.h"
#include "multisession_mapper/nodelets/in_process_messages.h"
#include "multisession_mapper/nodelets/nodelet_common.h"
#include "multisession_mapper/ros/conversions.h"
#include "multisession_mapper/ros/parameter_mapping.h"

namespace multisession_mapper {
namespace nodelets {

class MapMergingNodelet : public nodelet::Nodelet {
 private:
  void onInit() override {
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    if (!LoadConfigParam(pnh, &pipeline_, &config_path_)) {
      NODELET_FATAL("MapMerging: bad parameters, not started");
      return;
    }
    merge_ = pipeline_.merge;
    frames_ = FramesParam(pnh);
    map_dir_ = SearchString(pnh, "map_dir", "");
    bag_ = SearchString(pnh, "bag", "");
    finish_timeout_s_ = SearchDouble(pnh, "finish_timeout_s", 900.0);
    merged_map_pub_ = nh.advertise<sensor_msgs::PointCloud2>("merged_map", 1, true);
    dynamic_pub_ = nh.advertise<DynamicPoints>("dynamic_points", 100, true);
    changes_pub_ = nh.advertise<std_msgs::String>("change_summary", 1, true);
    map_changed_pub_ = nh.advertise<std_msgs::String>("map_changed", 1, true);
    finish_pub_ = nh.advertise<std_msgs::String>("finish_request", 2);
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (!map_dir_.empty() && core::MapStore::Exists(map_dir_)) LoadLocked(map_dir_, nullptr);
    }
    MapMergingConfig initial = ros_params::ToMapMergingConfig(merge_);
    // ROS-only parameters: from the launch file when given there.
    pnh.param("idle_finish_s", initial.idle_finish_s, initial.idle_finish_s);
    pnh.param("merged_map_voxel_m", initial.merged_map_voxel_m, initial.merged_map_voxel_m);
    server_ = StartReconfigureServer(
        reconfigure_mutex_, pnh, initial,
        [this](MapMergingConfig& c, uint32_t) { Reconfigure(&c); });

    odom_sub_ = nh.subscribe("odom", 100, &MapMergingNodelet::OnOdom, this);
    session_sub_ = nh.subscribe("finished_session", 2, &MapMergingNodelet::OnSession, this);
    recognition_sub_ = nh.subscribe("finished_recognition", 2, &MapMergingNodelet::OnRecognition, this);
    idle_timer_ = nh.createWallTimer(ros::WallDuration(0.5), &MapMergingNodelet::OnIdleTimer, this);
    ros::NodeHandle& mt = getMTNodeHandle();
    finish_srv_ = mt.advertiseService("finish_session", &MapMergingNodelet::OnFinishService, this);
    save_srv_ = mt.advertiseService("save_map", &MapMergingNodelet::OnSaveService, this);
    load_srv_ = mt.advertiseService("load_map", &MapMergingNodelet::OnLoadService, this);
    NODELET_INFO_STREAM("MapMerging: map directory '" << map_dir_ << "'");
  }

  // A refused change leaves the configuration as it was, and `*c` shows it (the server sends
  // `*c` back to the client and keeps it as its current configuration).
  void Reconfigure(MapMergingConfig* c) {
    std::lock_guard<std::mutex> lock(mutex_);
    core::SessionMergerConfig changed = merge_;
    ros_params::ApplyMapMergingConfig(*c, &changed);
    const core::Status s = changed.Validate();
    if (!s.ok()) {
      NODELET_WARN_STREAM("MapMerging: reconfigure refused: " << s.message());
      *c = ros_params::ToMapMergingConfig(merge_);
      c->idle_finish_s = idle_finish_s_;
      c->merged_map_voxel_m = merged_map_voxel_m_;
      return;
    }
    merge_ = changed;
    idle_finish_s_ = c->idle_finish_s;
    merged_map_voxel_m_ = c->merged_map_voxel_m;
    NODELET_INFO("MapMerging: reconfigured for the next merge: d_beta %.2f m, grow %.2f m / %.2f rad, "
                 "height guard %s %.1f m, fusion overlap >= %.2f; idle finish %.1f s",
                 merge_.dynamics.seed_distance_m, merge_.dynamics.grow_radius_m,
                 merge_.dynamics.grow_max_normal_angle_rad,
                 merge_.dynamics.height_guard_enabled ? "on" : "off", merge_.dynamics.height_guard_m,
                 merge_.fusion.min_overlap_ratio, idle_finish_s_);
  }

  void OnOdom(const nav_msgs::Odometry::ConstPtr&) {
    std::lock_guard<std::mutex> lock(mutex_);
    last_input_ = ros::WallTime::now();
    if (!session_active_) session_start_ = last_input_;
    session_active_ = true;
  }

  void OnIdleTimer(const ros::WallTimerEvent&) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!session_active_ || idle_finish_s_ <= 0.0) return;
    if ((ros::WallTime::now() - last_input_).toSec() < idle_finish_s_) return;
    NODELET_INFO("MapMerging: no scan for %.1f s: finishing the session", idle_finish_s_);
    RequestFinishLocked("input stopped");
  }

  void RequestFinishLocked(const std::string& why) {
    session_active_ = false;
    std_msgs::String request;
    request.data = why;
    finish_pub_.publish(request);
  }

  void OnSession(const boost::shared_ptr<const FinishedSession>& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    session_ = msg;
    MergeIfCompleteLocked();
  }

  void OnRecognition(const boost::shared_ptr<const FinishedRecognition>& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    recognition_ = msg;
    MergeIfCompleteLocked();
  }

  void MergeIfCompleteLocked() {
    if (!session_ || !recognition_ || session_->session != recognition_->session) return;
    last_response_ = MergeLocked(*session_, *recognition_);
    if (!last_response_.success) {
      std_msgs::String text;  // failures are reported on the summary topic too
      text.data = last_response_.message;
      changes_pub_.publish(text);
    }
    session_.reset();
    recognition_.reset();
    ++merges_;
    merged_.notify_all();
    // The finished session (its SessionResult and PlaceRecognizer, last held here) and the
    // merge's working memory are freed now; hand the free heap pages back to the system, or
    // the manager keeps every session's peak in its RSS (glibc keeps freed memory in per-thread
    // arenas). Measured by scripts/stress.sh --only nodelets.
    ReleaseFreeHeap();
    // The live heap after a merge is what scripts/stress.sh --only nodelets checks for leaks
    // between sessions (the RSS also holds the allocator's retained pages).
    NODELET_INFO("MapMerging: heap in use after merge %zu: %.1f MB", merges_,
                 static_cast<double>(HeapInUseBytes()) / (1024.0 * 1024.0));
  }

  FinishSession::Response MergeLocked(const FinishedSession& session,
                                      const FinishedRecognition& recognition) {
    FinishSession::Response response;
    const ros::WallTime start = ros::WallTime::now();
    if (!session.result || !recognition.recognizer) {
      response.message = "session '" + session.session + "' not merged: " +
                         (session.error.empty() ? recognition.error : session.error);
      NODELET_ERROR_STREAM("MapMerging: " << response.message);
      return response;
    }
    core::SessionMergerConfig config = merge_;
    config.matching.voting = recognition.voting;
    config.matching.neighbour_distance_m = recognition.neighbour_distance_m;
    core::StatusOr<core::SessionMerger> merger = core::SessionMerger::Create(config);
    if (!merger.ok()) {
      response.message = merger.status().message();
      return response;
    }
    const core::SessionResult& result = *session.result;
    core::SessionRecord record;
    record.name = session.session;
    record.bag = bag_;
    record.scans = static_cast<std::uint32_t>(result.scans_processed);
    if (!result.trajectory.empty()) {
      record.duration_s = result.trajectory.back().stamp_s - result.trajectory.front().stamp_s;
    }
    char now[32];
    const std::time_t t = std::time(nullptr);
    std::strftime(now, sizeof(now), "%Y-%m-%dT%H:%M:%SZ", std::gmtime(&t));
    record.merged_at = now;
    core::SessionTimings timings = result.timings;
    timings.descriptor_ms = recognition.recognizer->descriptor_ms();
    timings.query_ms = recognition.recognizer->query_ms();
    core::SessionRunInfo run;
    run.bag_duration_s = record.duration_s;
    core::SessionFiles files;
    files.timing_yaml = core::TimingYaml(timings, run);
    files.place_recognition_csv = recognition.recognizer->QueriesCsv();
    core::StatusOr<core::MergeReport> report =
        merger.value().Merge(result, record, *recognition.recognizer, files, &map_);
    if (!report.ok()) {
      response.message = "session '" + session.session + "' not merged (map unchanged): " +
                         report.status().message();
      NODELET_ERROR_STREAM("MapMerging: " << response.message);
      return response;
    }
    core::PipelineConfig recorded = pipeline_;  // with the live changes of this nodelet
    recorded.merge = config;
    map_.parameters_yaml = core::PipelineConfigToYaml(recorded);
    const core::MergeReport& r = report.value();
    // The timing record again, now with the merge figures (as offline_mapper writes it). Wall
    // time: first to last scan of the session plus the merge, without the idle wait.
    timings.global_registration_s = r.matching.registration_s;
    timings.guided_registration_s = r.matching.guided_registration_s;
    timings.dynamic_detection_s = r.dynamic_pair_s;
    run.merge_matching_s = r.matching_s;
    run.merge_optimisation_s = r.optimisation_s;
    run.merge_update_s = r.update_s;
    run.merge_update_dynamics_s = r.update_dynamics_s;
    run.merge_update_fusion_s = r.update_fusion_s;
    run.merge_update_database_s = r.update_database_s;
    run.merge_s = (ros::WallTime::now() - start).toSec();
    run.wall_time_s = std::max(0.0, (last_input_ - session_start_).toSec()) + run.merge_s;
    run.peak_rss_mb = core::ProcessPeakRssMb();  // the nodelet manager, all four nodelets
    map_.files["timing/" + record.name + ".yaml"] = core::TimingYaml(timings, run);
    std::ostringstream summary;
    summary << "session '" << r.session << "'" << (r.first_session ? " (first)" : "") << ": "
            << r.inter_loops << " inter-session loops, " << r.sequence_loops
            << " by sequence, " << r.proximity_loops
            << " proximity loops, " << r.submaps_added << " submaps added, " << r.submaps_fused
            << " fused, " << r.points_removed << " dynamic points removed, " << r.points_mended
            << " mended, " << r.points_held_back << " of new objects held back, merge "
            << r.total_s << " s";
    const core::Status saved = SaveLocked(map_dir_);
    summary << (saved.ok() ? "; saved to " + map_dir_ : "; NOT saved: " + saved.message());
    for (const core::SubmapChange& change : r.changes) {
      DynamicPoints msg;
      msg.header.stamp = ros::Time::now();
      msg.header.frame_id = frames_.map;
      msg.history_session = change.session;
      msg.history_submap = change.submap_id;
      msg.current_session = r.session;
      msg.removed = conversions::ToPointCloud2(change.removed_m, frames_.map, msg.header.stamp);
      msg.mended = conversions::ToPointCloud2(change.mended_m, frames_.map, msg.header.stamp);
      dynamic_pub_.publish(msg);
    }
    if (!r.held_m.empty()) {  // one message for the new objects held back by the merge
      DynamicPoints msg;
      msg.header.stamp = ros::Time::now();
      msg.header.frame_id = frames_.map;
      msg.current_session = r.session;
      msg.held = conversions::ToPointCloud2(r.held_m, frames_.map, msg.header.stamp);
      dynamic_pub_.publish(msg);
    }
    PublishMapLocked();
    std_msgs::String text;
    text.data = summary.str();
    changes_pub_.publish(text);
    NODELET_INFO_STREAM("MapMerging: " << text.data << " (" << (ros::WallTime::now() - start).toSec()
                        << " s wall)");
    response.success = saved.ok();
    response.message = text.data;
    response.submaps_added = static_cast<std::uint32_t>(r.submaps_added);
    response.inter_session_loops = static_cast<std::uint32_t>(r.inter_loops + r.sequence_loops + r.proximity_loops);
    response.dynamic_points_removed = static_cast<std::uint32_t>(r.points_removed);
    return response;
  }

  core::Status SaveLocked(const std::string& dir) {
    if (dir.empty()) return core::Status::Error("no map directory (map_dir parameter)");
    const core::Status s = core::MapStore().Save(map_, dir);
    if (s.ok()) {
      std_msgs::String changed;
      changed.data = dir;
      map_changed_pub_.publish(changed);
    }
    return s;
  }

  bool LoadLocked(const std::string& dir, LoadMap::Response* response) {
    core::StatusOr<core::MapContents> loaded = core::MapStore().Load(dir);
    if (!loaded.ok()) {
      NODELET_ERROR_STREAM("MapMerging: " << loaded.status().message());
      if (response) response->message = loaded.status().message();
      return false;
    }
    map_ = std::move(loaded.value());
    map_dir_ = dir;
    std::size_t active = 0;
    for (const core::Submap& s : map_.submaps) active += s.state == core::SubmapState::kActive;
    NODELET_INFO("MapMerging: loaded '%s': %zu sessions, %zu submaps (%zu active)", dir.c_str(),
                 map_.sessions.size(), map_.submaps.size(), active);
    if (response) {
      response->success = true;
      response->message = "loaded " + dir;
      response->sessions = static_cast<std::uint32_t>(map_.sessions.size());
      response->submaps = static_cast<std::uint32_t>(map_.submaps.size());
    }
    PublishMapLocked();
    std_msgs::String changed;
    changed.data = dir;
    map_changed_pub_.publish(changed);
    return true;
  }

  // Active submaps in the map frame, downsampled for display.
  void PublishMapLocked() {
    core::PointVector points;
    for (const core::Submap& s : map_.submaps) {
      if (s.state != core::SubmapState::kActive) continue;
      for (const Eigen::Vector3d& p : s.points) points.push_back(s.T_map_submap * p);
    }
    merged_map_pub_.publish(conversions::ToPointCloud2(
        core::VoxelDownsample(points, merged_map_voxel_m_), frames_.map, ros::Time::now()));
  }

  bool OnFinishService(FinishSession::Request&, FinishSession::Response& response) {
    std::unique_lock<std::mutex> lock(mutex_);
    const std::size_t before = merges_;
    RequestFinishLocked("finish_session service");
    if (!merged_.wait_for(lock, std::chrono::duration<double>(finish_timeout_s_),
                          [&] { return merges_ != before; })) {
      response.message = "timed out waiting for the session to finish";
      return true;
    }
    response = last_response_;
    return true;
  }

  bool OnSaveService(SaveMap::Request& request, SaveMap::Response& response) {
    std::lock_guard<std::mutex> lock(mutex_);
    const std::string dir = request.map_dir.empty() ? map_dir_ : request.map_dir;
    const core::Status s = SaveLocked(dir);
    response.success = s.ok();
    response.message = s.ok() ? "saved to " + dir : s.message();
    return true;
  }

  bool OnLoadService(LoadMap::Request& request, LoadMap::Response& response) {
    std::lock_guard<std::mutex> lock(mutex_);
    LoadLocked(request.map_dir.empty() ? map_dir_ : request.map_dir, &response);
    return true;
  }

  std::mutex mutex_;
  std::condition_variable merged_;
  boost::recursive_mutex reconfigure_mutex_;
  std::unique_ptr<dynamic_reconfigure::Server<MapMergingConfig>> server_;
  core::PipelineConfig pipeline_;
  core::SessionMergerConfig merge_;
  std::string config_path_, map_dir_, bag_;
  double finish_timeout_s_ = 900.0;
  double idle_finish_s_ = 5.0;
  double merged_map_voxel_m_ = 0.5;
  core::MapContents map_;
  bool session_active_ = false;
  ros::WallTime last_input_, session_start_;
  boost::shared_ptr<const FinishedSession> session_;
  boost::shared_ptr<const FinishedRecognition> recognition_;
  std::size_t merges_ = 0;
  FinishSession::Response last_response_;
  Frames frames_;
  ros::Subscriber odom_sub_, session_sub_, recognition_sub_;
  ros::Publisher merged_map_pub_, dynamic_pub_, changes_pub_, map_changed_pub_, finish_pub_;
  ros::ServiceServer finish_srv_, save_srv_, load_srv_;
  ros::WallTimer idle_timer_;
};

}  // namespace nodelets
}  // namespace multisession_mapper

PLUGINLIB_EXPORT_CLASS(multisession_mapper::nodelets::MapMergingNodelet, nodelet::Nodelet)
