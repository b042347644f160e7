// Scans for the place-recognition tests (issue 6): a ray-cast synthetic VLP-16 scan of a walled
// yard with pillars, the real VLP-16 PCDs of ../shared/data/real/vlp16_indoor, and yaw rotation.
#pragma once

#define PCL_NO_PRECOMPILE
#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include <pcl/io/pcd_io.h>
#include <pcl/point_types.h>

#include "multisession_mapper/core/types.h"

namespace msm_pr_test {

// The layout of the real VLP-16 files: x y z intensity ring (padding fields are skipped).
struct EIGEN_ALIGN16 PointXYZIR {
  PCL_ADD_POINT4D;
  float intensity;
  std::uint16_t ring;
  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

}  // namespace msm_pr_test

POINT_CLOUD_REGISTER_POINT_STRUCT(msm_pr_test::PointXYZIR,
                                  (float, x, x)(float, y, y)(float, z, z)(float, intensity,
                                                                         intensity)(
                                      std::uint16_t, ring, ring))

namespace msm_pr_test {

namespace core = multisession_mapper::core;

inline std::string RealVlp16Dir() {
  return std::string(MSM_SHARED_DATA_DIR) + "/real/vlp16_indoor";
}

/// Loads one real VLP-16 PCD (with ring); false when it cannot be read.
inline bool LoadVlp16Pcd(const std::string& path, core::LidarScan* scan) {
  pcl::PointCloud<PointXYZIR> cloud;
  if (pcl::io::loadPCDFile(path, cloud) != 0) return false;
  scan->points.clear();
  scan->has_ring = true;
  for (const PointXYZIR& p : cloud.points) {
    core::LidarPoint lp;
    lp.position_m = Eigen::Vector3f(p.x, p.y, p.z);
    lp.intensity = p.intensity;
    lp.ring = p.ring;
    scan->points.push_back(lp);
  }
  return !scan->points.empty();
}

/// A walled yard [x_min, x_max] x [y_min, y_max] (sensor at the origin, ground at -1.8 m) with
/// vertical pillars of radius 0.4 m, scanned by a VLP-16 (16 rings -15..+15 deg, 0.2 deg azimuth
/// steps) with 1 cm range noise. Rays that hit nothing within 100 m give no return.
struct Yard {
  double x_min = -20, x_max = 25, y_min = -12, y_max = 18;
  std::vector<Eigen::Vector2d> pillars;
};

inline Yard RandomYard(std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> size(8.0, 30.0);
  Yard yard;
  yard.x_min = -size(rng);
  yard.x_max = size(rng);
  yard.y_min = -size(rng);
  yard.y_max = size(rng);
  std::uniform_real_distribution<double> ux(yard.x_min + 1, yard.x_max - 1);
  std::uniform_real_distribution<double> uy(yard.y_min + 1, yard.y_max - 1);
  for (int i = 0; i < 12; ++i) {
    Eigen::Vector2d c(ux(rng), uy(rng));
    if (c.norm() > 2.0) yard.pillars.push_back(c);
  }
  return yard;
}

inline core::LidarScan ScanYard(const Yard& yard, std::uint32_t noise_seed) {
  std::mt19937 rng(noise_seed);
  std::normal_distribution<double> noise(0.0, 0.01);
  core::LidarScan scan;
  scan.has_ring = true;
  const double ground_z = -1.8;
  for (int ring = 0; ring < 16; ++ring) {
    const double elev = (-15.0 + 2.0 * ring) * M_PI / 180.0;
    for (int a = 0; a < 1800; ++a) {
      const double az = a * 0.2 * M_PI / 180.0;
      const Eigen::Vector3d dir(std::cos(elev) * std::cos(az), std::cos(elev) * std::sin(az),
                                std::sin(elev));
      double t = 100.0;
      if (dir.x() > 0) t = std::min(t, yard.x_max / dir.x());
      if (dir.x() < 0) t = std::min(t, yard.x_min / dir.x());
      if (dir.y() > 0) t = std::min(t, yard.y_max / dir.y());
      if (dir.y() < 0) t = std::min(t, yard.y_min / dir.y());
      if (dir.z() < 0) t = std::min(t, ground_z / dir.z());
      for (const Eigen::Vector2d& c : yard.pillars) {
        // Ray (horizontal part) against a circle of radius 0.4 m.
        const Eigen::Vector2d d2(dir.x(), dir.y());
        const double aa = d2.squaredNorm();
        const double bb = -2.0 * d2.dot(c);
        const double cc = c.squaredNorm() - 0.16;
        const double disc = bb * bb - 4 * aa * cc;
        if (disc < 0 || aa <= 0) continue;
        const double hit = (-bb - std::sqrt(disc)) / (2 * aa);
        if (hit > 0) t = std::min(t, hit);
      }
      if (t >= 100.0) continue;
      core::LidarPoint p;
      p.position_m = (dir * (t + noise(rng))).cast<float>();
      p.ring = static_cast<std::uint16_t>(ring);
      scan.points.push_back(p);
    }
  }
  return scan;
}

/// The scan as seen by a sensor turned by `yaw_rad` about z: points rotated by -yaw_rad, so
/// that p_original = Rz(yaw_rad) * p_rotated.
inline core::LidarScan TurnSensor(const core::LidarScan& scan, double yaw_rad) {
  core::LidarScan out = scan;
  const Eigen::Matrix3f r =
      Eigen::AngleAxisf(static_cast<float>(-yaw_rad), Eigen::Vector3f::UnitZ()).toRotationMatrix();
  for (core::LidarPoint& p : out.points) p.position_m = r * p.position_m;
  return out;
}

inline double L2(const std::vector<float>& a, const std::vector<float>& b) {
  double sum = 0.0;
  for (std::size_t i = 0; i < a.size() && i < b.size(); ++i) {
    sum += double(a[i] - b[i]) * (a[i] - b[i]);
  }
  return std::sqrt(sum);
}

}  // namespace msm_pr_test
