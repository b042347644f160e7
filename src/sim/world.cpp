#include "multisession_mapper/sim/world.h"

#include <algorithm>
#include <cmath>
#include <set>
#include <string>

#include "multisession_mapper/core/se3.h"

namespace multisession_mapper {
namespace sim {
core::Pose3 WorldObject::Pose() const {
  return core::se3::FromXyzRpy(position_m.x(), position_m.y(), position_m.z(), roll_rad,
                               pitch_rad, yaw_rad);
}

bool WorldObject::PoseAt(double stamp_s, core::Pose3* pose) const {
  if (trajectory.empty() || stamp_s < trajectory.front().stamp_s ||
      stamp_s > trajectory.back().stamp_s) {
    return false;
  }
  auto it = std::upper_bound(
      trajectory.begin(), trajectory.end(), stamp_s,
      [](double t, const TrajectoryRow& row) { return t < row.stamp_s; });
  if (it == trajectory.end()) it = trajectory.end() - 1;
  if (it == trajectory.begin()) it = trajectory.begin() + 1;
  if (trajectory.size() == 1) {
    *pose = core::se3::FromXyzRpy(trajectory[0].position_m.x(), trajectory[0].position_m.y(),
                                  trajectory[0].position_m.z(), 0.0, 0.0,
                                  trajectory[0].yaw_rad);
    return true;
  }
  const TrajectoryRow& a = *(it - 1);
  const TrajectoryRow& b = *it;
  const double span = b.stamp_s - a.stamp_s;
  const double alpha = span > 0.0 ? (stamp_s - a.stamp_s) / span : 0.0;
  const Eigen::Vector3d p = a.position_m + alpha * (b.position_m - a.position_m);
  double dyaw = std::remainder(b.yaw_rad - a.yaw_rad, 2.0 * M_PI);
  *pose = core::se3::FromXyzRpy(p.x(), p.y(), p.z(), 0.0, 0.0, a.yaw_rad + alpha * dyaw);
  return true;
}

std::vector<Primitive> WorldObject::Primitives(const core::Pose3& pose) const {
  std::vector<Primitive> out;
  auto make = [&](Shape part_shape, const core::Pose3& part_pose, const Eigen::Vector3d& size,
                  double density, double reflectivity) {
    Primitive p;
    p.shape = part_shape;
    p.pose = part_pose;
    p.half_size_m = 0.5 * size;  // cylinders: size = (diameter, diameter, height)
    p.density_per_m = density;
    p.reflectivity = reflectivity;
    p.object_class = object_class;
    p.object_id = id;
    p.sessions_mask = sessions_mask;
    out.push_back(p);
  };
  if (parts.empty()) {
    make(shape, pose, size_m, 0.0, 0.3);
    return out;
  }
  for (const ObjectPart& part : parts) {
    const core::Pose3 local = core::se3::FromXyzRpy(part.center_m.x(), part.center_m.y(),
                                                    part.center_m.z(), part.rpy_rad.x(),
                                                    part.rpy_rad.y(), part.rpy_rad.z());
    make(part.shape, pose * local, part.size_m, part.density_per_m, part.reflectivity);
  }
  return out;
}

std::uint64_t World::AllSessionsMask() const {
  const std::size_t n = session_names.size();
  return n >= 64 ? ~0ULL : ((1ULL << n) - 1ULL);
}

std::vector<Primitive> World::StaticPrimitives() const {
  std::vector<Primitive> out;
  for (const WorldObject& object : objects) {
    if (object.moving()) continue;
    std::vector<Primitive> prims = object.Primitives(object.Pose());
    out.insert(out.end(), prims.begin(), prims.end());
  }
  return out;
}

core::Status World::Validate() const {
  if (session_names.empty() || session_names.size() > 64) {
    return core::Status::Error("world: need 1..64 sessions, got " +
                               std::to_string(session_names.size()));
  }
  core::Status status = terrain.Validate();
  if (!status.ok()) return status;
  std::set<std::uint32_t> ids;
  for (const WorldObject& o : objects) {
    const std::string where = "world: object " + std::to_string(o.id);
    if (o.id == 0) return core::Status::Error("world: object id 0 is reserved for the terrain");
    if (!ids.insert(o.id).second) return core::Status::Error(where + " appears twice");
    if (!o.position_m.allFinite() || !o.size_m.allFinite() || (o.size_m.array() <= 0.0).any()) {
      return core::Status::Error(where + " has a non-finite position or a non-positive size");
    }
    for (const ObjectPart& part : o.parts) {
      if (!part.size_m.allFinite() || (part.size_m.array() <= 0.0).any() ||
          !(part.density_per_m >= 0.0)) {
        return core::Status::Error(where + " has a part with a bad size or density");
      }
    }
    for (std::size_t i = 1; i < o.trajectory.size(); ++i) {
      if (!(o.trajectory[i].stamp_s > o.trajectory[i - 1].stamp_s)) {
        return core::Status::Error(where + ": trajectory stamps must increase");
      }
    }
  }
  return core::Status::Ok();
}

}  // namespace sim
}  // namespace multisession_mapper
