// offline_mapper: maps recording sessions from bags into a map directory, as fast as the
// machine allows (no roscore, no playback). Thin: reads the bag through the conversions layer,
// drives the core SessionMapper and PlaceRecognizer, merges the session into the map with the
// core SessionMerger and saves atomically. Several bags are merged one after the other.
//   offline_mapper --bag day1.bag [--bag day2.bag ...] --map campus_map/ [options]
// Exit codes: 0 merged, 1 error (input, map or configuration), 2 usage, 3 the session could not
// be merged (e.g. no consistent overlap with the map); on any error the map is unchanged.

#include <algorithm>
#include <cmath>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "multisession_mapper/core/map_store.h"
#include "multisession_mapper/core/session_merger.h"
#include "multisession_mapper/core/pipeline_config.h"
#include "multisession_mapper/core/odometry_worker.h"
#include "multisession_mapper/core/place_recognizer.h"
#include "multisession_mapper/core/serial_worker.h"
#include "multisession_mapper/core/session_mapper.h"
#include "multisession_mapper/core/timing_record.h"
#include "multisession_mapper/ros/bag_scan_reader.h"
#include "multisession_mapper/tools/cli.h"

namespace msm = multisession_mapper;
namespace core = multisession_mapper::core;

namespace {

const char kUsage[] =
    "usage: offline_mapper --bag FILE [--bag FILE ...] --map DIR [options]\n"
    "  --bag FILE        a session's bag; several are merged one after the other\n"
    "  --map DIR         map directory (created when absent; updated atomically)\n"
    "  --topic NAME      PointCloud2 topic (/velodyne_points)\n"
    "  --config FILE     pipeline configuration YAML (defaults: cfg/default.yaml)\n"
    "  --session NAME    session name (default: the bag's file name without extension)\n"
    "  --max-scans N     stop each session after N scans (0: all)\n"
    "  --quiet           no progress output\n"
    "  --sequential      bag reading, odometry, submap building and place descriptors\n"
    "                    one after the other (default: the bag is read ahead on a thread\n"
    "                    of its own, the odometry runs ahead on another and the\n"
    "                    descriptors follow on a third; same result either way)\n"
    "  --odometry-queue N  scans the odometry thread may run ahead of the submap building\n"
    "                    (32, about 1 MB each: it keeps going while a submap is finished);\n"
    "                    also the scans queued for the place descriptors' thread\n";

struct Options {
  std::vector<std::string> bags;
  std::string map_dir;
  std::string topic = "/velodyne_points";
  std::string config_path;
  std::string session;
  long long max_scans = 0;
  bool quiet = false;
  bool sequential = false;
  /// Scans handed to the odometry thread whose results the submap building has not taken
  /// yet (queued, in the odometry or done; OdometryWorker's max_pending bounds the first two).
  /// Session 36 (when it counted only the scans queued or in the odometry, not the results),
  /// first 1500 `campus` seed-1 s00 scans, alternating twice: 4: 6.6x / 7.1x real
  /// time, 16: 7.5x / 7.4x (peak 256 / 270-275 MB); 64 in another run 8.0x / 7.8x, 305 MB.
  /// The submap thread's spikes (a submap's finishing, ~0.2 s) no longer stall the odometry.
  /// Session 63, bag read ahead, whole seed-1 s00: 16 / 48 alternating five times: median
  /// 9.56x / 10.33x (48 faster in every pair), peak 741-749 / 781-792 MB; then 32 / 48 / 96
  /// three times each: median 10.41 / 10.52 / 10.44x, peak 768-772 / 784-790 / 807-844 MB.
  long long odometry_queue = 32;
};

// Scans read ahead of the odometry's queue (about 1 MB each). Whole campus seed-1 s00, peak
// RSS with 16: 749-753 MB, with 4: 741-746 MB, against 722-734 MB reading in place.
constexpr std::size_t kReadAheadScans = 4;

int UsageError(const std::string& message) {
  std::fprintf(stderr, "offline_mapper: %s\n%s", message.c_str(), kUsage);
  return 2;
}

std::string UtcNow() {
  char buffer[32];
  const std::time_t now = std::time(nullptr);
  std::strftime(buffer, sizeof(buffer), "%Y-%m-%dT%H:%M:%SZ", std::gmtime(&now));
  return buffer;
}

// The map's descriptor database, or null for a map without sessions.
core::StatusOr<std::shared_ptr<const core::DescriptorDatabase>> LoadHistoryDatabase(
    const std::string& map_dir, const core::MapContents& map, const core::PipelineConfig& config) {
  if (map.sessions.empty()) return std::shared_ptr<const core::DescriptorDatabase>();
  const std::string path = map_dir + "/database/descriptors.bin";
  core::StatusOr<core::DescriptorDatabase> db =
      core::DescriptorDatabase::Load(path, config.place_recognition.database);
  if (!db.ok()) return db.status();
  return std::shared_ptr<const core::DescriptorDatabase>(
      std::make_shared<core::DescriptorDatabase>(std::move(db.value())));
}

void PrintMergeReport(const core::MergeReport& report) {
  if (report.first_session) {
    std::fprintf(stderr, "%s: first session of the map (defines the map frame)\n",
                 report.session.c_str());
    return;
  }
  std::size_t matched = 0, undefined = 0;
  for (const core::SubmapVoteResult& vote : report.matching.votes) {
    (vote.outcome == core::SubmapVoteResult::Outcome::kUndefined ? undefined : matched) += 1;
  }
  const core::TimingSummary pairs = core::Summarize(report.dynamic_pair_s);
  std::fprintf(stderr,
               "%s merged: %zu submaps voted to a candidate, %zu undefined; %zu inter-session "
               "loops + %zu by sequence (%zu of them judged again) + %zu proximity loops; %zu submaps added, %zu fused; %zu dynamic points "
               "removed (%zu of them and of the new session's left out as copies), %zu mended, %zu fused points added, %zu points of %zu new objects held back; matching %.1f s, optimisation %.1f s, "
               "dynamics %.2f s/pair median, update %.1f s (detection %.1f, fusion %.1f, "
               "database %.1f)\n",
               report.session.c_str(), matched, undefined, report.inter_loops,
               report.sequence_loops, report.rejudged_loops, report.proximity_loops, report.submaps_added, report.submaps_fused,
               report.points_removed, report.points_propagated, report.points_mended,
               report.points_fused, report.points_held_back, report.objects_held_back,
               report.matching_s, report.optimisation_s, pairs.median, report.update_s,
               report.update_dynamics_s, report.update_fusion_s, report.update_database_s);
}

// Maps one bag and adds it to the map directory (first session or merge); returns the exit
// code. On any error the map directory is left as it was.
int MapSession(const Options& options, const std::string& bag_path, const std::string& name,
               const core::PipelineConfig& config) {
  const auto start = std::chrono::steady_clock::now();
  core::StatusOr<msm::conversions::BagScanReader> reader =
      msm::conversions::BagScanReader::Open(bag_path, options.topic);
  if (!reader.ok()) {
    std::fprintf(stderr, "offline_mapper: %s\n", reader.status().message().c_str());
    return 1;
  }
  core::MapContents map;
  const core::MapStore store;
  if (core::MapStore::Exists(options.map_dir)) {
    core::StatusOr<core::MapContents> loaded = store.Load(options.map_dir);
    if (!loaded.ok()) {
      std::fprintf(stderr, "offline_mapper: cannot load the map: %s\n",
                   loaded.status().message().c_str());
      return 1;
    }
    map = std::move(loaded.value());
    for (const core::SessionRecord& s : map.sessions) {
      if (s.name == name) {
        std::fprintf(stderr,
                     "offline_mapper: the map already has a session '%s' (use --session)\n",
                     name.c_str());
        return 1;
      }
    }
  }
  core::StatusOr<std::shared_ptr<const core::DescriptorDatabase>> history =
      LoadHistoryDatabase(options.map_dir, map, config);
  if (!history.ok()) {
    std::fprintf(stderr, "offline_mapper: cannot load the map's place database: %s\n",
                 history.status().message().c_str());
    return 1;
  }
  core::StatusOr<core::SessionMerger> merger = core::SessionMerger::Create(config.merge);
  core::StatusOr<core::SessionMapper> mapper = core::SessionMapper::Create(config.session, name);
  core::StatusOr<core::PlaceRecognizer> recognizer =
      core::PlaceRecognizer::Create(config.place_recognition, name, history.value());
  for (const core::Status& s : {merger.status(), mapper.status(), recognizer.status()}) {
    if (!s.ok()) {
      std::fprintf(stderr, "offline_mapper: %s\n", s.message().c_str());
      return 1;
    }
  }
  const std::size_t total = options.max_scans > 0
                                ? std::min<std::size_t>(options.max_scans, reader.value().num_messages())
                                : reader.value().num_messages();
  msm::tools::Progress progress(name, total, "scans", !options.quiet);
  std::size_t bad_scans = 0;
  double last_stamp_s = 0.0;
  // The odometry runs on its own thread (OdometryWorker), ahead of the submap building and
  // place recognition here; results are the same as with SessionMapper::AddScan.
  core::StatusOr<std::unique_ptr<core::OdometryWorker>> odometry = core::OdometryWorker::Create(
      config.session.odometry, static_cast<std::size_t>(options.odometry_queue));
  if (!odometry.ok()) {
    std::fprintf(stderr, "offline_mapper: %s\n", odometry.status().message().c_str());
    return 1;
  }
  std::vector<std::size_t> pending_index;  // bag index of each scan in the worker, in order
  std::size_t next_pending = 0;
  const auto report = [&](std::size_t index, const core::Status& status) {
    if (!status.ok() && ++bad_scans <= 5) {
      std::fprintf(stderr, "\noffline_mapper: scan %zu skipped: %s\n", index,
                   status.message().c_str());
    }
  };
  // The place descriptors are computed on a thread of their own (SerialWorker: in scan order,
  // the same descriptors and queries as in place), because this thread, which builds the
  // submaps, is the critical path of the run. Their failures are reported from here.
  // (Declared before the worker, whose destructor may still run tasks that use them.)
  std::mutex descriptor_failures_mutex;
  std::vector<std::pair<std::size_t, core::Status>> descriptor_failures;
  std::optional<core::SerialWorker> descriptors;  // none with --sequential
  if (!options.sequential) descriptors.emplace(static_cast<std::size_t>(options.odometry_queue));
  const auto report_descriptor_failures = [&] {
    std::vector<std::pair<std::size_t, core::Status>> failures;
    {
      std::lock_guard<std::mutex> lock(descriptor_failures_mutex);
      failures.swap(descriptor_failures);
    }
    for (const auto& [index, status] : failures) report(index, status);
  };
  // Builds the submaps and descriptors from one of the worker's results.
  const auto build = [&](core::StatusOr<core::OdometryResult> result) {
    const std::size_t index = pending_index[next_pending++];
    core::Status status = result.status();
    if (!result.ok()) {
      mapper.value().CountSkippedScan();
    } else {
      status = mapper.value().AddRegisteredScan(result.value());
      if (status.ok() && options.sequential) {
        status = recognizer.value().AddScan(result.value().deskewed_scan,
                                            mapper.value().current_submap_id());
      } else if (status.ok()) {
        descriptors->Post([&, index, submap = mapper.value().current_submap_id(),
                          scan = std::move(result.value().deskewed_scan)] {
          const core::Status added = recognizer.value().AddScan(scan, submap);
          if (added.ok()) return;
          std::lock_guard<std::mutex> lock(descriptor_failures_mutex);
          descriptor_failures.emplace_back(index, added);
        });
      }
    }
    report(index, status);
    report_descriptor_failures();
    progress.Update(index + 1, "submap " + std::to_string(mapper.value().current_submap_id()));
  };
  // Hands a scan read from the bag (or its error) to the odometry, in bag order.
  const auto feed = [&](core::StatusOr<core::LidarScan> scan, std::size_t index) {
    if (scan.ok() && last_stamp_s > 0.0 &&
        scan.value().stamp_s - last_stamp_s > config.session.odometry.max_scan_gap_s) {
      std::fprintf(stderr,
                   "\noffline_mapper: gap of %.2f s before scan %zu (more than "
                   "odometry.max_scan_gap_s): the motion model restarts\n",
                   scan.value().stamp_s - last_stamp_s, index);
    }
    if (scan.ok()) {
      last_stamp_s = scan.value().stamp_s;
      pending_index.push_back(index);
      odometry.value()->Push(std::move(scan).value());
    } else {
      mapper.value().CountSkippedScan();
      report(index, scan.status());
    }
  };
  const std::size_t max_scans = static_cast<std::size_t>(options.max_scans);  // 0: all
  core::Status read = core::Status::Ok();
  if (options.sequential) {
    read = reader.value().ForEach(
        [&](const core::StatusOr<core::LidarScan>& scan, std::size_t index) {
          if (max_scans > 0 && index >= max_scans) return false;
          feed(scan, index);
          while (auto result = odometry.value()->Pop(true)) build(std::move(*result));
          return true;
        });
  } else {
    // The bag is read on a thread of its own; this one keeps the odometry fed with the scans
    // read so far (up to its queue) and builds from its results, waiting only when it has
    // nothing else to do.
    const std::size_t queue = static_cast<std::size_t>(options.odometry_queue);
    msm::conversions::BagReadAhead bag(&reader.value(), kReadAheadScans, max_scans);
    const auto feed_read = [&] {  // the scans read so far, as far as the odometry takes them
      while (odometry.value()->pending() < queue) {
        std::optional<msm::conversions::ReadScan> next = bag.Next(false);
        if (!next) break;
        feed(std::move(next->scan), next->index);
      }
    };
    try {
      for (;;) {
        feed_read();
        if (auto result = odometry.value()->Pop(false)) {
          build(std::move(*result));
        } else if (odometry.value()->pending() > 0) {
          std::optional<core::StatusOr<core::OdometryResult>> waited =
              odometry.value()->Pop(true);
          feed_read();  // what was read while this thread waited, before a long build
          if (waited) build(std::move(*waited));
        } else if (std::optional<msm::conversions::ReadScan> next = bag.Next(true)) {
          feed(std::move(next->scan), next->index);
        } else {
          break;  // all read and built
        }
      }
      read = bag.Finish();
    } catch (const std::exception& e) {  // e.g. out of memory: the map is left as it was
      read = core::Status::Error(std::string("error while mapping: ") + e.what());
    }
  }
  if (descriptors) descriptors->Wait();
  report_descriptor_failures();
  progress.Finish();
  if (!read.ok()) {
    std::fprintf(stderr, "offline_mapper: %s; the map was not changed\n", read.message().c_str());
    return 1;
  }
  core::StatusOr<core::SessionResult> result = mapper.value().Finish();
  if (!result.ok()) {
    std::fprintf(stderr, "offline_mapper: %s; the map was not changed\n",
                 result.status().message().c_str());
    return 1;
  }
  const auto merge_start = std::chrono::steady_clock::now();
  core::SessionRecord record;
  record.name = name;
  record.bag = std::filesystem::path(bag_path).filename().string();
  record.scans = static_cast<std::uint32_t>(result.value().scans_processed);
  const core::Trajectory& scans = result.value().trajectory;
  record.duration_s = scans.back().stamp_s - scans.front().stamp_s;
  record.merged_at = UtcNow();
  result.value().timings.descriptor_ms = recognizer.value().descriptor_ms();
  result.value().timings.query_ms = recognizer.value().query_ms();
  core::SessionFiles files;
  files.place_recognition_csv = recognizer.value().QueriesCsv();
  if (!options.quiet) std::fprintf(stderr, "%s: merging into the map ...\n", name.c_str());
  core::StatusOr<core::MergeReport> merged =
      merger.value().Merge(result.value(), record, recognizer.value(), files, &map);
  if (!merged.ok()) {
    std::fprintf(stderr, "offline_mapper: %s\n", merged.status().message().c_str());
    return 3;
  }
  map.parameters_yaml = core::PipelineConfigToYaml(config);
  result.value().timings.global_registration_s = merged.value().matching.registration_s;
  result.value().timings.guided_registration_s = merged.value().matching.guided_registration_s;
  result.value().timings.dynamic_detection_s = merged.value().dynamic_pair_s;
  core::SessionRunInfo run;
  run.merge_matching_s = merged.value().matching_s;
  run.merge_optimisation_s = merged.value().optimisation_s;
  run.merge_update_s = merged.value().update_s;
  run.merge_update_dynamics_s = merged.value().update_dynamics_s;
  run.merge_update_fusion_s = merged.value().update_fusion_s;
  run.merge_update_database_s = merged.value().update_database_s;
  run.bag_duration_s = record.duration_s;
  run.merge_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - merge_start).count();
  run.wall_time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  run.peak_rss_mb = core::ProcessPeakRssMb();
  map.files["timing/" + name + ".yaml"] = core::TimingYaml(result.value().timings, run);
  const core::Status saved = store.Save(map, options.map_dir);
  if (!saved.ok()) {
    std::fprintf(stderr, "offline_mapper: saving failed: %s\n", saved.message().c_str());
    return 1;
  }
  PrintMergeReport(merged.value());
  const core::FrameAnchorResult& anchor = result.value().anchor;
  if (!merged.value().first_session) {
    // Later sessions are placed by their loops: the anchor is not used.
  } else if (anchor.accepted) {
    std::fprintf(stderr,
                 "%s: frame re-anchored on its first scan: moved %.3f m / %.3f deg (overlap %.2f "
                 "with %zu submaps)\n",
                 name.c_str(), anchor.correction_m, anchor.correction_rad * 180.0 / M_PI,
                 anchor.overlap_ratio, anchor.reference_submaps);
  } else if (!anchor.reason.empty()) {
    std::fprintf(stderr, "%s: frame not re-anchored: %s\n", name.c_str(), anchor.reason.c_str());
  }
  int accepted = 0;
  for (const core::LoopRecord& loop : result.value().loops) {
    accepted += loop.status == core::LoopStatus::kAccepted;
  }
  const core::IntraSessionPairsStats& pairs = result.value().intra_pairs;
  if (pairs.pairs > 0) {
    std::fprintf(stderr,
                 "%s: %zu points of moving objects removed between neighbouring submaps "
                 "(%zu pairs, %zu of them while the session was mapped, %zu left unchanged as "
                 "misaligned, %zu not compared across odometry jumps, %.2f s per pair median)\n",
                 name.c_str(), pairs.points_removed, pairs.pairs, pairs.pairs_during_session,
                 pairs.skipped_pairs,
                 pairs.pairs_across_jumps, core::Summarize(pairs.pair_s).median);
    std::string steps;
    for (const auto& step : pairs.stage_s.Named()) {
      char item[64];
      std::snprintf(item, sizeof(item), "%s%s %.2f s", steps.empty() ? "" : ", ", step.first,
                    step.second);
      steps += item;
    }
    std::fprintf(stderr, "%s: pair detection steps, summed over the pairs: %s\n", name.c_str(),
                 steps.c_str());
  }
  const core::TimingSummary odom = core::Summarize(result.value().timings.odometry_ms);
  std::fprintf(stderr,
               "%s: %zu scans (%zu skipped), %zu submaps, %d intra-session loops accepted, "
               "odometry %.1f ms/scan median, merge %.1f s, %.1f x real time, peak %.0f MB -> %s\n",
               name.c_str(), result.value().scans_processed, result.value().scans_skipped,
               result.value().submaps.size(), accepted, odom.median, run.merge_s,
               run.wall_time_s > 0 ? run.bag_duration_s / run.wall_time_s : 0.0, run.peak_rss_mb,
               options.map_dir.c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  Options options;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    auto value = [&](std::string* out) {
      if (i + 1 >= argc) return false;
      *out = argv[++i];
      return true;
    };
    std::string text;
    if (arg == "--bag" && value(&text)) {
      options.bags.push_back(text);
    } else if (arg == "--map" && value(&options.map_dir)) {
    } else if (arg == "--topic" && value(&options.topic)) {
    } else if (arg == "--config" && value(&options.config_path)) {
    } else if (arg == "--session" && value(&options.session)) {
    } else if (arg == "--max-scans" && value(&text)) {
      if (!msm::tools::ParseInt(text, &options.max_scans) || options.max_scans < 0) {
        return UsageError("--max-scans needs a whole number >= 0");
      }
    } else if (arg == "--odometry-queue" && value(&text)) {
      if (!msm::tools::ParseInt(text, &options.odometry_queue) || options.odometry_queue < 1) {
        return UsageError("--odometry-queue needs a whole number >= 1");
      }
    } else if (arg == "--quiet") {
      options.quiet = true;
    } else if (arg == "--sequential") {
      options.sequential = true;
    } else if (arg == "-h" || arg == "--help") {
      std::fputs(kUsage, stdout);
      return 0;
    } else {
      return UsageError("unknown or incomplete argument '" + arg + "'");
    }
  }
  if (options.bags.empty()) return UsageError("--bag is required");
  if (options.map_dir.empty()) return UsageError("--map is required");
  if (!options.session.empty() && options.bags.size() > 1) {
    return UsageError("--session names one session; give it with a single --bag");
  }
  core::PipelineConfig config;
  if (!options.config_path.empty()) {
    core::StatusOr<core::PipelineConfig> loaded = core::LoadPipelineConfig(options.config_path);
    if (!loaded.ok()) {
      std::fprintf(stderr, "offline_mapper: %s\n", loaded.status().message().c_str());
      return 1;
    }
    config = loaded.value();
  }
  for (const std::string& bag : options.bags) {
    const std::string name =
        options.session.empty() ? std::filesystem::path(bag).stem().string() : options.session;
    const int code = MapSession(options, bag, name, config);
    if (code != 0) return code;
  }
  return 0;
}
