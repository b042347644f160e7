// PlaceRecognitionNodelet: a descriptor per scan, queried live against the stored map's
// database, and the vote per finished submap (core::PlaceRecognizer, core::SubmapVoting).
//   in:  scan_in_submap (in-process), submaps (SubmapInfo: the submap origins shown),
//        finished_session (in-process), map_changed (std_msgs/String: reload the database)
//   Votes: a submap is voted on once, when the scan stream moves on to a later submap (its
//   scans are then complete) or when the session finishes. The votes depend only on the
//   in-process scan stream, not on when SubmapInfo arrives (it could arrive after the
//   finished_session message, or, in the rostest, not reach this nodelet at all).
//   out: place_matches (PlaceMatch per scan; only while a history database exists),
//        loop_candidates (LoopCandidateArray, latched: all inter-session candidates and
//        undefined submaps of the session so far), finished_recognition (in-process: the
//        recognizer and the voting thresholds for MapMergingNodelet).
//   History origins in loop_candidates are in the stored map's frame; current origins in the
//   live session's frame (the two agree only after the merge).
//   dynamic_reconfigure: cfg/PlaceRecognition.cfg (initial values from the `config` YAML).
// Threading / ownership: all callbacks run on this nodelet's single-threaded queue; mutex_
// guards recognizer_, history_, the configs and the vote bookkeeping against onInit. The
// recognizer is handed over as shared_ptr<const> at the end of a session and a new one starts.
#include <map>
#include <memory>
#include <mutex>
#include <set>

#include <dynamic_reconfigure/server.h>
#include <multisession_mapper/LoopCandidateArray.h>
#include <multisession_mapper/PlaceMatch.h>
#include <multisession_mapper/SubmapInfo.h>
#include <nodelet/nodelet.h>
#include <pluginlib/class_list_macros.hpp>
#include <std_msgs/String.h>

#include "multisession_mapper/core/map_store.h"
#include "multisession_mapper/core/place_recognizer.h"
#include "multisession_mapper/core/submap_voting.h"
#include "multisession_mapper/nodelets/in_process_messages.h"
#include "multisession_mapper/nodelets/nodelet_common.h"
#include "multisession_mapper/ros/conversions.h"
#include "multisession_mapper/ros/parameter_mapping.h"

namespace multisession_mapper {
namespace nodelets {

class PlaceRecognitionNodelet : public nodelet::Nodelet {
 private:
  void onInit() override {
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    core::PipelineConfig pipeline;
    std::string path;
    if (!LoadConfigParam(pnh, &pipeline, &path)) {
      NODELET_FATAL("PlaceRecognition: bad parameters, not started");
      return;
    }
    config_ = pipeline.place_recognition;
    matching_ = pipeline.merge.matching;
    frames_ = FramesParam(pnh);
    map_dir_ = SearchString(pnh, "map_dir", "");
    {
      std::lock_guard<std::mutex> lock(mutex_);
      LoadHistory();
    }
    PlaceRecognitionConfig initial = ros_params::ToPlaceRecognitionConfig(config_, matching_);
    server_ = StartReconfigureServer(
        reconfigure_mutex_, pnh, initial,
        [this](PlaceRecognitionConfig& c, uint32_t) { Reconfigure(&c); });

    match_pub_ = nh.advertise<PlaceMatch>("place_matches", 100);
    candidates_pub_ = nh.advertise<LoopCandidateArray>("loop_candidates", 1, true);
    finished_pub_ = nh.advertise<FinishedRecognition>("finished_recognition", 2);
    scan_sub_ = nh.subscribe("scan_in_submap", 200, &PlaceRecognitionNodelet::OnScan, this);
    info_sub_ = nh.subscribe("submaps", 100, &PlaceRecognitionNodelet::OnSubmap, this);
    finished_sub_ = nh.subscribe("finished_session", 2, &PlaceRecognitionNodelet::OnFinished, this);
    map_sub_ = nh.subscribe("map_changed", 2, &PlaceRecognitionNodelet::OnMapChanged, this);
  }

  // Reads the map's descriptor database and history submap origins (none: first session).
  void LoadHistory() {
    history_.reset();
    history_origins_.clear();
    if (map_dir_.empty() || !core::MapStore::Exists(map_dir_)) {
      NODELET_INFO_STREAM("PlaceRecognition: no stored map at '" << map_dir_
                          << "': descriptors only (first session)");
      return;
    }
    core::MapStoreConfig store_config;
    store_config.verify_checksums = false;  // MapMergingNodelet verifies the map it merges into
    core::StatusOr<core::MapContents> map = core::MapStore(store_config).Load(map_dir_);
    if (!map.ok()) {
      NODELET_ERROR_STREAM("PlaceRecognition: " << map.status().message());
      return;
    }
    // MapStore carries the database as an opaque file (not read by Load): read it directly.
    const std::string path = map_dir_ + "/database/descriptors.bin";
    core::StatusOr<core::DescriptorDatabase> db =
        core::DescriptorDatabase::Load(path, config_.database);
    if (!db.ok()) {
      NODELET_ERROR_STREAM("PlaceRecognition: " << db.status().message());
      return;
    }
    history_ = std::make_shared<const core::DescriptorDatabase>(std::move(db.value()));
    for (const core::Submap& s : map.value().submaps) {
      history_origins_[{s.session, static_cast<int>(s.id)}] = s.T_map_submap.translation();
    }
    NODELET_INFO("PlaceRecognition: history database of %zu scans, %zu submaps", history_->size(),
                 history_origins_.size());
  }

  bool StartRecognizer(const std::string& session) {
    core::StatusOr<core::PlaceRecognizer> r = core::PlaceRecognizer::Create(config_, session, history_);
    if (!r.ok()) {
      NODELET_ERROR_STREAM("PlaceRecognition: " << r.status().message());
      return false;
    }
    recognizer_ = std::make_unique<core::PlaceRecognizer>(std::move(r.value()));
    session_ = session;
    voted_.clear();
    seen_.clear();
    origins_.clear();
    candidates_ = LoopCandidateArray();
    return true;
  }

  // A refused change leaves the configuration as it was, and `*c` shows it (the server sends
  // `*c` back to the client and keeps it as its current configuration).
  void Reconfigure(PlaceRecognitionConfig* c) {
    std::lock_guard<std::mutex> lock(mutex_);
    core::PlaceRecognizerConfig recognizer = config_;
    core::InterSessionMatcherConfig matching = matching_;
    ros_params::ApplyPlaceRecognitionConfig(*c, &recognizer, &matching);
    core::Status s = recognizer.Validate();
    if (s.ok()) s = matching.voting.Validate();
    if (!s.ok()) {
      NODELET_WARN_STREAM("PlaceRecognition: reconfigure refused: " << s.message());
      *c = ros_params::ToPlaceRecognitionConfig(config_, matching_);
      return;
    }
    config_ = recognizer;
    matching_ = matching;
    NODELET_INFO("PlaceRecognition: reconfigured: voting gamma %.3f, n %d, min matched %d, "
                 "neighbours %.1f m (next submap); d_alpha %.3f / %.3f (next session)",
                 matching_.voting.gamma, matching_.voting.top_n, matching_.voting.min_matched_scans,
                 matching_.neighbour_distance_m, config_.database.d_alpha_ring_histogram,
                 config_.database.d_alpha_scan_context);
  }

  void OnScan(const boost::shared_ptr<const ScanInSubmap>& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!recognizer_ || session_ != msg->session) {
      if (!StartRecognizer(msg->session)) return;
    }
    // The scans of every earlier submap are complete once a later submap's scan arrives.
    for (std::uint32_t id : seen_) {
      if (id < msg->submap_id) VoteLocked(id, msg->header.stamp);
    }
    if (seen_.insert(msg->submap_id).second) {
      geometry_msgs::Point origin;  // until SubmapInfo gives the optimised one: first scan pose
      origin.x = msg->odometry->pose.translation().x();
      origin.y = msg->odometry->pose.translation().y();
      origin.z = msg->odometry->pose.translation().z();
      origins_.emplace(msg->submap_id, origin);
    }
    const core::Status s = recognizer_->AddScan(msg->odometry->deskewed_scan, msg->submap_id);
    if (!s.ok()) {
      NODELET_WARN_STREAM_THROTTLE(5.0, "PlaceRecognition: " << s.message());
      return;
    }
    if (!history_) return;
    if (recognizer_->queries().empty()) return;
    const core::ScanQuery& query = recognizer_->queries().back();  // this scan's query
    PlaceMatch match;
    match.header = msg->header;
    match.session = msg->session;
    match.submap = msg->submap_id;
    match.matched = query.result.matched && !query.result.neighbors.empty();
    match.descriptor_distance = -1.0f;  // no neighbour at all (empty history)
    if (!query.result.neighbors.empty()) {
      const core::DatabaseNeighbor& nearest = query.result.neighbors.front();
      const core::DatabaseEntry& entry = recognizer_->history()->entry(nearest.index);
      match.descriptor_distance = nearest.distance;
      if (match.matched) {
        match.history_session = entry.session;
        match.history_submap = static_cast<std::uint32_t>(entry.submap_id);
        match.history_scan_stamp = entry.stamp_s;
      }
    }
    match_pub_.publish(match);
  }

  // Keeps the submap's (optimised) origin for the candidates shown.
  void OnSubmap(const SubmapInfo::ConstPtr& info) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (info->session != session_) return;
    origins_[info->id] = info->origin.position;
  }

  // Votes once for submap `id` of the current session (mutex_ held).
  void VoteLocked(std::uint32_t id, const ros::Time& stamp) {
    if (!recognizer_ || !history_ || !voted_.insert(id).second) return;
    core::StatusOr<core::SubmapVoting> voting = core::SubmapVoting::Create(matching_.voting);
    if (!voting.ok()) {
      NODELET_WARN_STREAM_THROTTLE(5.0, "PlaceRecognition: " << voting.status().message());
      return;
    }
    const core::SubmapVoteResult vote = voting.value().Vote(
        recognizer_->VotesOf(id),
        core::SubmapVoting::OriginsWithin(history_origins_, matching_.neighbour_distance_m));
    const geometry_msgs::Point current_origin = origins_[id];
    auto add = [&](const core::HistorySubmapId* history, double proportion) {
      core::LoopRecord record;
      record.kind = core::LoopKind::kInter;
      record.current_session = session_;
      record.current_submap = id;
      record.status = history ? core::LoopStatus::kCandidate : core::LoopStatus::kUndefined;
      record.vote_proportion = proportion;
      record.reason = vote.reason;
      geometry_msgs::Point history_origin;
      if (history) {
        record.history_session = history->session;
        record.history_submap = history->submap_id;
        auto it = history_origins_.find(*history);
        if (it != history_origins_.end()) {
          history_origin.x = it->second.x();
          history_origin.y = it->second.y();
          history_origin.z = it->second.z();
        }
      }
      candidates_.candidates.push_back(conversions::ToLoopCandidateMsg(record));
      candidates_.current_origins.push_back(current_origin);
      candidates_.history_origins.push_back(history ? history_origin : current_origin);
    };
    if (vote.candidates.empty()) {
      add(nullptr, vote.proportions.empty() ? 0.0 : vote.proportions.front().proportion);
    }
    for (const core::HistorySubmapId& h : vote.candidates) {
      double proportion = 0.0;
      for (const core::VoteProportion& p : vote.proportions) {
        if (p.history == h) proportion = p.proportion;
      }
      add(&h, proportion);
    }
    NODELET_INFO("PlaceRecognition: submap %u: %s (%d of %d scans matched) %s", id,
                 core::VoteOutcomeName(vote.outcome), vote.scans_matched, vote.scans_total,
                 vote.reason.c_str());
    candidates_.header.stamp = stamp;
    candidates_.header.frame_id = frames_.map;
    candidates_pub_.publish(candidates_);
  }

  void OnFinished(const boost::shared_ptr<const FinishedSession>& finished) {
    std::lock_guard<std::mutex> lock(mutex_);
    boost::shared_ptr<FinishedRecognition> out = boost::make_shared<FinishedRecognition>();
    out->session = finished->session;
    out->voting = matching_.voting;
    out->neighbour_distance_m = matching_.neighbour_distance_m;
    if (recognizer_ && session_ == finished->session) {
      for (std::uint32_t id : seen_) VoteLocked(id, ros::Time::now());  // the last submaps
      out->recognizer = std::shared_ptr<const core::PlaceRecognizer>(std::move(recognizer_));
    } else {
      // No scan reached this nodelet: an empty recognizer keeps the merge well-defined.
      if (StartRecognizer(finished->session)) out->recognizer = std::move(recognizer_);
    }
    recognizer_.reset();
    session_.clear();
    finished_pub_.publish(out);
  }

  void OnMapChanged(const std_msgs::String::ConstPtr& dir) {
    std::lock_guard<std::mutex> lock(mutex_);
    map_dir_ = dir->data;
    LoadHistory();  // used from the next session on
  }

  std::mutex mutex_;
  boost::recursive_mutex reconfigure_mutex_;
  std::unique_ptr<dynamic_reconfigure::Server<PlaceRecognitionConfig>> server_;
  core::PlaceRecognizerConfig config_;
  core::InterSessionMatcherConfig matching_;  ///< only voting and neighbour_distance_m are used
  std::string map_dir_;
  std::shared_ptr<const core::DescriptorDatabase> history_;
  std::map<core::HistorySubmapId, Eigen::Vector3d> history_origins_;
  std::unique_ptr<core::PlaceRecognizer> recognizer_;
  std::string session_;
  std::set<std::uint32_t> voted_;  ///< submaps of this session already voted on
  std::set<std::uint32_t> seen_;   ///< submaps of this session with scans
  std::map<std::uint32_t, geometry_msgs::Point> origins_;  ///< current submap origins shown
  LoopCandidateArray candidates_;
  Frames frames_;
  ros::Subscriber scan_sub_, info_sub_, finished_sub_, map_sub_;
  ros::Publisher match_pub_, candidates_pub_, finished_pub_;
};

}  // namespace nodelets
}  // namespace multisession_mapper

PLUGINLIB_EXPORT_CLASS(multisession_mapper::nodelets::PlaceRecognitionNodelet, nodelet::Nodelet)
