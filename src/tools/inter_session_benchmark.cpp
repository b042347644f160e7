// inter_session_benchmark: evaluates inter-session loop detection (issue 6, items 4-5) on a
// simulated session against a stored map. Not part of the pipeline and not a test.
//   inter_session_benchmark --map DIR --bag s01.bag --truth-dir truth/ [options]
// It maps the bag with SessionMapper + PlaceRecognizer (queries against the map's descriptor
// database, as offline_mapper does), runs InterSessionMatcher once per requested global
// registration method, and compares the loops with the simulator's ground truth.
//
// READS GROUND TRUTH, for evaluation only: truth/<session>.tum (sensor poses in the simulator's
// world frame at every scan stamp) of the map's session and of the new one. The matcher never
// sees it. Truth per loop: T_history_current = T_world_hist0^-1 * T_world_cur0 at the first
// scan stamps of the two submaps (a submap's origin is the sensor pose of its first scan).
// A current submap "overlaps history" when one of its scans was taken within --overlap-radius of
// a scan of an active history submap (truth positions). An accepted loop is correct when its
// pose is within --correct-m / --correct-deg of the truth, otherwise wrong.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "multisession_mapper/core/descriptor_database.h"
#include "multisession_mapper/core/inter_session_matcher.h"
#include "multisession_mapper/core/map_store.h"
#include "multisession_mapper/core/pipeline_config.h"
#include "multisession_mapper/core/place_recognizer.h"
#include "multisession_mapper/core/se3.h"
#include "multisession_mapper/core/session_mapper.h"
#include "multisession_mapper/core/trajectory_io.h"
#include "multisession_mapper/ros/bag_scan_reader.h"
#include "multisession_mapper/tools/cli.h"

namespace msm = multisession_mapper;
namespace core = multisession_mapper::core;

namespace {

const char kUsage[] =
    "usage: inter_session_benchmark --map DIR --bag FILE --truth-dir DIR [options]\n"
    "  --map DIR            map holding the history session(s) and database/descriptors.bin\n"
    "  --bag FILE           the new session's bag (session name: file name without extension)\n"
    "  --truth-dir DIR      simulator truth folder (<session>.tum); evaluation only\n"
    "  --config FILE        pipeline configuration YAML (defaults otherwise)\n"
    "  --method M           fpfh_ransac | yaw_search_icp | both (default fpfh_ransac)\n"
    "  --topic NAME         PointCloud2 topic (/velodyne_points)\n"
    "  --overlap-radius M   truth overlap: scans within this distance [m] (10)\n"
    "  --correct-m M        accepted loop is correct within this error [m] (1.0)\n"
    "  --correct-deg D      ... and this rotation error [deg] (3.0)\n"
    "  --json FILE          also write the figures as JSON (for scripts/bench.d)\n"
    "  --verbose            one line per record\n";

int UsageError(const std::string& message) {
  std::fprintf(stderr, "inter_session_benchmark: %s\n%s", message.c_str(), kUsage);
  return 2;
}

// Truth pose at `stamp_s` (interpolated between the two nearest stamps).
bool TruthAt(const core::Trajectory& truth, double stamp_s, core::Pose3* pose) {
  if (truth.empty()) return false;
  auto it = std::lower_bound(truth.begin(), truth.end(), stamp_s,
                             [](const core::StampedPose& p, double t) { return p.stamp_s < t; });
  if (it == truth.end()) it = std::prev(it);
  if (it == truth.begin()) {
    *pose = it->pose;
    return std::abs(it->stamp_s - stamp_s) < 0.2;
  }
  const core::StampedPose& b = *it;
  const core::StampedPose& a = *std::prev(it);
  const double span = b.stamp_s - a.stamp_s;
  const double alpha = span > 0.0 ? std::clamp((stamp_s - a.stamp_s) / span, 0.0, 1.0) : 0.0;
  *pose = core::se3::Interpolate(a.pose, b.pose, alpha);
  return stamp_s >= a.stamp_s - 0.2 && stamp_s <= b.stamp_s + 0.2;
}

double Median(std::vector<double> v) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  return v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
}

struct Options {
  std::string map_dir, bag, truth_dir, config_path, json_path, method = "fpfh_ransac";
  std::string topic = "/velodyne_points";
  double overlap_radius_m = 10.0, correct_m = 1.0, correct_deg = 3.0;
  bool verbose = false;
};

}  // namespace

int main(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    auto value = [&](std::string* out) {
      if (i + 1 >= argc) return false;
      *out = argv[++i];
      return true;
    };
    std::string text;
    if (arg == "--map" && value(&o.map_dir)) {
    } else if (arg == "--bag" && value(&o.bag)) {
    } else if (arg == "--truth-dir" && value(&o.truth_dir)) {
    } else if (arg == "--config" && value(&o.config_path)) {
    } else if (arg == "--method" && value(&o.method)) {
    } else if (arg == "--topic" && value(&o.topic)) {
    } else if (arg == "--overlap-radius" && value(&text)) {
      if (!msm::tools::ParseDouble(text, &o.overlap_radius_m)) return UsageError("bad --overlap-radius");
    } else if (arg == "--correct-m" && value(&text)) {
      if (!msm::tools::ParseDouble(text, &o.correct_m)) return UsageError("bad --correct-m");
    } else if (arg == "--correct-deg" && value(&text)) {
      if (!msm::tools::ParseDouble(text, &o.correct_deg)) return UsageError("bad --correct-deg");
    } else if (arg == "--json" && value(&o.json_path)) {
    } else if (arg == "--verbose") {
      o.verbose = true;
    } else if (arg == "-h" || arg == "--help") {
      std::fputs(kUsage, stdout);
      return 0;
    } else {
      return UsageError("unknown or incomplete argument '" + arg + "'");
    }
  }
  if (o.map_dir.empty() || o.bag.empty() || o.truth_dir.empty()) {
    return UsageError("--map, --bag and --truth-dir are required");
  }
  std::vector<core::GlobalRegistrationConfig::Method> methods;
  if (o.method == "fpfh_ransac" || o.method == "both") {
    methods.push_back(core::GlobalRegistrationConfig::Method::kFpfhRansac);
  }
  if (o.method == "yaw_search_icp" || o.method == "both") {
    methods.push_back(core::GlobalRegistrationConfig::Method::kYawSearchIcp);
  }
  if (methods.empty()) return UsageError("unknown --method '" + o.method + "'");

  core::PipelineConfig config;
  if (!o.config_path.empty()) {
    core::StatusOr<core::PipelineConfig> loaded = core::LoadPipelineConfig(o.config_path);
    if (!loaded.ok()) return UsageError(loaded.status().message());
    config = loaded.value();
  }
  const core::MapStore store;
  core::StatusOr<core::MapContents> map = store.Load(o.map_dir);
  if (!map.ok()) return UsageError("cannot load the map: " + map.status().message());
  core::StatusOr<core::DescriptorDatabase> db = core::DescriptorDatabase::Load(
      o.map_dir + "/database/descriptors.bin", config.place_recognition.database);
  if (!db.ok()) return UsageError("database: " + db.status().message());
  auto history_db = std::make_shared<const core::DescriptorDatabase>(std::move(db.value()));

  // Map the new session (as offline_mapper does).
  const std::string name = std::filesystem::path(o.bag).stem().string();
  core::StatusOr<msm::conversions::BagScanReader> reader =
      msm::conversions::BagScanReader::Open(o.bag, o.topic);
  if (!reader.ok()) return UsageError(reader.status().message());
  core::StatusOr<core::SessionMapper> mapper = core::SessionMapper::Create(config.session, name);
  core::StatusOr<core::PlaceRecognizer> recognizer =
      core::PlaceRecognizer::Create(config.place_recognition, name, history_db);
  if (!mapper.ok() || !recognizer.ok()) {
    return UsageError(!mapper.ok() ? mapper.status().message() : recognizer.status().message());
  }
  msm::tools::Progress progress(name, reader.value().num_messages(), "scans");
  const core::Status read = reader.value().ForEach(
      [&](const core::StatusOr<core::LidarScan>& scan, std::size_t index) {
        core::Status status = scan.ok() ? mapper.value().AddScan(scan.value()) : scan.status();
        if (status.ok()) {
          status = recognizer.value().AddScan(mapper.value().last_odometry()->deskewed_scan,
                                              mapper.value().current_submap_id());
        }
        progress.Update(index + 1);
        return true;
      });
  progress.Finish();
  if (!read.ok()) return UsageError(read.message());
  core::StatusOr<core::SessionResult> session = mapper.value().Finish();
  if (!session.ok()) return UsageError(session.status().message());

  // Truth (evaluation only).
  std::map<std::string, core::Trajectory> truth;
  for (const core::SessionRecord& s : map.value().sessions) {
    core::StatusOr<core::Trajectory> t = core::ReadTumFile(o.truth_dir + "/" + s.name + ".tum");
    if (!t.ok()) return UsageError(t.status().message());
    truth[s.name] = t.value();
  }
  core::StatusOr<core::Trajectory> cur_truth = core::ReadTumFile(o.truth_dir + "/" + name + ".tum");
  if (!cur_truth.ok()) return UsageError(cur_truth.status().message());

  const auto& hist = map.value().submaps;
  const auto& cur = session.value().submaps;
  // Which current submaps overlap the (active) history, from truth scan positions.
  std::vector<Eigen::Vector3d> history_positions;
  for (const core::Submap& h : hist) {
    if (h.state != core::SubmapState::kActive) continue;
    for (const core::SubmapScanRecord& r : h.scans) {
      core::Pose3 p;
      if (TruthAt(truth[h.session], r.stamp_s, &p)) history_positions.push_back(p.translation());
    }
  }
  std::map<std::uint32_t, bool> overlaps;
  for (const core::Submap& c : cur) {
    bool any = false;
    for (const core::SubmapScanRecord& r : c.scans) {
      core::Pose3 p;
      if (!TruthAt(cur_truth.value(), r.stamp_s, &p)) continue;
      for (const Eigen::Vector3d& h : history_positions) {
        if ((h - p.translation()).norm() <= o.overlap_radius_m) {
          any = true;
          break;
        }
      }
      if (any) break;
    }
    overlaps[c.id] = any;
  }
  std::map<std::uint32_t, const core::Submap*> cur_by_id;
  for (const core::Submap& c : cur) cur_by_id[c.id] = &c;
  auto true_relative = [&](const core::Submap& h, const core::Submap& c, core::Pose3* rel) {
    core::Pose3 th, tc;
    if (!TruthAt(truth[h.session], h.first_stamp_s(), &th) ||
        !TruthAt(cur_truth.value(), c.first_stamp_s(), &tc)) {
      return false;
    }
    *rel = th.inverse() * tc;
    return true;
  };
  std::map<std::pair<std::string, std::int64_t>, std::size_t> hist_index;
  for (std::size_t i = 0; i < hist.size(); ++i) hist_index[{hist[i].session, hist[i].id}] = i;

  std::size_t num_overlapping = 0;
  for (const auto& [id, ov] : overlaps) num_overlapping += ov;
  std::printf("session %s: %zu submaps, %zu overlap the history by truth (%.0f m); history %zu "
              "submaps\n",
              name.c_str(), cur.size(), num_overlapping, o.overlap_radius_m, hist.size());

  std::string json = "{\"session\": \"" + name + "\", \"submaps\": " +
                     std::to_string(cur.size()) + ", \"overlapping\": " +
                     std::to_string(num_overlapping) + ", \"methods\": {";
  for (core::GlobalRegistrationConfig::Method method : methods) {
    core::InterSessionMatcherConfig matcher_config;
    matcher_config.registration.method = method;
    core::StatusOr<core::InterSessionMatcher> matcher = core::InterSessionMatcher::Create(matcher_config);
    if (!matcher.ok()) return UsageError(matcher.status().message());
    const auto start = std::chrono::steady_clock::now();
    const std::clock_t cpu_start = std::clock();
    core::StatusOr<core::InterSessionMatchResult> result =
        matcher.value().Match(map.value(), session.value(), recognizer.value());
    const double total_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const double cpu_s = static_cast<double>(std::clock() - cpu_start) / CLOCKS_PER_SEC;
    if (!result.ok()) return UsageError(result.status().message());

    // Per current submap: correct / wrong / unmatched; all registered pairs: pose error.
    std::map<std::uint32_t, int> correct, wrong;
    std::vector<double> err_m, err_deg, reg_err_m, reg_err_deg;
    int registered_good_rejected = 0, candidates = 0;
    for (const core::LoopRecord& r : result.value().records) {
      if (r.status == core::LoopStatus::kUndefined) {
        if (o.verbose) {
          std::printf("  cur %u undefined (%s)%s\n", r.current_submap, r.reason.c_str(),
                      overlaps[r.current_submap] ? " [overlaps by truth]" : "");
        }
        continue;
      }
      ++candidates;
      const auto hi = hist_index.find({r.history_session, r.history_submap});
      core::Pose3 rel;
      const bool have_truth = hi != hist_index.end() &&
                              true_relative(hist[hi->second], *cur_by_id[r.current_submap], &rel);
      double em = NAN, ed = NAN;
      if (have_truth && r.has_pose) {
        const core::Pose3 error = core::se3::Between(rel, r.T_history_current);
        em = core::se3::TranslationNorm(error);
        ed = core::se3::RotationAngleRad(error) * 180.0 / M_PI;
      }
      const bool good = em <= o.correct_m && ed <= o.correct_deg;
      if (r.has_pose && have_truth && r.overlap_ratio > 0.0) {
        reg_err_m.push_back(em);
        reg_err_deg.push_back(ed);
      }
      if (r.status == core::LoopStatus::kAccepted) {
        (good ? correct : wrong)[r.current_submap] += 1;
        err_m.push_back(em);
        err_deg.push_back(ed);
      } else if (good) {
        ++registered_good_rejected;
      }
      if (o.verbose) {
        std::printf("  cur %u -> %s/%lld %s vote %.2f overlap %.2f err %.3f m %.3f deg %s\n",
                    r.current_submap, r.history_session.c_str(),
                    static_cast<long long>(r.history_submap), core::LoopStatusName(r.status),
                    r.vote_proportion, r.overlap_ratio, em, ed, r.reason.c_str());
      }
    }
    int matched_ok = 0, matched_wrong = 0, overlapping_unmatched = 0, new_place_undefined = 0;
    for (const core::Submap& c : cur) {
      if (wrong.count(c.id)) {
        ++matched_wrong;
      } else if (correct.count(c.id)) {
        ++matched_ok;
      } else if (overlaps[c.id]) {
        ++overlapping_unmatched;
      } else {
        ++new_place_undefined;
      }
    }
    const std::vector<double>& times = result.value().registration_s;
    std::printf(
        "[%s] submaps: %d correctly matched, %d wrongly matched, %d overlapping but unmatched, "
        "%d in new places without loop; matched %.1f %% of the %zu overlapping; %zu accepted "
        "loops of %d registered candidates (%d correct poses rejected); aligned %s\n",
        core::GlobalRegistrationMethodName(method), matched_ok, matched_wrong,
        overlapping_unmatched, new_place_undefined,
        num_overlapping ? 100.0 * matched_ok / num_overlapping : 0.0, num_overlapping,
        result.value().loops.size(), candidates, registered_good_rejected,
        result.value().aligned ? "yes" : "no");
    std::printf("[%s] accepted-loop RPE median %.3f m / %.3f deg (max %.3f m / %.3f deg); all "
                "registered pairs median %.3f m / %.3f deg\n",
                core::GlobalRegistrationMethodName(method), Median(err_m), Median(err_deg),
                err_m.empty() ? NAN : *std::max_element(err_m.begin(), err_m.end()),
                err_deg.empty() ? NAN : *std::max_element(err_deg.begin(), err_deg.end()),
                Median(reg_err_m), Median(reg_err_deg));
    std::printf("[%s] time per registered pair: median %.3f s, max %.3f s (%zu pairs); matcher "
                "total %.1f s wall, %.1f s CPU (single-threaded: CPU / pairs is the cost per pair on an "
                "unloaded core)\n",
                core::GlobalRegistrationMethodName(method), Median(times),
                times.empty() ? NAN : *std::max_element(times.begin(), times.end()),
                result.value().registration_s.size(), total_s, cpu_s);
    char buffer[512];
    std::snprintf(buffer, sizeof(buffer),
                  "%s\"%s\": {\"correct\": %d, \"wrong\": %d, \"overlapping_unmatched\": %d, "
                  "\"new_place_without_loop\": %d, \"rpe_median_m\": %.4f, "
                  "\"rpe_median_deg\": %.4f, \"pair_time_median_s\": %.4f, \"pairs\": %zu, "
                  "\"aligned\": %s}",
                  method == methods.front() ? "" : ", ", core::GlobalRegistrationMethodName(method),
                  matched_ok, matched_wrong, overlapping_unmatched, new_place_undefined,
                  err_m.empty() ? -1.0 : Median(err_m), err_deg.empty() ? -1.0 : Median(err_deg),
                  times.empty() ? -1.0 : Median(times), times.size(),
                  result.value().aligned ? "true" : "false");
    json += buffer;
  }
  json += "}}\n";
  if (!o.json_path.empty()) {
    std::FILE* f = std::fopen(o.json_path.c_str(), "w");
    if (f == nullptr || std::fputs(json.c_str(), f) < 0 || std::fclose(f) != 0) {
      std::fprintf(stderr, "inter_session_benchmark: cannot write %s\n", o.json_path.c_str());
      return 1;
    }
  }
  return 0;
}
