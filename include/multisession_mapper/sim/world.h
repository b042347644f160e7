// The simulated world as the ground truth describes it (world.yaml, docs/simulator.md): terrain
// grid and every object with its class, bounding shape, pose, size, the sessions in which it is
// present, its parts (the primitives that are actually ray-cast, in the object frame) and, for
// moving objects, a trajectory. Ray-castable primitives are derived from this description, so
// what the evaluator reads is exactly what the sensor saw.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "multisession_mapper/core/status.h"
#include "multisession_mapper/core/types.h"
#include "multisession_mapper/sim/primitive.h"
#include "multisession_mapper/sim/terrain.h"

namespace multisession_mapper {
namespace sim {

/// One primitive of an object, in the object frame.
struct ObjectPart {
  Shape shape = Shape::kBox;
  Eigen::Vector3d center_m = Eigen::Vector3d::Zero();  ///< object frame [m]
  Eigen::Vector3d rpy_rad = Eigen::Vector3d::Zero();   ///< roll, pitch, yaw in the object frame
  Eigen::Vector3d size_m = Eigen::Vector3d::Ones();    ///< full extents (cylinder: d, d, h)
  double density_per_m = 0.0;                          ///< 0 solid, > 0 porous [1/m]
  double reflectivity = 0.3;                           ///< [0, 1]
};

/// A moving object's pose at a time (linear interpolation between rows, absent outside).
struct TrajectoryRow {
  double stamp_s = 0.0;
  Eigen::Vector3d position_m = Eigen::Vector3d::Zero();  ///< object centre
  double yaw_rad = 0.0;
};

struct WorldObject {
  std::uint32_t id = 0;  ///< > 0; 0 is the terrain in the labels
  ObjectClass object_class = ObjectClass::kBuilding;
  std::string kind;  ///< finer type: "curb", "lamp_post", "bin", "truck", ... (free text)
  Shape shape = Shape::kBox;  ///< bounding shape
  Eigen::Vector3d position_m = Eigen::Vector3d::Zero();  ///< bounding-shape centre
  double yaw_rad = 0.0;
  double roll_rad = 0.0;   ///< non-zero for objects that follow the slope (curbs)
  double pitch_rad = 0.0;
  Eigen::Vector3d size_m = Eigen::Vector3d::Ones();  ///< bounding-shape full extents
  std::uint64_t sessions_mask = ~0ULL;               ///< bit s: present in session s
  std::vector<ObjectPart> parts;                     ///< empty: the bounding shape itself
  std::vector<TrajectoryRow> trajectory;             ///< moving objects only

  bool moving() const { return !trajectory.empty(); }
  /// Object pose (T_world_object) for a static object.
  core::Pose3 Pose() const;
  /// Pose of a moving object at `stamp_s`; false outside its trajectory.
  bool PoseAt(double stamp_s, core::Pose3* pose) const;
  /// World-frame primitives for an object pose (parts, or the bounding shape when none).
  std::vector<Primitive> Primitives(const core::Pose3& pose) const;
};

struct World {
  std::string format = "multisession_mapper_sim/1";
  std::string profile;
  std::uint64_t seed = 0;
  std::vector<std::string> session_names;
  TerrainGrid terrain;
  std::vector<WorldObject> objects;

  /// Bit mask with every session set.
  std::uint64_t AllSessionsMask() const;
  /// Primitives of every static object (moving ones excluded), with session masks.
  std::vector<Primitive> StaticPrimitives() const;
  core::Status Validate() const;
};

}  // namespace sim
}  // namespace multisession_mapper
