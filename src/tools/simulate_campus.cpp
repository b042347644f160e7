// simulate_campus: writes the simulated multi-session campus (docs/simulator.md): one bag per
// session with /velodyne_points (lz4), and the ground truth beside it. The simulation itself is
// the ROS-free library multisession_mapper_sim; this tool parses arguments, shows progress and
// writes the bags.
#include <sys/stat.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include <ros/time.h>
#include <rosbag/bag.h>

#include "multisession_mapper/ros/conversions.h"
#include "multisession_mapper/sim/campus_simulator.h"
#include "multisession_mapper/tools/cli.h"

namespace msm = multisession_mapper;

namespace {

const char kUsage[] =
    "usage: simulate_campus --out DIR [options]\n"
    "  --profile campus|small|tiny  route scale: ~1 km, ~150 m or ~10 m per session (small)\n"
    "  --sessions N                 number of sessions (days), 1..64 (3)\n"
    "  --seed S                     world and noise seed, unsigned integer (1)\n"
    "  --out DIR                    output folder (created; existing files are overwritten)\n"
    "  --noise SIGMA_M              range noise standard deviation [m] (0.025)\n"
    "  --speed MPS                  robot cruise speed [m/s] (profile default: 1.8/3.0/2.0)\n"
    "  --parked-density F           probability that a changing parking slot is occupied (0.6)\n"
    "  --always-parked F            fraction of slots occupied in every session (0.3)\n"
    "  --movable-density F          scale on bins, construction fences, trucks (1.0)\n"
    "  --moving-density F           scale on moving cars and pedestrians (1.0)\n"
    "  --label-voxel M              voxel of the labels PCD [m] (0.1)\n"
    "  --max-scans N                stop each session after N sweeps (0 = whole route)\n"
    "  --threads N                  simulation threads (2)\n"
    "  --compression lz4|bz2|none   bag compression (lz4)\n"
    "  --quiet                      no progress output\n";

int UsageError(const std::string& message) {
  std::fprintf(stderr, "simulate_campus: %s\n%s", message.c_str(), kUsage);
  return 2;
}

// mkdir -p.
bool MakeDir(const std::string& path) {
  struct stat st;
  if (stat(path.c_str(), &st) == 0) return S_ISDIR(st.st_mode);
  const std::size_t slash = path.find_last_of('/');
  if (slash != std::string::npos && slash > 0 && !MakeDir(path.substr(0, slash))) return false;
  return mkdir(path.c_str(), 0755) == 0 || (stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode));
}

}  // namespace

int main(int argc, char** argv) {
  msm::sim::CampusSimulatorConfig config;
  std::string out_dir;
  std::string compression = "lz4";
  bool quiet = false;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--help" || arg == "-h") {
      std::printf("%s", kUsage);
      return 0;
    }
    if (arg == "--quiet") {
      quiet = true;
      continue;
    }
    if (arg.rfind("--", 0) != 0) return UsageError("unexpected argument '" + arg + "'");
    if (i + 1 >= argc) return UsageError(arg + " needs a value");
    const std::string value = argv[++i];
    double d = 0.0;
    long long n = 0;
    auto bad = [&]() { return UsageError("bad value '" + value + "' for " + arg); };
    if (arg == "--profile") {
      config.campus.profile = value;
    } else if (arg == "--out") {
      out_dir = value;
    } else if (arg == "--compression") {
      if (value != "lz4" && value != "bz2" && value != "none") return bad();
      compression = value;
    } else if (arg == "--sessions") {
      if (!msm::tools::ParseInt(value, &n) || n < 1 || n > 64) return bad();
      config.campus.num_sessions = static_cast<int>(n);
    } else if (arg == "--seed") {
      if (!msm::tools::ParseInt(value, &n) || n < 0) return bad();
      config.campus.seed = static_cast<std::uint64_t>(n);
    } else if (arg == "--threads") {
      if (!msm::tools::ParseInt(value, &n) || n < 1 || n > 256) return bad();
      config.num_threads = static_cast<int>(n);
    } else if (arg == "--max-scans") {
      if (!msm::tools::ParseInt(value, &n) || n < 0) return bad();
      config.max_scans_per_session = static_cast<int>(n);
    } else if (arg == "--noise") {
      if (!msm::tools::ParseDouble(value, &d)) return bad();
      config.sensor.range_noise_sigma_m = d;
    } else if (arg == "--speed") {
      if (!msm::tools::ParseDouble(value, &d) || d <= 0.0) return bad();
      config.campus.cruise_speed_mps = d;
    } else if (arg == "--parked-density") {
      if (!msm::tools::ParseDouble(value, &d)) return bad();
      config.campus.parked_car_density = d;
    } else if (arg == "--always-parked") {
      if (!msm::tools::ParseDouble(value, &d)) return bad();
      config.campus.always_parked_fraction = d;
    } else if (arg == "--movable-density") {
      if (!msm::tools::ParseDouble(value, &d)) return bad();
      config.campus.movable_density = d;
    } else if (arg == "--moving-density") {
      if (!msm::tools::ParseDouble(value, &d)) return bad();
      config.campus.moving_object_density = d;
    } else if (arg == "--label-voxel") {
      if (!msm::tools::ParseDouble(value, &d)) return bad();
      config.label_voxel_m = d;
    } else {
      return UsageError("unknown option '" + arg + "'");
    }
  }
  if (out_dir.empty()) return UsageError("--out DIR is required");
  const msm::core::Status valid = config.Validate();
  if (!valid.ok()) return UsageError(valid.message());

  const auto t_start = std::chrono::steady_clock::now();
  auto created = msm::sim::CampusSimulator::Create(config);
  if (!created.ok()) {
    std::fprintf(stderr, "simulate_campus: %s\n", created.status().message().c_str());
    return 1;
  }
  const msm::sim::CampusSimulator& sim = created.value();
  if (!MakeDir(out_dir) || !MakeDir(out_dir + "/truth")) {
    std::fprintf(stderr, "simulate_campus: cannot create '%s'\n", out_dir.c_str());
    return 1;
  }
  ros::Time::init();
  int total_scans = 0;
  for (int s = 0; s < sim.num_sessions(); ++s) {
    total_scans += static_cast<int>(sim.ScanStamps(s).size());
  }
  if (!quiet) {
    std::fprintf(stderr,
                 "simulate_campus: profile %s, seed %llu, %d sessions, %d sweeps, %zu objects "
                 "(world built in %.1f s)\n",
                 config.campus.profile.c_str(),
                 static_cast<unsigned long long>(config.campus.seed), sim.num_sessions(),
                 total_scans, sim.world().objects.size(),
                 std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start)
                     .count());
  }

  std::vector<msm::sim::SessionSummary> summaries;
  int done = 0;
  const auto t_sim = std::chrono::steady_clock::now();
  for (int s = 0; s < sim.num_sessions(); ++s) {
    const std::string name = sim.world().session_names[s];
    const std::string bag_path = out_dir + "/" + name + ".bag";
    rosbag::Bag bag;
    try {
      bag.open(bag_path, rosbag::bagmode::Write);
      bag.setCompression(compression == "lz4"   ? rosbag::compression::LZ4
                         : compression == "bz2" ? rosbag::compression::BZ2
                                                : rosbag::compression::Uncompressed);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "simulate_campus: cannot write '%s': %s\n", bag_path.c_str(),
                   e.what());
      return 1;
    }
    const int session_scans = static_cast<int>(sim.ScanStamps(s).size());
    auto last_print = std::chrono::steady_clock::now();
    auto sink = [&](int index, const msm::sim::SimulatedScan& scan) -> msm::core::Status {
      sensor_msgs::PointCloud2 msg = msm::conversions::ToPointCloud2(scan.scan, "velodyne");
      msg.header.seq = static_cast<std::uint32_t>(index);
      try {
        bag.write("/velodyne_points", msg.header.stamp, msg);
      } catch (const std::exception& e) {
        return msm::core::Status::Error(std::string("bag write failed: ") + e.what());
      }
      ++done;
      const auto now = std::chrono::steady_clock::now();
      if (!quiet && (std::chrono::duration<double>(now - last_print).count() > 1.0 ||
                     index + 1 == session_scans)) {
        last_print = now;
        const double elapsed = std::chrono::duration<double>(now - t_sim).count();
        const double rate = done / std::max(elapsed, 1e-6);
        std::fprintf(stderr, "\r  %s: %5d/%d sweeps | total %d/%d | %.1f sweeps/s | ETA %s   ",
                     name.c_str(), index + 1, session_scans, done, total_scans, rate,
                     msm::tools::FormatDuration((total_scans - done) / std::max(rate, 1e-6)).c_str());
      }
      return msm::core::Status::Ok();
    };
    msm::sim::SessionSummary summary;
    const msm::core::Status status = sim.RunSession(s, out_dir, sink, &summary);
    bag.close();
    if (!status.ok()) {
      std::fprintf(stderr, "\nsimulate_campus: session %s: %s\n", name.c_str(),
                   status.message().c_str());
      return 1;
    }
    if (!quiet) {
      struct stat st;
      const double mb = stat(bag_path.c_str(), &st) == 0 ? st.st_size / 1e6 : 0.0;
      std::fprintf(stderr,
                   "\n  %s: %d sweeps, %.1f s, %.0f m, %zu points, bag %.1f MB, %.2f ms/sweep "
                   "ray casting\n",
                   name.c_str(), summary.scans, summary.duration_s, summary.route_length_m,
                   summary.points, mb, summary.raycast_ms_per_scan);
    }
    summaries.push_back(summary);
  }
  const msm::core::Status status = sim.WriteIndex(out_dir, summaries);
  if (!status.ok()) {
    std::fprintf(stderr, "simulate_campus: %s\n", status.message().c_str());
    return 1;
  }
  if (!quiet) {
    std::fprintf(stderr, "simulate_campus: wrote %s in %.1f s\n", out_dir.c_str(),
                 std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start)
                     .count());
  }
  return 0;
}
