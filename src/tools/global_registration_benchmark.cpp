// global_registration_benchmark: accuracy and time per pair of GlobalRegistration (issue 6) on
// the submaps of a stored map. Not part of the pipeline and not a test.
//   global_registration_benchmark --map DIR [--method fpfh_ransac|yaw_search_icp|both]
//       [--max-distance M] [--max-pairs N] [--coarse-voxel M] [--coarse-range M]
//       [--feature-radius M] [--feature-epsilon E] [--compare-fpfh]
// Pairs: submaps of the map whose origins are within --max-distance (overlapping) and, for the
// rejection check, the same pairs with the target mirrored (a place that does not exist). Each source submap
// is first moved by a large known transform (yaw 90-180 deg, 15-30 m, fixed seed), so the
// registration starts with no usable guess. Reference: the map's own optimised submap poses
// (no ground truth is read).
// --compare-fpfh instead times our FPFH (core/fpfh_features.h) against PCL's FPFHEstimation on
// the coarse clouds of the map's submaps (the registration's crop, voxel and PCL normals), in
// the same run, and reports the largest difference of the histograms.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <map>
#include <random>
#include <string>
#include <vector>

#include <pcl/features/fpfh.h>
#include <pcl/search/kdtree.h>

#include "multisession_mapper/core/fpfh_features.h"
#include "multisession_mapper/core/global_registration.h"
#include "multisession_mapper/core/map_store.h"
#include "multisession_mapper/core/se3.h"
#include "multisession_mapper/tools/cli.h"

namespace core = multisession_mapper::core;

namespace {

const char kUsage[] =
    "usage: global_registration_benchmark --map DIR [options]\n"
    "  --method M        fpfh_ransac | yaw_search_icp | both (default both)\n"
    "  --max-distance M  overlapping pairs: origins within this distance [m] (15)\n"
    "  --max-pairs N     at most N overlapping and N non-overlapping pairs (20)\n"
    "  --coarse-voxel M  GlobalRegistrationConfig::coarse_voxel_m (its default)\n"
    "  --coarse-range M  GlobalRegistrationConfig::coarse_max_range_m (its default)\n"
    "  --feature-radius M  GlobalRegistrationConfig::feature_radius_m (its default)\n"
    "  --feature-epsilon E GlobalRegistrationConfig::feature_match_epsilon (its default)\n"
    "  --compare-fpfh    time our FPFH against PCL's on the first --max-pairs submaps instead\n";

double Median(std::vector<double> v) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  return v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
}

// The steps of GlobalRegistrationResult, one sample per pair.
struct StageMedians {
  std::vector<double> prepare, matching, hypotheses, fine;
  void Add(const core::GlobalRegistrationResult& r) {
    prepare.push_back(r.prepare_s);
    matching.push_back(r.matching_s);
    hypotheses.push_back(r.hypotheses_s);
    fine.push_back(r.fine_s);
  }
};

// PCL's FPFHEstimation and ComputeFpfh on the coarse clouds of the first `max_submaps`
// submaps (MakeCoarsePoints, as GlobalRegistration builds them), each timed in the same run;
// the histograms compared on the points where both are defined.
int CompareFpfh(const std::vector<core::Submap, Eigen::aligned_allocator<core::Submap>>& submaps,
                const core::GlobalRegistrationConfig& c,
                long long max_submaps) {
  using Clock = std::chrono::steady_clock;
  std::vector<double> pcl_ms, own_ms;
  std::size_t points = 0, compared = 0, same = 0, definition_differs = 0;
  for (std::size_t k = 0; k < submaps.size() && static_cast<long long>(k) < max_submaps; ++k) {
    // Both on the points with a normal: ours leaves the others out, PCL would count them
    // (fpfh_features.h), so that the histograms are comparable.
    const core::CoarsePoints coarse = core::MakeCoarsePoints(submaps[k].points, c);
    core::PointVector kept;
    std::vector<Eigen::Vector3d> ours_normals;
    pcl::PointCloud<pcl::PointXYZ>::Ptr kept_cloud(new pcl::PointCloud<pcl::PointXYZ>);
    pcl::PointCloud<pcl::Normal>::Ptr kept_normals(new pcl::PointCloud<pcl::Normal>);
    for (std::size_t i = 0; i < coarse.points.size(); ++i) {
      const Eigen::Vector3d& p = coarse.points[i];
      const Eigen::Vector3f n = coarse.normals[i].cast<float>();  // PCL's float, exactly
      if (n.isZero(0.0)) continue;
      kept.push_back(p);
      ours_normals.push_back(coarse.normals[i]);
      kept_cloud->push_back(pcl::PointXYZ(static_cast<float>(p.x()), static_cast<float>(p.y()),
                                          static_cast<float>(p.z())));
      kept_normals->push_back(pcl::Normal(n.x(), n.y(), n.z()));
    }
    const auto t0 = Clock::now();
    pcl::PointCloud<pcl::FPFHSignature33> reference;
    pcl::FPFHEstimation<pcl::PointXYZ, pcl::Normal, pcl::FPFHSignature33> fpfh;
    fpfh.setInputCloud(kept_cloud);
    fpfh.setInputNormals(kept_normals);
    fpfh.setSearchMethod(pcl::search::KdTree<pcl::PointXYZ>::Ptr(
        new pcl::search::KdTree<pcl::PointXYZ>));
    fpfh.setRadiusSearch(c.feature_radius_m);
    fpfh.compute(reference);
    const auto t1 = Clock::now();
    std::vector<std::uint8_t> defined;
    const core::StatusOr<std::vector<float>> ours =
        core::ComputeFpfh(kept, ours_normals, c.feature_radius_m, &defined);
    const auto t2 = Clock::now();
    if (!ours.ok()) {
      std::fprintf(stderr, "submap %zu: %s\n", k, ours.status().message().c_str());
      return 1;
    }
    pcl_ms.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
    own_ms.push_back(std::chrono::duration<double, std::milli>(t2 - t1).count());
    points += kept.size();
    for (std::size_t i = 0; i < kept.size(); ++i) {
      const float* h = reference[i].histogram;
      bool pcl_defined = true;
      for (int b = 0; b < core::kFpfhBins && pcl_defined; ++b) pcl_defined = std::isfinite(h[b]);
      if (pcl_defined != (defined[i] != 0)) ++definition_differs;
      if (!pcl_defined || !defined[i]) continue;
      ++compared;
      double l1 = 0.0;
      for (int b = 0; b < core::kFpfhBins; ++b) {
        l1 += std::abs(h[b] - ours.value()[i * core::kFpfhBins + b]);
      }
      same += l1 <= 0.01 ? 1 : 0;
    }
  }
  const double pcl_median = Median(pcl_ms), own_median = Median(own_ms);
  std::printf("[fpfh] %zu submaps, %zu coarse points with a normal: PCL FPFHEstimation %.1f ms "
              "per submap median, ours %.1f ms (%.2fx faster); of %zu points with both "
              "histograms %.2f %% within L1 0.01 of 300; defined differently at %zu points\n",
              pcl_ms.size(), points, pcl_median, own_median, pcl_median / own_median, compared,
              compared > 0 ? 100.0 * same / compared : 0.0, definition_differs);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  std::string map_dir, method = "both";
  double max_distance_m = 15.0;
  long long max_pairs = 20;
  const core::GlobalRegistrationConfig defaults;
  double coarse_voxel_m = defaults.coarse_voxel_m;
  double coarse_range_m = defaults.coarse_max_range_m;
  double feature_radius_m = defaults.feature_radius_m;
  double feature_epsilon = defaults.feature_match_epsilon;
  bool compare_fpfh = false;
  const std::map<std::string, double*> double_options = {
      {"--max-distance", &max_distance_m},   {"--coarse-voxel", &coarse_voxel_m},
      {"--coarse-range", &coarse_range_m},   {"--feature-radius", &feature_radius_m},
      {"--feature-epsilon", &feature_epsilon}};
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    const bool has_value = i + 1 < argc;
    if (arg == "--map" && has_value) {
      map_dir = argv[++i];
    } else if (arg == "--compare-fpfh") {
      compare_fpfh = true;
    } else if (arg == "--method" && has_value) {
      method = argv[++i];
    } else if (double_options.count(arg) > 0 && has_value) {
      if (!multisession_mapper::tools::ParseDouble(argv[++i], double_options.at(arg))) {
        std::fprintf(stderr, "bad %s\n%s", arg.c_str(), kUsage);
        return 2;
      }
    } else if (arg == "--max-pairs" && has_value) {
      if (!multisession_mapper::tools::ParseInt(argv[++i], &max_pairs) || max_pairs < 1) {
        std::fprintf(stderr, "bad --max-pairs\n%s", kUsage);
        return 2;
      }
    } else {
      std::fprintf(stderr, "unknown or incomplete argument '%s'\n%s", arg.c_str(), kUsage);
      return 2;
    }
  }
  if (map_dir.empty()) {
    std::fprintf(stderr, "--map is required\n%s", kUsage);
    return 2;
  }
  std::vector<core::GlobalRegistrationConfig::Method> methods;
  if (method == "fpfh_ransac" || method == "both") {
    methods.push_back(core::GlobalRegistrationConfig::Method::kFpfhRansac);
  }
  if (method == "yaw_search_icp" || method == "both") {
    methods.push_back(core::GlobalRegistrationConfig::Method::kYawSearchIcp);
  }
  if (methods.empty()) {
    std::fprintf(stderr, "unknown --method '%s'\n%s", method.c_str(), kUsage);
    return 2;
  }
  const core::StatusOr<core::MapContents> map = core::MapStore().Load(map_dir);
  if (!map.ok()) {
    std::fprintf(stderr, "cannot load the map: %s\n", map.status().message().c_str());
    return 1;
  }
  const auto& submaps = map.value().submaps;
  if (compare_fpfh) {
    core::GlobalRegistrationConfig config;
    config.coarse_voxel_m = coarse_voxel_m;
    config.coarse_max_range_m = coarse_range_m;
    config.feature_radius_m = feature_radius_m;
    return CompareFpfh(submaps, config, max_pairs);
  }
  std::vector<std::pair<std::size_t, std::size_t>> near;
  for (std::size_t i = 0; i < submaps.size(); ++i) {
    for (std::size_t j = i + 1; j < submaps.size(); ++j) {
      const double d =
          (submaps[i].T_map_submap.translation() - submaps[j].T_map_submap.translation()).norm();
      if (d <= max_distance_m && static_cast<long long>(near.size()) < max_pairs) near.push_back({j, i});
    }
  }
  std::printf("%zu submaps; %zu overlapping pairs (origins <= %.0f m); the same pairs with a "
              "mirrored target as non-overlapping pairs\n",
              submaps.size(), near.size(), max_distance_m);
  for (core::GlobalRegistrationConfig::Method m : methods) {
    core::GlobalRegistrationConfig config;
    config.method = m;
    config.coarse_voxel_m = coarse_voxel_m;
    config.coarse_max_range_m = coarse_range_m;
    config.feature_radius_m = feature_radius_m;
    config.feature_match_epsilon = feature_epsilon;
    const core::StatusOr<core::GlobalRegistration> created =
        core::GlobalRegistration::Create(config);
    if (!created.ok()) {
      std::fprintf(stderr, "%s\n", created.status().message().c_str());
      return 2;
    }
    const core::GlobalRegistration& registration = created.value();
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> yaw(M_PI / 2.0, M_PI), dist(15.0, 30.0),
        dir(-M_PI, M_PI);
    std::vector<double> err_m, err_deg, times, coarse_times, cpu_times;
    StageMedians stages;  // overlapping pairs
    int accepted = 0, wrong = 0, far_accepted = 0;
    for (const auto& [s, t] : near) {
      const double a = dir(rng), r = dist(rng);
      const core::Pose3 moved =
          core::se3::FromXyzRpy(r * std::cos(a), r * std::sin(a), 0.0, 0.0, 0.0,
                                (rng() % 2 ? 1.0 : -1.0) * yaw(rng));
      core::PointVector source;
      source.reserve(submaps[s].points.size());
      for (const Eigen::Vector3d& p : submaps[s].points) source.push_back(moved * p);
      const std::clock_t cpu_start = std::clock();
      const core::GlobalRegistrationResult result = registration.Register(source, submaps[t].points);
      cpu_times.push_back(static_cast<double>(std::clock() - cpu_start) / CLOCKS_PER_SEC);
      times.push_back(result.time_s);
      coarse_times.push_back(result.coarse_time_s);
      stages.Add(result);
      const core::Pose3 reference = core::se3::Between(submaps[t].T_map_submap, submaps[s].T_map_submap);
      const core::Pose3 error = core::se3::Between(reference, result.T_target_source * moved);
      const double em = core::se3::TranslationNorm(error);
      const double ed = core::se3::RotationAngleRad(error) * 180.0 / M_PI;
      std::printf("  %s %u <- %u: %s %.3f m %.3f deg, overlap %.2f, structure %.2f, %.2f s "
                  "(coarse %.2f s) %s\n",
                  core::GlobalRegistrationMethodName(m), submaps[t].id, submaps[s].id,
                  result.accepted ? "accepted" : "rejected", em, ed, result.overlap_ratio,
                  result.structure_overlap_ratio, result.time_s, result.coarse_time_s,
                  result.reason.c_str());
      if (!result.accepted) continue;
      ++accepted;
      if (em > 1.0 || ed > 3.0) ++wrong;
      err_m.push_back(em);
      err_deg.push_back(ed);
    }
    for (const auto& [s, t] : near) {
      // A place that does not exist: the target mirrored (y -> -y). No rigid transform maps
      // the source onto it except by chance symmetry; every acceptance is wrong.
      core::PointVector mirrored = submaps[t].points;
      for (Eigen::Vector3d& p : mirrored) p.y() = -p.y();
      const std::clock_t cpu_start = std::clock();
      const core::GlobalRegistrationResult result = registration.Register(submaps[s].points, mirrored);
      cpu_times.push_back(static_cast<double>(std::clock() - cpu_start) / CLOCKS_PER_SEC);
      times.push_back(result.time_s);
      coarse_times.push_back(result.coarse_time_s);
      far_accepted += result.accepted;
      if (result.accepted) {
        // Is the place itself mirror-symmetric (a straight street lined alike on both sides)?
        // Then its mirror image is nearly the same place, and the acceptance says little.
        const core::GlobalRegistrationResult self =
            registration.Register(submaps[t].points, mirrored);
        std::printf("  %s %zu <- mirrored %zu: ACCEPTED, overlap %.2f, structure %.2f; the target "
                    "against its own mirror image: %s, overlap %.2f, structure %.2f\n",
                    core::GlobalRegistrationMethodName(m), s, t, result.overlap_ratio,
                    result.structure_overlap_ratio, self.accepted ? "accepted" : "rejected",
                    self.overlap_ratio, self.structure_overlap_ratio);
      }
    }
    std::printf("[%s] overlapping: %d/%zu accepted, %d of them wrong (> 1 m / 3 deg), error median "
                "%.3f m / %.3f deg; mirrored: %d/%zu accepted (must be 0); time per pair median "
                "%.3f s wall (coarse %.3f s), max %.3f s; CPU time per pair median %.3f s, max %.3f s\n",
                core::GlobalRegistrationMethodName(m), accepted, near.size(), wrong,
                Median(err_m), Median(err_deg), far_accepted, near.size(), Median(times),
                Median(coarse_times),
                times.empty() ? NAN : *std::max_element(times.begin(), times.end()),
                Median(cpu_times),
                cpu_times.empty() ? NAN : *std::max_element(cpu_times.begin(), cpu_times.end()));
    std::printf("[%s] overlapping pairs, median per step [s]: preparing both submaps %.3f, "
                "feature matching %.3f, hypotheses %.4f, fine %.3f\n",
                core::GlobalRegistrationMethodName(m), Median(stages.prepare),
                Median(stages.matching), Median(stages.hypotheses), Median(stages.fine));
  }
  return 0;
}
