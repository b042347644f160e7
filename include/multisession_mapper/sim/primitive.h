// Geometric primitives of the simulated world (oriented box, cylinder, ellipsoid), solid or
// porous. Porous volumes (tree canopies, hedges, mesh fences) follow the Beer-Lambert model used
// for LiDAR in vegetation (e.g. Béland et al., "On seeing the wood from the leaves and the role
// of voxel size in determining leaf area distribution of forests with terrestrial LiDAR", 2014):
// a ray travelling a length L inside the volume is stopped with probability 1 - exp(-density L),
// at an exponentially distributed depth. The draw comes from a per-(ray, primitive) key, so the
// same leaves return different points on different days (sessions).
#pragma once

#include <cstdint>
#include <string>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "multisession_mapper/core/status.h"
#include "multisession_mapper/core/types.h"

namespace multisession_mapper {
namespace sim {

/// Ground-truth class of a point; the numbers are the `label` field of the labels PCD
/// (docs/simulator.md).
enum class ObjectClass : std::uint8_t {
  kTerrain = 0,
  kBuilding = 1,
  kWall = 2,
  kPole = 3,
  kHedge = 4,
  kTrunk = 5,
  kCanopy = 6,
  kParkedCar = 7,
  kMovable = 8,
  kMovingCar = 9,
  kPedestrian = 10,
};
constexpr int kNumObjectClasses = 11;

/// world.yaml name of a class ("terrain", "parked_car", ...).
const char* ObjectClassName(ObjectClass object_class);
core::StatusOr<ObjectClass> ParseObjectClass(const std::string& name);

enum class Shape : std::uint8_t { kBox = 0, kCylinder = 1, kEllipsoid = 2 };
const char* ShapeName(Shape shape);
core::StatusOr<Shape> ParseShape(const std::string& name);

struct Ray {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  Eigen::Vector3d direction = Eigen::Vector3d::UnitX();  ///< unit length
};

/// A volume centred at the origin of its local frame (local z up).
struct Primitive {
  Shape shape = Shape::kBox;
  core::Pose3 pose = core::Pose3::Identity();  ///< T_world_local
  /// Box: half extents; cylinder: (radius, radius, half height); ellipsoid: semi-axes [m].
  Eigen::Vector3d half_size_m = Eigen::Vector3d::Constant(0.5);
  /// 0 for a solid surface; > 0: porous, probability of a return per metre travelled [1/m].
  double density_per_m = 0.0;
  double reflectivity = 0.3;  ///< diffuse reflectivity in [0, 1], drives intensity
  ObjectClass object_class = ObjectClass::kBuilding;
  std::uint32_t object_id = 0;
  std::uint64_t sessions_mask = ~0ULL;  ///< bit s set: present in session s
};

/// Parameter interval [t_enter, t_exit] of the ray inside the volume (t along the unit
/// direction). False when the ray line misses or the volume lies behind the origin.
bool IntersectInterval(const Primitive& primitive, const Ray& ray, double* t_enter,
                       double* t_exit);

/// Distance along the ray to the return from this primitive, searching in [t_min, t_max].
/// Solid: the entry point (no hit when the origin is inside). Porous: an exponential depth drawn
/// from `key`; no hit when the ray passes through. Returns a negative value for no hit.
double HitDistance(const Primitive& primitive, const Ray& ray, double t_min, double t_max,
                   std::uint64_t key);

/// Outward unit normal of the surface point nearest to `point_world`.
Eigen::Vector3d SurfaceNormal(const Primitive& primitive, const Eigen::Vector3d& point_world);

/// Signed distance to the surface [m] (negative inside). Exact for boxes and cylinders, a
/// first-order approximation for ellipsoids (exact for spheres).
double SignedDistance(const Primitive& primitive, const Eigen::Vector3d& point_world);

/// Axis-aligned bounding box in the world frame.
Eigen::AlignedBox3d WorldBounds(const Primitive& primitive);

}  // namespace sim
}  // namespace multisession_mapper
