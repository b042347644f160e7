#include "multisession_mapper/sim/campus_simulator.h"

#include <atomic>
#include <condition_variable>
#include <cstdio>
#include <fstream>
#include <map>
#include <memory>
#include <mutex>
#include <thread>

#include <time.h>

#include "multisession_mapper/core/trajectory_io.h"
#include "multisession_mapper/sim/counter_rng.h"
#include "multisession_mapper/sim/label_cloud.h"
#include "multisession_mapper/sim/world_io.h"

namespace multisession_mapper {
namespace sim {
namespace {

// CPU time of the calling thread [ns]: meaningful on a loaded machine, unlike wall time.
long long ThreadCpuNs() {
  timespec ts;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<long long>(ts.tv_sec) * 1000000000LL + ts.tv_nsec;
}

std::string Fixed(double v, int decimals) {
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), "%.*f", decimals, v);
  return buffer;
}

}  // namespace

core::Status CampusSimulatorConfig::Validate() const {
  core::Status status = campus.Validate();
  if (!status.ok()) return status;
  status = sensor.Validate();
  if (!status.ok()) return status;
  status = ray_caster.Validate();
  if (!status.ok()) return status;
  if (!(label_voxel_m >= 0.0 && label_voxel_m < 10.0)) {
    return core::Status::Error("label_voxel_m must be in [0, 10)");
  }
  if (num_threads < 1 || num_threads > 256) {
    return core::Status::Error("num_threads must be in [1, 256]");
  }
  if (max_scans_per_session < 0) return core::Status::Error("max_scans_per_session must be >= 0");
  return core::Status::Ok();
}

core::StatusOr<CampusSimulator> CampusSimulator::Create(const CampusSimulatorConfig& config) {
  core::Status status = config.Validate();
  if (!status.ok()) return status;
  auto campus = GenerateCampus(config.campus);
  if (!campus.ok()) return campus.status();
  auto terrain = Terrain::Create(campus.value().world.terrain);
  if (!terrain.ok()) return terrain.status();
  auto caster = RayCaster::Create(std::move(terrain).value(),
                                  campus.value().world.StaticPrimitives(), config.ray_caster);
  if (!caster.ok()) return caster.status();
  auto sensor = Vlp16::Create(config.sensor);
  if (!sensor.ok()) return sensor.status();
  return CampusSimulator(config, std::move(campus).value(), std::move(caster).value(),
                         std::move(sensor).value());
}

std::vector<double> CampusSimulator::ScanStamps(int session) const {
  const RobotTrajectory& traj = campus_.trajectories[session];
  const double period = sensor_.period_s();
  std::vector<double> stamps;
  for (int k = 0;; ++k) {
    const double t = traj.start_stamp_s() + k * period;
    if (t + period > traj.end_stamp_s()) break;
    if (config_.max_scans_per_session > 0 && k >= config_.max_scans_per_session) break;
    stamps.push_back(t);
  }
  return stamps;
}

std::vector<const WorldObject*> CampusSimulator::Movers(int session) const {
  std::vector<const WorldObject*> movers;
  for (const WorldObject& o : campus_.world.objects) {
    if (o.moving() && (o.sessions_mask & (1ULL << session))) movers.push_back(&o);
  }
  return movers;
}

SimulatedScan CampusSimulator::SimulateScan(int session, int index) const {
  const std::vector<double> stamps = ScanStamps(session);
  const RobotTrajectory& traj = campus_.trajectories[session];
  return sensor_.Simulate(
      caster_, Movers(session), [&traj](double t) { return traj.SensorPose(t); }, session,
      stamps.at(index), MakeKey(campus_.world.seed, session, index, 0x5CA7));
}

core::Status CampusSimulator::RunSession(
    int session, const std::string& out_dir,
    const std::function<core::Status(int, const SimulatedScan&)>& sink,
    SessionSummary* summary) const {
  if (session < 0 || session >= num_sessions()) {
    return core::Status::Error("no session " + std::to_string(session));
  }
  const std::vector<double> stamps = ScanStamps(session);
  const int n = static_cast<int>(stamps.size());
  const RobotTrajectory& traj = campus_.trajectories[session];
  const std::vector<const WorldObject*> movers = Movers(session);
  const std::uint64_t seed = campus_.world.seed;

  // Workers fill a window of slots ahead of the consumer; the consumer takes them in order.
  const int window = 4 * config_.num_threads;
  std::vector<std::unique_ptr<SimulatedScan>> slots(window);
  std::mutex mutex;
  std::condition_variable cv;
  int consumed = 0;
  bool abort = false;
  std::atomic<int> next{0};
  std::atomic<long long> cpu_ns{0};
  auto worker = [&]() {
    while (true) {
      const int i = next.fetch_add(1);
      if (i >= n) return;
      {
        std::unique_lock<std::mutex> lock(mutex);
        cv.wait(lock, [&] { return abort || i < consumed + window; });
        if (abort) return;
      }
      const long long t0 = ThreadCpuNs();
      auto scan = std::make_unique<SimulatedScan>(sensor_.Simulate(
          caster_, movers, [&traj](double t) { return traj.SensorPose(t); }, session,
          stamps[i], MakeKey(seed, session, i, 0x5CA7)));
      cpu_ns += ThreadCpuNs() - t0;
      {
        std::lock_guard<std::mutex> lock(mutex);
        slots[i % window] = std::move(scan);
      }
      cv.notify_all();
    }
  };
  std::vector<std::thread> threads;
  for (int k = 0; k < config_.num_threads; ++k) threads.emplace_back(worker);

  LabelCloud labels(config_.label_voxel_m);
  core::Trajectory truth;
  core::Status status = core::Status::Ok();
  std::size_t points = 0;
  for (int i = 0; i < n; ++i) {
    std::unique_ptr<SimulatedScan> scan;
    {
      std::unique_lock<std::mutex> lock(mutex);
      cv.wait(lock, [&] { return slots[i % window] != nullptr; });
      scan = std::move(slots[i % window]);
    }
    status = sink(i, *scan);
    {
      std::lock_guard<std::mutex> lock(mutex);
      ++consumed;
      if (!status.ok()) abort = true;
    }
    cv.notify_all();
    if (!status.ok()) break;
    labels.Add(scan->truth);
    points += scan->scan.points.size();
    core::StampedPose sp;
    sp.stamp_s = scan->scan.stamp_s;
    sp.pose = scan->pose_at_stamp;
    truth.push_back(sp);
  }
  for (std::thread& t : threads) t.join();
  if (!status.ok()) return status;

  const std::string name = campus_.world.session_names[session];
  status = core::WriteTumFile(out_dir + "/truth/" + name + ".tum", truth);
  if (!status.ok()) return status;
  status = labels.WritePcd(out_dir + "/truth/" + name + "_labels.pcd");
  if (!status.ok()) return status;
  if (summary) {
    summary->name = name;
    summary->scans = n;
    summary->start_stamp_s = n > 0 ? stamps.front() : traj.start_stamp_s();
    summary->duration_s = n > 0 ? stamps.back() - stamps.front() + sensor_.period_s() : 0.0;
    summary->route_length_m =
        n > 0 ? traj.ArcLength(stamps.back() + sensor_.period_s()) - traj.ArcLength(stamps.front())
              : 0.0;
    summary->points = points;
    summary->label_points = labels.size();
    summary->raycast_ms_per_scan = n > 0 ? 1e-6 * static_cast<double>(cpu_ns.load()) / n : 0.0;
  }
  return core::Status::Ok();
}

core::Status CampusSimulator::WriteIndex(const std::string& out_dir,
                                         const std::vector<SessionSummary>& sessions) const {
  core::Status status = WriteWorldYamlFile(out_dir + "/world.yaml", campus_.world);
  if (!status.ok()) return status;
  const std::string path = out_dir + "/sessions.yaml";
  std::ofstream out(path, std::ios::binary);
  if (!out) return core::Status::Error("cannot open '" + path + "' for writing");
  const Vlp16Config& s = config_.sensor;
  out << "format: multisession_mapper_sim/1\n"
      << "profile: " << config_.campus.profile << "\n"
      << "seed: " << config_.campus.seed << "\n"
      << "label_voxel_m: " << Fixed(config_.label_voxel_m, 3) << "\n"
      << "lidar_topic: /velodyne_points\n"
      << "frame_id: velodyne\n"
      << "sensor: {model: VLP-16, rate_hz: " << Fixed(s.rate_hz, 3)
      << ", columns: " << s.num_columns << ", max_range_m: " << Fixed(s.max_range_m, 3)
      << ", range_noise_sigma_m: " << Fixed(s.range_noise_sigma_m, 4)
      << ", height_above_ground_m: " << Fixed(config_.campus.robot.sensor_height_m, 3) << "}\n"
      << "sessions:\n";
  for (const SessionSummary& ss : sessions) {
    out << "  - name: " << ss.name << "\n"
        << "    bag: " << ss.name << ".bag\n"
        << "    truth_trajectory: truth/" << ss.name << ".tum\n"
        << "    labels: truth/" << ss.name << "_labels.pcd\n"
        << "    scans: " << ss.scans << "\n"
        << "    start_stamp_s: " << Fixed(ss.start_stamp_s, 6) << "\n"
        << "    duration_s: " << Fixed(ss.duration_s, 3) << "\n"
        << "    route_length_m: " << Fixed(ss.route_length_m, 2) << "\n"
        << "    points: " << ss.points << "\n"
        << "    label_points: " << ss.label_points << "\n";
  }
  out.close();
  if (!out) return core::Status::Error("write error on '" + path + "'");
  return core::Status::Ok();
}

}  // namespace sim
}  // namespace multisession_mapper
