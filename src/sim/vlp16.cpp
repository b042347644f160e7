#include "multisession_mapper/sim/vlp16.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "multisession_mapper/sim/counter_rng.h"

namespace multisession_mapper {
namespace sim {
namespace {

constexpr double kFiringGapS = 2.304e-6;  // between consecutive lasers of one column

struct MoverWindow {
  const WorldObject* object;
  double azimuth_rad;       // centre, sensor frame at the scan's middle
  double half_width_rad;    // angular half-width incl. motion margin
};

double WrapAngle(double a) { return std::remainder(a, 2.0 * M_PI); }

}  // namespace

core::Status Vlp16Config::Validate() const {
  if (num_columns < 4 || num_columns > 36000) {
    return core::Status::Error("vlp16.num_columns must be in [4, 36000]");
  }
  if (!(rate_hz > 0.0 && rate_hz <= 50.0)) return core::Status::Error("vlp16.rate_hz in (0, 50]");
  if (!(min_range_m >= 0.0) || !(max_range_m > min_range_m) || !std::isfinite(max_range_m)) {
    return core::Status::Error("vlp16: need 0 <= min_range_m < max_range_m");
  }
  if (!(range_noise_sigma_m >= 0.0 && range_noise_sigma_m < 1.0)) {
    return core::Status::Error("vlp16.range_noise_sigma_m must be in [0, 1), got " +
                               std::to_string(range_noise_sigma_m));
  }
  if (!(intensity_noise >= 0.0) || !std::isfinite(start_azimuth_rad)) {
    return core::Status::Error("vlp16: intensity_noise must be >= 0, start azimuth finite");
  }
  return core::Status::Ok();
}

core::StatusOr<Vlp16> Vlp16::Create(const Vlp16Config& config) {
  core::Status status = config.Validate();
  if (!status.ok()) return status;
  return Vlp16(config);
}

Vlp16::Vlp16(const Vlp16Config& config) : config_(config) {
  directions_.resize(static_cast<std::size_t>(config.num_columns) * kNumLasers);
  for (int c = 0; c < config.num_columns; ++c) {
    // Clockwise rotation seen from above: azimuth decreases.
    const double az = config.start_azimuth_rad - 2.0 * M_PI * c / config.num_columns;
    for (int l = 0; l < kNumLasers; ++l) {
      const double el = LaserElevationRad(l);
      directions_[c * kNumLasers + l] = Eigen::Vector3d(
          std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
    }
  }
}

double Vlp16::LaserElevationRad(int laser) {
  const int deg = (laser % 2 == 0) ? -15 + laser : laser;
  return deg * M_PI / 180.0;
}

int Vlp16::LaserRing(int laser) {
  const int deg = (laser % 2 == 0) ? -15 + laser : laser;
  return (deg + 15) / 2;
}

double Vlp16::ColumnTimeS(int column) const { return column * period_s() / config_.num_columns; }

SimulatedScan Vlp16::Simulate(const RayCaster& caster,
                              const std::vector<const WorldObject*>& movers,
                              const std::function<core::Pose3(double)>& sensor_pose,
                              int session, double stamp_s, std::uint64_t key) const {
  SimulatedScan out;
  out.scan.stamp_s = stamp_s;
  out.scan.has_ring = true;
  out.scan.has_time = true;
  out.pose_at_stamp = sensor_pose(stamp_s);
  out.scan.points.reserve(directions_.size());
  out.truth.reserve(directions_.size());

  // Moving objects near the sensor, with the azimuth window in which they can be hit.
  const double mid = stamp_s + 0.5 * period_s();
  const core::Pose3 mid_pose = sensor_pose(mid);
  const core::Pose3 mid_inv = mid_pose.inverse();
  std::vector<MoverWindow> windows;
  for (const WorldObject* m : movers) {
    core::Pose3 pose;
    if (!m->PoseAt(mid, &pose)) continue;
    const Eigen::Vector3d local = mid_inv * pose.translation();
    const double dist = local.head<2>().norm();
    const double radius = 0.5 * m->size_m.norm() + 1.0;  // + motion within half a sweep
    if (dist - radius > config_.max_range_m) continue;
    const double half = dist <= radius ? M_PI : std::asin(radius / dist) + 0.1;
    windows.push_back({m, std::atan2(local.y(), local.x()), half});
  }

  std::vector<Primitive> mover_prims;
  for (int c = 0; c < config_.num_columns; ++c) {
    const double t_col = ColumnTimeS(c);
    const core::Pose3 pose = sensor_pose(stamp_s + t_col);
    const double az = config_.start_azimuth_rad - 2.0 * M_PI * c / config_.num_columns;
    mover_prims.clear();
    for (const MoverWindow& w : windows) {
      if (std::abs(WrapAngle(az - w.azimuth_rad)) > w.half_width_rad) continue;
      core::Pose3 mpose;
      if (!w.object->PoseAt(stamp_s + t_col, &mpose)) continue;
      std::vector<Primitive> prims = w.object->Primitives(mpose);
      mover_prims.insert(mover_prims.end(), prims.begin(), prims.end());
    }
    for (int l = 0; l < kNumLasers; ++l) {
      const std::uint64_t ray_key = MakeKey(key, static_cast<std::uint64_t>(c), l);
      Ray ray;
      ray.origin = pose.translation();
      ray.direction = pose.linear() * directions_[c * kNumLasers + l];
      RayHit hit;
      caster.Cast(ray, config_.min_range_m, config_.max_range_m, session, ray_key, &hit);
      for (const Primitive& p : mover_prims) {
        const double limit = hit.range_m >= 0.0 ? hit.range_m : config_.max_range_m;
        const double t = HitDistance(p, ray, config_.min_range_m, limit, ray_key);
        if (t >= 0.0 && (hit.range_m < 0.0 || t < hit.range_m)) {
          hit.range_m = t;
          hit.object_class = p.object_class;
          hit.object_id = p.object_id;
          hit.reflectivity = p.reflectivity;
          hit.normal = SurfaceNormal(p, ray.origin + ray.direction * t);
        }
      }
      if (hit.range_m < 0.0) continue;  // sky or out of range: no return
      CounterRng rng(ray_key ^ 0x5EED5EED5EEDULL);
      const double range = hit.range_m + config_.range_noise_sigma_m * rng.Gaussian();
      if (range < config_.min_range_m || range > config_.max_range_m) continue;
      const Eigen::Vector3d world_hit = ray.origin + ray.direction * hit.range_m;
      const double cos_inc = std::abs(hit.normal.dot(ray.direction));
      double intensity = 255.0 * hit.reflectivity * (0.25 + 0.75 * cos_inc) +
                         config_.intensity_noise * rng.Gaussian();
      intensity = std::round(std::clamp(intensity, 0.0, 255.0));
      core::LidarPoint point;
      // Sensor frame at this column's firing time: the direction itself, scaled.
      point.position_m = (directions_[c * kNumLasers + l] * range).cast<float>();
      point.intensity = static_cast<float>(intensity);
      point.ring = static_cast<std::uint16_t>(LaserRing(l));
      point.time_s = static_cast<float>(t_col + l * kFiringGapS);
      out.scan.points.push_back(point);
      TruthPoint truth;
      truth.position_m = world_hit.cast<float>();
      truth.label = hit.object_class;
      truth.object_id = hit.object_id;
      truth.range_m = static_cast<float>(hit.range_m);
      out.truth.push_back(truth);
    }
  }
  return out;
}

}  // namespace sim
}  // namespace multisession_mapper
