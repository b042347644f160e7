// Runs the simulated campus: generates the world and the routes (CampusGenerator), indexes the
// static world for ray casting, simulates every VLP-16 sweep of every session and writes the
// ground truth (docs/simulator.md): truth/<session>.tum, truth/<session>_labels.pcd,
// world.yaml and sessions.yaml. Writing the sweeps themselves (bags) is the caller's business,
// through a sink, so this library stays free of ROS.
//
// Determinism: every random draw of a sweep is keyed on (seed, session, scan index, ray), and
// sweeps computed on worker threads are handed to the sink and to the truth accumulators
// strictly in scan order, so the output is byte-identical for any number of threads.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "multisession_mapper/core/status.h"
#include "multisession_mapper/sim/campus_generator.h"
#include "multisession_mapper/sim/ray_caster.h"
#include "multisession_mapper/sim/vlp16.h"
#include "multisession_mapper/sim/world.h"

namespace multisession_mapper {
namespace sim {

struct CampusSimulatorConfig {
  CampusConfig campus;
  Vlp16Config sensor;
  RayCasterConfig ray_caster;
  double label_voxel_m = 0.1;      ///< voxel of the labels PCD [m]; 0 keeps every return
  int num_threads = 2;             ///< sweeps simulated in parallel (>= 1)
  int max_scans_per_session = 0;   ///< 0: the whole route; > 0: stop after this many sweeps

  core::Status Validate() const;
};

struct SessionSummary {
  std::string name;
  int scans = 0;
  double start_stamp_s = 0.0;
  double duration_s = 0.0;       ///< last stamp - first stamp + one sweep period
  double route_length_m = 0.0;   ///< distance driven during the recorded sweeps
  std::size_t points = 0;        ///< returns in all sweeps
  std::size_t label_points = 0;  ///< points in the labels PCD
  double raycast_ms_per_scan = 0.0;  ///< mean thread CPU time to simulate one sweep [ms]
};

class CampusSimulator {
 public:
  static core::StatusOr<CampusSimulator> Create(const CampusSimulatorConfig& config);

  const World& world() const { return campus_.world; }
  const RayCaster& ray_caster() const { return caster_; }
  const Vlp16& sensor() const { return sensor_; }
  int num_sessions() const { return static_cast<int>(campus_.trajectories.size()); }
  const RobotTrajectory& trajectory(int session) const { return campus_.trajectories[session]; }
  const CampusSimulatorConfig& config() const { return config_; }

  /// Start stamps of the sweeps of a session.
  std::vector<double> ScanStamps(int session) const;
  /// Moving objects present in a session.
  std::vector<const WorldObject*> Movers(int session) const;
  /// One sweep; thread-safe and deterministic.
  SimulatedScan SimulateScan(int session, int index) const;

  /// Simulates the session's sweeps on config.num_threads threads and calls `sink` for each, in
  /// order, on the calling thread; then writes truth/<name>.tum and truth/<name>_labels.pcd
  /// under `out_dir` (which must exist with a truth/ folder). A sink error stops the run.
  core::Status RunSession(int session, const std::string& out_dir,
                          const std::function<core::Status(int, const SimulatedScan&)>& sink,
                          SessionSummary* summary) const;

  /// world.yaml and sessions.yaml for the finished sessions.
  core::Status WriteIndex(const std::string& out_dir,
                          const std::vector<SessionSummary>& sessions) const;

 private:
  CampusSimulator(const CampusSimulatorConfig& config, Campus campus, RayCaster caster,
                  Vlp16 sensor)
      : config_(config),
        campus_(std::move(campus)),
        caster_(std::move(caster)),
        sensor_(std::move(sensor)) {}

  CampusSimulatorConfig config_;
  Campus campus_;
  RayCaster caster_;
  Vlp16 sensor_;
};

}  // namespace sim
}  // namespace multisession_mapper
