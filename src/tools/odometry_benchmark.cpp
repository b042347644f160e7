// Benchmark (not a test): own voxel downsample vs pcl::VoxelGrid, own point-to-plane ICP vs
// pcl::IterativeClosestPoint / pcl::GeneralizedIterativeClosestPoint on the real fast_gicp
// pair and on a synthetic pair, and the per-scan time of the whole odometry on a synthetic
// 3 m/s VLP-16 sequence. Prints medians; the "own vs PCL" choices in the headers cite it.
//   odometry_benchmark [--data DIR] [--scans N]
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <ctime>
#include <fstream>
#include <functional>
#include <iomanip>
#include <iostream>
#include <string>
#include <vector>

// GCC 12 reports a false -Warray-bounds inside Eigen::umeyama, instantiated by
// pcl::IterativeClosestPoint in this file; the code is third-party and correct.
#pragma GCC diagnostic ignored "-Warray-bounds"
#include <pcl/filters/voxel_grid.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_types.h>
#include <pcl/registration/gicp.h>
#include <pcl/registration/icp.h>

#include "../../test/synthetic_lidar_scene.h"
#include "multisession_mapper/core/deskew.h"
#include "multisession_mapper/core/icp_registration.h"
#include "multisession_mapper/core/input_filter.h"
#include "multisession_mapper/core/kdtree_target.h"
#include "multisession_mapper/core/odometry.h"
#include "multisession_mapper/core/pcd_scan_io.h"
#include "multisession_mapper/core/se3.h"
#include "multisession_mapper/core/voxel_downsample.h"

namespace msm = multisession_mapper;
namespace core = multisession_mapper::core;
using Cloud = pcl::PointCloud<pcl::PointXYZ>;

namespace {

double NowMs() {
  return std::chrono::duration<double, std::milli>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

double CpuMs() {
  timespec ts;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

double Percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<std::size_t>(q * v.size()))];
}

// Median wall time of `runs` calls [ms].
double TimeMs(int runs, const std::function<void()>& f) {
  std::vector<double> t;
  for (int i = 0; i < runs; ++i) {
    const double start = NowMs();
    f();
    t.push_back(NowMs() - start);
  }
  return Percentile(t, 0.5);
}

Cloud::Ptr ToPcl(const core::PointVector& pts) {
  Cloud::Ptr c(new Cloud);
  for (const Eigen::Vector3d& p : pts) {
    c->push_back(pcl::PointXYZ(static_cast<float>(p.x()), static_cast<float>(p.y()),
                               static_cast<float>(p.z())));
  }
  return c;
}

void PrintError(const std::string& name, double ms, const core::Pose3& estimate,
                const core::Pose3& truth) {
  const core::Pose3 e = core::se3::Between(truth, estimate);
  std::cout << "  " << std::left << std::setw(34) << name << std::right << std::fixed
            << std::setprecision(2) << std::setw(9) << ms << " ms   error " << std::setw(6)
            << core::se3::TranslationNorm(e) * 100.0 << " cm " << std::setprecision(3)
            << std::setw(7) << core::se3::RotationAngleRad(e) * 180.0 / M_PI << " deg\n";
}

// Own ICP vs PCL ICP / GICP on one pair; target/source downsampled alike (0.2 m / 0.5 m).
void ComparePair(const core::PointVector& target, const core::PointVector& source,
                 const core::Pose3& truth, const core::Pose3& guess, int runs) {
  const core::PointVector target_ds = core::VoxelDownsample(target, 0.2);
  const core::PointVector source_ds = core::VoxelDownsample(source, 0.5);
  std::cout << "  target " << target.size() << " -> " << target_ds.size() << " pts, source "
            << source.size() << " -> " << source_ds.size() << " pts\n";
  core::IcpConfig config;
  config.max_correspondence_distance_m = 1.0;
  config.kernel_scale_m = 0.2;
  config.max_iterations = 50;
  const core::IcpRegistration icp = core::IcpRegistration::Create(config).value();
  core::Pose3 own = guess;
  const double own_ms = TimeMs(runs, [&] {
    const core::KdTreeTarget tree = core::KdTreeTarget::Create(target_ds).value();
    const core::StatusOr<core::IcpResult> r = icp.Register(source_ds, tree, guess);
    if (r.ok()) own = r.value().pose;
  });
  PrintError("own point-to-plane (incl. tree)", own_ms, own, truth);

  const Cloud::Ptr tgt = ToPcl(target_ds);
  const Cloud::Ptr src = ToPcl(source_ds);
  const Eigen::Matrix4f guess_f = guess.matrix().cast<float>();
  core::Pose3 pcl_icp = guess;
  const double icp_ms = TimeMs(runs, [&] {
    pcl::IterativeClosestPoint<pcl::PointXYZ, pcl::PointXYZ> reg;
    reg.setInputSource(src);
    reg.setInputTarget(tgt);
    reg.setMaxCorrespondenceDistance(1.0);
    reg.setMaximumIterations(50);
    reg.setTransformationEpsilon(1e-8);
    Cloud out;
    reg.align(out, guess_f);
    pcl_icp = core::Pose3(reg.getFinalTransformation().cast<double>());
  });
  PrintError("pcl::IterativeClosestPoint", icp_ms, core::se3::Normalized(pcl_icp), truth);

  core::Pose3 pcl_gicp = guess;
  const double gicp_ms = TimeMs(runs, [&] {
    pcl::GeneralizedIterativeClosestPoint<pcl::PointXYZ, pcl::PointXYZ> reg;
    reg.setInputSource(src);
    reg.setInputTarget(tgt);
    reg.setMaxCorrespondenceDistance(1.0);
    reg.setMaximumIterations(50);
    Cloud out;
    reg.align(out, guess_f);
    pcl_gicp = core::Pose3(reg.getFinalTransformation().cast<double>());
  });
  PrintError("pcl::GeneralizedIterativeClosestPoint", gicp_ms,
             core::se3::Normalized(pcl_gicp), truth);
}

core::PointVector LoadXyz(const std::string& path) {
  const core::StatusOr<core::LidarScan> scan = core::LoadPcdScan(path);
  if (!scan.ok()) {
    std::cerr << scan.status().message() << "\n";
    return {};
  }
  return core::ScanToPointVector(scan.value());
}

}  // namespace

int main(int argc, char** argv) {
  std::string data_dir = MSM_SHARED_DATA_DIR;
  int num_scans = 100;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string arg = argv[i];
    if (arg == "--data") data_dir = argv[i + 1];
    if (arg == "--scans") num_scans = std::atoi(argv[i + 1]);
  }

  // 1. Voxel downsample on a real VLP-16 scan.
  const std::string vlp = data_dir + "/real/vlp16_indoor/0.pcd";
  const core::PointVector vlp_points = LoadXyz(vlp);
  if (!vlp_points.empty()) {
    std::cout << "voxel downsample, " << vlp << " (" << vlp_points.size()
              << " pts), median of 50\n";
    const Cloud::Ptr cloud = ToPcl(vlp_points);
    for (double voxel : {0.1, 0.5, 1.5}) {
      std::size_t own_n = 0, pcl_n = 0;
      const double own_ms =
          TimeMs(50, [&] { own_n = core::VoxelDownsample(vlp_points, voxel).size(); });
      const double pcl_ms = TimeMs(50, [&] {
        pcl::VoxelGrid<pcl::PointXYZ> grid;
        grid.setInputCloud(cloud);
        grid.setLeafSize(voxel, voxel, voxel);
        Cloud out;
        grid.filter(out);
        pcl_n = out.size();
      });
      std::cout << "  voxel " << voxel << " m: own " << std::setprecision(3) << own_ms
                << " ms (" << own_n << " pts), pcl::VoxelGrid " << pcl_ms << " ms (" << pcl_n
                << " pts)\n";
    }
  }

  // 1b. Per-scan front end at full VLP-16 density: input filter + de-skew + both downsamples
  // on the real 28k-point scan (times spread over 0.1 s, 3 m/s and 1 rad/s assumed).
  const core::StatusOr<core::LidarScan> vlp_scan = core::LoadPcdScan(vlp);
  if (vlp_scan.ok()) {
    core::LidarScan scan = vlp_scan.value();
    scan.has_time = true;
    for (std::size_t i = 0; i < scan.points.size(); ++i) {
      scan.points[i].time_s = static_cast<float>(0.1 * i / scan.points.size());
    }
    const core::InputFilter filter = core::InputFilter::Create(core::InputFilterConfig()).value();
    const core::Deskewer deskewer = core::Deskewer::Create(core::DeskewConfig()).value();
    core::se3::Vector6d velocity;
    velocity << 3.0, 0.0, 0.0, 0.0, 0.0, 1.0;
    std::size_t kept = 0;
    const double ms = TimeMs(50, [&] {
      const core::LidarScan deskewed = deskewer.Apply(filter.Apply(scan), velocity);
      const core::PointVector map_points =
          core::VoxelDownsample(core::ScanToPointVector(deskewed), 0.5);
      kept = core::VoxelDownsample(map_points, 1.5).size();
    });
    std::cout << "front end (filter + de-skew + 0.5 m and 1.5 m downsample) on the real scan: "
              << ms << " ms median (" << kept << " registration points)\n";
  }

  // 2. Real pair (relative.txt maps 251371071 into 251370668).
  const std::string pair_dir = data_dir + "/real/fast_gicp_pair";
  const core::PointVector target = LoadXyz(pair_dir + "/251370668.pcd");
  const core::PointVector source = LoadXyz(pair_dir + "/251371071.pcd");
  std::ifstream rel(pair_dir + "/relative.txt");
  if (!target.empty() && !source.empty() && rel) {
    Eigen::Matrix4d m;
    for (int i = 0; i < 16; ++i) rel >> m(i / 4, i % 4);
    std::cout << "real pair (fast_gicp), from identity, median of 5 runs; error vs relative.txt\n";
    ComparePair(target, source, core::Pose3(m), core::Pose3::Identity(), 5);
  }

  // 3. Synthetic pair: static scans 0.5 m / 3 deg apart, truth known exactly.
  {
    const msm::test::VehicleTrajectory still(0.0, {{1.0, 0.0}});
    const msm::test::SyntheticScene scene(21, 120, 70.0, {Eigen::Vector2d::Zero()}, 5.0);
    const core::Pose3 pa = core::se3::FromXyzRpy(0, 0, 1.8, 0, 0, 0.2);
    const core::Pose3 t_ab = core::se3::FromXyzRpy(0.5, 0.1, 0.02, 0.005, -0.003, 0.05);
    const core::Pose3 pb = pa * t_ab;
    const auto scan_at = [&](const core::Pose3& p, unsigned seed) {
      return core::ScanToPointVector(msm::test::SimulateVlp16(
          scene, [&p](double) { return p; }, 0.0, seed, 0.01, 1800, 0.1, false));
    };
    std::cout << "synthetic pair (single VLP-16 scans, 0.5 m / 3 deg), from identity, "
                 "median of 5\n";
    ComparePair(scan_at(pa, 1), scan_at(pb, 2), t_ab, core::Pose3::Identity(), 5);
  }

  // 4. Odometry on a synthetic 3 m/s sequence with turns (scans simulated beforehand).
  {
    const msm::test::VehicleTrajectory trajectory(
        3.0, {{3.0, 0.0}, {2.0, 0.5}, {3.0, 0.0}, {2.0, -0.6}, {10.0, 0.0}}, 1.0, 0.25);
    // Dense enough for ~20k returns per sweep, like a VLP-16 in a built-up area.
    const msm::test::SyntheticScene scene(31, 900, 90.0, trajectory.PathXy(), 4.0);
    const int n = std::min(num_scans, static_cast<int>(trajectory.duration_s() / 0.1) - 1);
    std::vector<core::LidarScan> scans;
    for (int k = 0; k < n; ++k) {
      scans.push_back(msm::test::SimulateVlp16(
          scene, [&](double t) { return trajectory.PoseAt(t); }, 0.1 * k, 100 + k));
    }
    core::Odometry odometry = core::Odometry::Create(core::OdometryConfig()).value();
    std::vector<double> wall, cpu, icp_ms, deskew_ms;
    double max_err = 0.0;
    std::size_t points = 0, iterations = 0, refined = 0, source_points = 0;
    for (int k = 0; k < n; ++k) {
      const double w0 = NowMs(), c0 = CpuMs();
      const core::StatusOr<core::OdometryResult> r = odometry.ProcessScan(scans[k]);
      wall.push_back(NowMs() - w0);
      cpu.push_back(CpuMs() - c0);
      if (!r.ok()) continue;
      // The refinement with the map's ground normals is an ICP run too (its own stage).
      icp_ms.push_back(r.value().timing.registration_ms + r.value().timing.map_ground_ms);
      deskew_ms.push_back(r.value().timing.deskew_ms);
      points += scans[k].points.size();
      iterations += r.value().icp.iterations;
      refined += r.value().refined ? 1 : 0;
      source_points += r.value().icp.num_source;
      const core::Pose3 truth =
          core::se3::Between(trajectory.PoseAt(0.0), trajectory.PoseAt(0.1 * k));
      max_err = std::max(max_err,
                         core::se3::TranslationNorm(core::se3::Between(truth, r.value().pose)));
    }
    std::cout << "odometry, synthetic VLP-16 sequence at 3 m/s, " << n << " scans of ~"
              << points / std::max(1, n) << " pts\n"
              << "  per scan: median " << Percentile(wall, 0.5) << " ms wall ("
              << Percentile(cpu, 0.5) << " ms thread CPU), p90 " << Percentile(wall, 0.9)
              << " ms; ICP median " << Percentile(icp_ms, 0.5) << " ms, de-skew median "
              << Percentile(deskew_ms, 0.5) << " ms\n"
              << "  mean ICP iterations " << static_cast<double>(iterations) / n << ", source "
              << source_points / std::max(1, n) << " pts, re-de-skewed " << refined << " of " << n
              << " scans\n"
              << "  max translation error vs truth " << max_err << " m over "
              << core::se3::TranslationNorm(core::se3::Between(trajectory.PoseAt(0.0),
                                                               trajectory.PoseAt(0.1 * (n - 1))))
              << " m (straight-line distance start-end)\n";
  }
  return 0;
}
