// Procedural campus (about 500 m x 500 m) from a seed: a grid of two-lane roads with curbs,
// parking strips and sidewalks over gently rolling terrain with one ramp; blocks holding
// buildings with facade relief, parks, parking lots and plazas; walls, fences, lamp posts,
// hedges and trees with porous canopies. Low-dynamic objects (parked cars in slots, bins,
// construction fences, trucks) are present in a per-session subset; the robot routes of the
// sessions (shared roads, different starts, opposite directions, areas only one session sees, a
// revisit of its own path) and the moving cars and pedestrians (background traffic on the road
// grid plus encounters timed to pass close to the robot) are generated with them.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "multisession_mapper/core/status.h"
#include "multisession_mapper/sim/robot_trajectory.h"
#include "multisession_mapper/sim/world.h"

namespace multisession_mapper {
namespace sim {

struct CampusConfig {
  /// "campus" (~1 km route per session), "small" (~150 m) or "tiny" (~10 m, for tests).
  std::string profile = "small";
  std::uint64_t seed = 1;
  int num_sessions = 3;                 ///< 1..64
  double parked_car_density = 0.6;      ///< probability that a changing slot is occupied [0, 1]
  double always_parked_fraction = 0.3;  ///< slots occupied in every session [0, 1]
  double movable_density = 1.0;         ///< scale on bins, construction fences, trucks (>= 0)
  double moving_object_density = 1.0;   ///< scale on moving cars and pedestrians (>= 0)
  /// Robot cruise speed [m/s]; 0 = the profile's default (campus 1.8, small 3.0, tiny 2.0).
  double cruise_speed_mps = 0.0;
  double base_stamp_s = 1700000000.0;  ///< stamp of the first session's start [s]
  double session_spacing_s = 86400.0;  ///< one session per day [s]
  RobotTrajectoryConfig robot;         ///< cruise_speed_mps is set from the field above

  core::Status Validate() const;
};

struct Campus {
  World world;
  std::vector<RobotTrajectory> trajectories;  ///< one per session
};

core::StatusOr<Campus> GenerateCampus(const CampusConfig& config);

/// Session names: s00, s01, ...
std::string SessionName(int index);

}  // namespace sim
}  // namespace multisession_mapper
