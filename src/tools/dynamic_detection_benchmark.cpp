// dynamic_detection_benchmark: evaluates the low-dynamic detection (DynamicDetector) on two
// simulated sessions mapped separately by offline_mapper, against the simulator's labels.
//
//   dynamic_detection_benchmark --sim DIR --history-map DIR --current-map DIR
//       [--history s00] [--current s01] [--pair-radius 15] [--voxel 0.2] [--max-pairs N]
//       [--near X,Y,R]
//       [--align submap|start] [--compare-octomap] [--own-indices]
//
// GROUND TRUTH IS USED HERE ONLY (never by the pipeline): the two maps are put into the world
// frame with the truth poses of truth/<session>.tum: `--align submap` (default) places every
// submap by the truth sensor pose of its first scan (isolates the detector from SLAM drift,
// as a perfect inter-session registration would); `--align start` moves each whole session by
// its truth start pose only (drift stays). Submaps of the two sessions whose origins are
// within --pair-radius are paired. Every submap point takes the label of the nearest truth
// point of its own session (truth/<session>_labels.pcd, within 0.3 m), and the object's
// `sessions` in world.yaml say whether it is low-dynamic for this pair of sessions (present in
// exactly one of them). A low-dynamic point counts for DA when the other submap of some pair
// saw the object's place (>= 5 of its points inside the object's box grown by 0.3 m, as the
// python evaluator's footprint rule). A point is removed when any pair flags it. Reported with
// the height guard on and off: low-dynamic DA, SA (static points kept; all paired points and
// those within 2 m of the other submap), canopy SA, high-dynamic leftovers, time per pair.
#include <octomap/OcTree.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include <yaml-cpp/yaml.h>

#include "multisession_mapper/core/dynamic_detection.h"
#include "multisession_mapper/core/map_store.h"
#include "multisession_mapper/core/point_index.h"
#include "multisession_mapper/core/point_index_pool.h"
#include "multisession_mapper/core/ray_voxel_grid.h"
#include "multisession_mapper/core/trajectory_io.h"
#include "multisession_mapper/sim/label_cloud.h"
#include "multisession_mapper/tools/cli.h"

namespace msm = multisession_mapper;
namespace core = multisession_mapper::core;
namespace sim = multisession_mapper::sim;

namespace {

const char kUsage[] =
    "usage: dynamic_detection_benchmark --sim DIR --history-map DIR --current-map DIR [options]\n"
    "  --history NAME / --current NAME   session names (s00 / s01)\n"
    "  --pair-radius M    pair submaps whose origins are this close (15)\n"
    "  --voxel M          detector voxel size (default of DynamicDetectionConfig)\n"
    "  --max-pairs N      evaluate at most N pairs (0: all)\n"
    "  --near X,Y,R       only the pairs whose two submap origins both lie within R [m] of the\n"
    "                     world point (X, Y): the detection at one place\n"
    "  --align submap|start   truth alignment per submap (default) or per session start\n"
    "  --eval-range M     score only points within M of a scan origin of the other submap of a\n"
    "                     pair (25 = the detector's max_range_m; 0: every paired point)\n"
    "  --guard on|off|both  run with the height guard on, off or both (both)\n"
    "  --per-object       list the vacated low-dynamic objects with their removed points, the\n"
    "                     static parked cars and movables that lost points (by the free-space\n"
    "                     detection or in a changed object), and every object the\n"
    "                     changed-object step examined, with its truth\n"
    "  --compare-octomap  time OctoMap key lookups against the own voxel grid on the same rays\n"
    "  --own-indices      build both neighbour indices inside every pair instead of one per\n"
    "                     submap shared by its pairs (as the merge does)\n"
    "  --json FILE        also write the figures as JSON\n"
    "  --set KEY=VALUE    override a detector parameter (seed_distance_m, support_radius_m,\n"
    "                     min_passing_rays, max_support_points, min_cluster_points,\n"
    "                     min_cluster_coarse_points, max_object_bottom_m, max_range_m, far_range_m,\n                     max_ray_length_m,\n"
    "                     end_margin_m, rays_per_point, origin_spacing_m,\n"
    "                     dynamic_grow_radius_m, mending_distance_m,\n"
    "                     free_column_depth_m, column_clearance_m, guard_object_height_m,\n"
    "                     ground_tolerance_m, ground_cell_m, own_ground_max_gap_m,\n"
    "                     changed_objects_enabled (0/1), changed_compare_range_m,\n"
    "                     changed_grow_radius_m, changed_min_points, changed_max_extent_m,\n"
    "                     changed_max_bottom_m, far_ground_cell_m,\n"
    "                     far_max_bottom_m, changed_min_planar_fraction,\n"
    "                     changed_neighbour_radius_m, changed_surface_distance_m,\n"
    "                     changed_min_compared, changed_min_fraction,\n"
    "                     changed_partner_min_fraction, changed_end_min_compared,\n"
    "                     changed_end_min_fraction, changed_end_min_cos,\n"
    "                     changed_same_max_fraction, low_residue_min_ground_points,\n"
    "                     low_residue_radius_m, low_residue_partner_distance_m,\n"
    "                     low_residue_range_m, low_residue_max_own_neighbours,\n"
    "                     low_residue_blob_radius_m)\n";

constexpr int kCanopy = 6;
constexpr int kParkedCar = 7;
constexpr int kMovable = 8;
constexpr int kMovingCar = 9;
constexpr int kPedestrian = 10;

struct TruthCloud {
  core::PointVector points;
  std::vector<std::uint8_t> labels;
  std::vector<std::uint32_t> object_ids;
};

// The simulator's labels PCD, read with the simulator's own reader.
core::StatusOr<TruthCloud> ReadLabels(const std::string& path) {
  auto read = sim::LabelCloud::ReadPcd(path);
  if (!read.ok()) return read.status();
  TruthCloud cloud;
  const std::vector<sim::TruthPoint>& truth = read.value();
  cloud.points.resize(truth.size());
  cloud.labels.resize(truth.size());
  cloud.object_ids.resize(truth.size());
  for (std::size_t i = 0; i < truth.size(); ++i) {
    cloud.points[i] = truth[i].position_m.cast<double>();
    cloud.labels[i] = static_cast<std::uint8_t>(truth[i].label);
    cloud.object_ids[i] = truth[i].object_id;
  }
  return cloud;
}

struct WorldObject {
  std::string cls;
  std::set<std::string> sessions;  // empty: all
  double pose[4] = {0, 0, 0, 0};
  double size[3] = {0, 0, 0};
};

// Whether the object's box (grown by margin) holds at least min_points of `index`.
bool ObservedPlace(const WorldObject& obj, const core::PointIndex& index, double margin_m,
                   int min_points) {
  const Eigen::Vector3d centre(obj.pose[0], obj.pose[1], obj.pose[2]);
  const Eigen::Vector3d half =
      Eigen::Vector3d(obj.size[0], obj.size[1], obj.size[2]) / 2.0 +
      Eigen::Vector3d::Constant(margin_m);
  std::vector<std::uint32_t> near;
  index.Radius(centre, half.norm(), &near);
  const double c = std::cos(obj.pose[3]), s = std::sin(obj.pose[3]);
  int inside = 0;
  for (std::uint32_t j : near) {
    const Eigen::Vector3d d = index.points()[j] - centre;
    const double u = c * d.x() + s * d.y(), v = -s * d.x() + c * d.y();
    if (std::abs(u) <= half.x() && std::abs(v) <= half.y() && std::abs(d.z()) <= half.z()) {
      ++inside;
    }
  }
  return inside >= min_points;
}

Eigen::Isometry3d TruthAt(const core::Trajectory& truth, double stamp) {
  auto it = std::lower_bound(truth.begin(), truth.end(), stamp,
                             [](const core::StampedPose& p, double t) { return p.stamp_s < t; });
  if (it == truth.end()) return truth.back().pose;
  if (it != truth.begin() && std::abs((it - 1)->stamp_s - stamp) < std::abs(it->stamp_s - stamp)) {
    --it;
  }
  return it->pose;
}

struct SessionData {
  std::string name;
  std::vector<core::Submap, Eigen::aligned_allocator<core::Submap>> submaps;
  std::vector<Eigen::Isometry3d, Eigen::aligned_allocator<Eigen::Isometry3d>> T_world_submap;
  // Per submap, per point: label, object id (0 when no truth point within 0.3 m: label 255).
  std::vector<std::vector<std::uint8_t>> labels;
  std::vector<std::vector<std::uint32_t>> objects;
};

core::StatusOr<SessionData> LoadSession(const std::string& map_dir, const std::string& sim_dir,
                                        const std::string& name, bool align_per_submap) {
  const core::MapStore store;
  core::StatusOr<core::MapContents> map = store.Load(map_dir);
  if (!map.ok()) return map.status();
  core::StatusOr<core::Trajectory> truth = core::ReadTumFile(sim_dir + "/truth/" + name + ".tum");
  if (!truth.ok()) return truth.status();
  core::StatusOr<TruthCloud> labels = ReadLabels(sim_dir + "/truth/" + name + "_labels.pcd");
  if (!labels.ok()) return labels.status();
  core::StatusOr<core::PointIndex> index = core::PointIndex::Create(labels.value().points);
  if (!index.ok()) return index.status();
  SessionData data;
  data.name = name;
  // Session alignment: the map frame is the sensor frame of the session's first scan.
  const core::Trajectory& optimised = map.value().trajectories.begin()->second;
  const Eigen::Isometry3d T_world_map =
      TruthAt(truth.value(), optimised.front().stamp_s) * optimised.front().pose.inverse();
  for (const core::Submap& submap : map.value().submaps) {
    if (submap.scans.empty() || submap.points.empty()) continue;
    Eigen::Isometry3d T_world_submap = T_world_map * submap.T_map_submap;
    if (align_per_submap) {
      T_world_submap = TruthAt(truth.value(), submap.scans.front().stamp_s) *
                       submap.scans.front().T_submap_sensor.inverse();
    }
    std::vector<double> distances;
    std::vector<std::uint8_t> point_labels(submap.points.size(), 255);
    std::vector<std::uint32_t> point_objects(submap.points.size(), 0);
    for (std::size_t i = 0; i < submap.points.size(); ++i) {
      std::uint32_t j = 0;
      double d2 = 0.0;
      if (index.value().Nearest(T_world_submap * submap.points[i], &j, &d2)) {
        distances.push_back(std::sqrt(d2));
      }
      if (d2 <= 0.09) {
        point_labels[i] = labels.value().labels[j];
        point_objects[i] = labels.value().object_ids[j];
      }
    }
    std::sort(distances.begin(), distances.end());
    if (!distances.empty()) {
      std::printf("  %s/%u: %zu points, %zu scans, distance to the truth points: median %.3f m, "
                  "90 %% %.3f m\n",
                  name.c_str(), submap.id, submap.points.size(), submap.scans.size(),
                  distances[distances.size() / 2], distances[distances.size() * 9 / 10]);
    }
    data.submaps.push_back(submap);
    data.T_world_submap.push_back(T_world_submap);
    data.labels.push_back(std::move(point_labels));
    data.objects.push_back(std::move(point_objects));
  }
  return data;
}

double Median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

// Times the same rays (each history point from its nearest origin) through an OcTree
// (computeRayKeys + search per key) and through RayVoxelGrid (Traverse + cell lookup).
void CompareOctomap(const core::Submap& submap, double voxel_m) {
  octomap::OcTree tree(voxel_m);
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e9), hi = -lo;
  for (const Eigen::Vector3d& p : submap.points) {
    tree.updateNode(octomap::point3d(p.x(), p.y(), p.z()), true, true);
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  tree.updateInnerOccupancy();
  std::vector<Eigen::Vector3d> origins;
  for (const core::SubmapScanRecord& s : submap.scans) {
    origins.push_back(s.T_submap_sensor.translation());
    lo = lo.cwiseMin(origins.back());
    hi = hi.cwiseMax(origins.back());
  }
  core::StatusOr<core::RayVoxelGrid> grid =
      core::RayVoxelGrid::Create(voxel_m, lo - Eigen::Vector3d::Constant(1.0),
                                 hi + Eigen::Vector3d::Constant(1.0));
  if (!grid.ok()) return;
  for (const Eigen::Vector3d& p : submap.points) grid.value().Touch(grid.value().KeyOf(p))->flags = 1;
  std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> rays;
  for (std::size_t i = 0; i < submap.points.size(); i += 4) {
    const Eigen::Vector3d& p = submap.points[i];
    const Eigen::Vector3d* best = &origins.front();
    for (const Eigen::Vector3d& o : origins) {
      if ((o - p).squaredNorm() < (*best - p).squaredNorm()) best = &o;
    }
    rays.emplace_back(*best, p);
  }
  long octo_hits = 0, own_hits = 0;
  const auto t0 = std::chrono::steady_clock::now();
  octomap::KeyRay key_ray;
  for (const auto& [o, p] : rays) {
    tree.computeRayKeys(octomap::point3d(o.x(), o.y(), o.z()), octomap::point3d(p.x(), p.y(), p.z()),
                        key_ray);
    for (const octomap::OcTreeKey& key : key_ray) {
      const octomap::OcTreeNode* node = tree.search(key);
      if (node != nullptr && tree.isNodeOccupied(node)) ++octo_hits;
    }
  }
  const auto t1 = std::chrono::steady_clock::now();
  for (const auto& [o, p] : rays) {
    grid.value().Traverse(o, p, [&](core::RayVoxelGrid::Cell* cell, double) {
      if (cell != nullptr && cell->flags) ++own_hits;
      return true;
    });
  }
  const auto t2 = std::chrono::steady_clock::now();
  std::printf("  octomap vs own grid: %zu rays, voxel %.2f m: octomap %.1f ms (%ld occupied "
              "keys), own %.1f ms (%ld occupied voxels)\n",
              rays.size(), voxel_m, std::chrono::duration<double, std::milli>(t1 - t0).count(),
              octo_hits, std::chrono::duration<double, std::milli>(t2 - t1).count(), own_hits);
}

}  // namespace

int main(int argc, char** argv) {
  std::string sim_dir, history_map, current_map, history_name = "s00", current_name = "s01";
  std::string align = "submap";
  double pair_radius = 15.0, voxel = 0.0, eval_range = 25.0;
  long long max_pairs = 0;
  std::vector<double> near;  // x, y, radius (empty: every pair)
  bool compare_octomap = false;
  bool shared_indices = true;
  bool per_object = false;
  std::string guard_mode = "both";
  std::string json_path;
  std::vector<std::pair<std::string, double>> overrides;
  std::string json = "{";
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    auto next = [&](std::string* out) {
      if (i + 1 >= argc) return false;
      *out = argv[++i];
      return true;
    };
    std::string value;
    bool ok = true;
    if (arg == "--sim") ok = next(&sim_dir);
    else if (arg == "--history-map") ok = next(&history_map);
    else if (arg == "--current-map") ok = next(&current_map);
    else if (arg == "--history") ok = next(&history_name);
    else if (arg == "--current") ok = next(&current_name);
    else if (arg == "--align") ok = next(&align) && (align == "submap" || align == "start");
    else if (arg == "--pair-radius") ok = next(&value) && msm::tools::ParseDouble(value, &pair_radius);
    else if (arg == "--eval-range") ok = next(&value) && msm::tools::ParseDouble(value, &eval_range);
    else if (arg == "--voxel") ok = next(&value) && msm::tools::ParseDouble(value, &voxel);
    else if (arg == "--max-pairs") ok = next(&value) && msm::tools::ParseInt(value, &max_pairs);
    else if (arg == "--near") {
      ok = next(&value);
      near.clear();  // the last --near counts
      std::stringstream parts(value);
      std::string part;
      double v = 0.0;
      while (ok && std::getline(parts, part, ',')) {
        ok = msm::tools::ParseDouble(part, &v);
        near.push_back(v);
      }
      ok = ok && near.size() == 3 && near[2] > 0.0 && value.back() != ',';
    }
    else if (arg == "--compare-octomap") compare_octomap = true;
    else if (arg == "--own-indices") shared_indices = false;
    else if (arg == "--per-object") per_object = true;
    else if (arg == "--guard") ok = next(&guard_mode) && (guard_mode == "on" || guard_mode == "off" || guard_mode == "both");
    else if (arg == "--json") ok = next(&json_path);
    else if (arg == "--set") {
      double v = 0.0;
      ok = next(&value) && value.find('=') != std::string::npos &&
           msm::tools::ParseDouble(value.substr(value.find('=') + 1), &v);
      if (ok) overrides.emplace_back(value.substr(0, value.find('=')), v);
    }
    else ok = false;
    if (!ok) {
      std::fprintf(stderr, "dynamic_detection_benchmark: bad argument %s\n%s", arg.c_str(), kUsage);
      return 2;
    }
  }
  if (sim_dir.empty() || history_map.empty() || current_map.empty()) {
    std::fprintf(stderr, "%s", kUsage);
    return 2;
  }
  // World objects: class, sessions, box.
  std::map<std::uint32_t, WorldObject> objects;
  try {
    const YAML::Node world = YAML::LoadFile(sim_dir + "/world.yaml");
    for (const YAML::Node& node : world["objects"]) {
      WorldObject obj;
      obj.cls = node["class"].as<std::string>("");
      if (node["sessions"]) {
        for (const YAML::Node& s : node["sessions"]) obj.sessions.insert(s.as<std::string>());
      }
      if (node["pose"]) for (int k = 0; k < 4; ++k) obj.pose[k] = node["pose"][k].as<double>();
      if (node["size"]) for (int k = 0; k < 3; ++k) obj.size[k] = node["size"][k].as<double>();
      objects[node["id"].as<std::uint32_t>()] = obj;
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "dynamic_detection_benchmark: world.yaml: %s\n", e.what());
    return 1;
  }
  const bool per_submap = align == "submap";
  core::StatusOr<SessionData> history = LoadSession(history_map, sim_dir, history_name, per_submap);
  core::StatusOr<SessionData> current = LoadSession(current_map, sim_dir, current_name, per_submap);
  if (!history.ok() || !current.ok()) {
    std::fprintf(stderr, "dynamic_detection_benchmark: %s\n",
                 (!history.ok() ? history.status() : current.status()).message().c_str());
    return 1;
  }
  const SessionData& H = history.value();
  const SessionData& C = current.value();
  auto is_low = [&](std::uint32_t object_id) {
    auto it = objects.find(object_id);
    if (it == objects.end() || object_id == 0 || it->second.sessions.empty()) return false;
    if (it->second.cls == "moving_car" || it->second.cls == "pedestrian") return false;
    return it->second.sessions.count(H.name) != it->second.sessions.count(C.name);
  };

  // A low-dynamic object whose place holds another parked car / movable object of the session
  // it is absent from ("replaced"): free-space evidence only exists where the shapes differ.
  auto replaced = [&](std::uint32_t object_id) {
    const WorldObject& x = objects[object_id];
    const std::string& absent_from = x.sessions.count(H.name) ? C.name : H.name;
    for (const auto& [id, y] : objects) {
      if (id == object_id || (y.cls != "parked_car" && y.cls != "movable")) continue;
      if (!y.sessions.empty() && !y.sessions.count(absent_from)) continue;
      if (std::hypot(y.pose[0] - x.pose[0], y.pose[1] - x.pose[1]) < 2.5) return true;
    }
    return false;
  };
  std::map<std::uint32_t, bool> replaced_cache;
  auto is_replaced = [&](std::uint32_t id) {
    auto it = replaced_cache.find(id);
    if (it == replaced_cache.end()) it = replaced_cache.emplace(id, replaced(id)).first;
    return it->second;
  };
  std::vector<std::pair<std::size_t, std::size_t>> pairs;
  for (std::size_t h = 0; h < H.submaps.size(); ++h) {
    for (std::size_t c = 0; c < C.submaps.size(); ++c) {
      const Eigen::Vector3d& a = H.T_world_submap[h].translation();
      const Eigen::Vector3d& b = C.T_world_submap[c].translation();
      const bool here = near.empty() || (std::hypot(a.x() - near[0], a.y() - near[1]) <= near[2] &&
                                         std::hypot(b.x() - near[0], b.y() - near[1]) <= near[2]);
      if ((a - b).norm() <= pair_radius && here) {
        pairs.emplace_back(h, c);
      }
    }
  }
  if (max_pairs > 0 && pairs.size() > static_cast<std::size_t>(max_pairs)) pairs.resize(max_pairs);
  std::size_t h_points = 0, c_points = 0;
  for (const auto& s : H.submaps) h_points += s.points.size();
  for (const auto& s : C.submaps) c_points += s.points.size();
  std::printf("sessions %s (%zu submaps, %zu points) / %s (%zu submaps, %zu points), %zu pairs "
              "within %.1f m, alignment: truth per %s, scored within %.1f m of the other "
              "submap's scan origins (0: all)\n",
              H.name.c_str(), H.submaps.size(), h_points, C.name.c_str(), C.submaps.size(),
              c_points, pairs.size(), pair_radius, per_submap ? "submap" : "session start",
              eval_range);
  if (!near.empty()) {
    std::printf("only the pairs with both submap origins within %.1f m of (%.1f, %.1f)\n", near[2],
                near[0], near[1]);
  }
  if (compare_octomap && !pairs.empty()) {
    const double v = voxel > 0.0 ? voxel : core::DynamicDetectionConfig().voxel_size_m;
    CompareOctomap(H.submaps[pairs.front().first], v);
    CompareOctomap(C.submaps[pairs.front().second], v);
  }

  for (bool guard : {true, false}) {
    if ((guard && guard_mode == "off") || (!guard && guard_mode == "on")) continue;
    core::DynamicDetectionConfig config;
    config.height_guard_enabled = guard;
    if (voxel > 0.0) config.voxel_size_m = voxel;
    for (const auto& [key, v] : overrides) {
      if (key == "seed_distance_m") config.seed_distance_m = v;
      else if (key == "changed_end_min_compared")
        config.changed_end_min_compared = static_cast<int>(v);
      else if (key == "changed_end_min_fraction") config.changed_end_min_fraction = v;
      else if (key == "changed_end_min_cos") config.changed_end_min_cos = v;
      else if (key == "support_radius_m") config.support_radius_m = v;
      else if (key == "free_column_depth_m") config.free_column_depth_m = v;
      else if (key == "column_clearance_m") config.column_clearance_m = v;
      else if (key == "guard_object_height_m") config.guard_object_height_m = v;
      else if (key == "min_passing_rays") config.min_passing_rays = static_cast<int>(v);
      else if (key == "max_support_points") config.max_support_points = static_cast<int>(v);
      else if (key == "min_cluster_points") config.min_cluster_points = static_cast<int>(v);
      else if (key == "min_cluster_coarse_points") config.min_cluster_coarse_points = static_cast<int>(v);
      else if (key == "min_cluster_coarse_fraction") config.min_cluster_coarse_fraction = v;
      else if (key == "min_pass_incidence_rad") config.min_pass_incidence_rad = v;
      else if (key == "rays_from_viewing_scans") config.rays_from_viewing_scans = v != 0.0;
      else if (key == "max_object_bottom_m") config.max_object_bottom_m = v;
      else if (key == "bottom_extension_radius_m") config.bottom_extension_radius_m = v;
      else if (key == "bottom_min_height_m") config.bottom_min_height_m = v;
      else if (key == "bottom_max_drop_m") config.bottom_max_drop_m = v;
      else if (key == "max_range_m") config.max_range_m = v;
      else if (key == "far_range_m") config.far_range_m = v;
      else if (key == "max_ray_length_m") config.max_ray_length_m = v;
      else if (key == "end_margin_m") config.end_margin_m = v;
      else if (key == "rays_per_point") config.rays_per_point = static_cast<int>(v);
      else if (key == "origin_spacing_m") config.origin_spacing_m = v;
      else if (key == "dynamic_grow_radius_m") config.dynamic_grow_radius_m = v;
      else if (key == "mending_distance_m") config.mending_distance_m = v;
      else if (key == "ground_tolerance_m") config.ground_tolerance_m = v;
      else if (key == "ground_cell_m") config.ground_cell_m = v;
      else if (key == "own_ground_max_gap_m") config.own_ground_max_gap_m = v;
      else if (key == "changed_objects_enabled") config.changed_objects_enabled = v != 0.0;
      else if (key == "changed_compare_range_m") config.changed_compare_range_m = v;
      else if (key == "changed_grow_radius_m") config.changed_grow_radius_m = v;
      else if (key == "changed_min_points") config.changed_min_points = static_cast<int>(v);
      else if (key == "changed_max_extent_m") config.changed_max_extent_m = v;
      else if (key == "changed_max_bottom_m") config.changed_max_bottom_m = v;
      else if (key == "far_ground_cell_m") config.far_ground_cell_m = v;
      else if (key == "far_max_bottom_m") config.far_max_bottom_m = v;
      else if (key == "changed_min_planar_fraction") config.changed_min_planar_fraction = v;
      else if (key == "changed_neighbour_radius_m") config.changed_neighbour_radius_m = v;
      else if (key == "changed_surface_distance_m") config.changed_surface_distance_m = v;
      else if (key == "changed_min_compared") config.changed_min_compared = static_cast<int>(v);
      else if (key == "changed_min_fraction") config.changed_min_fraction = v;
      else if (key == "changed_partner_min_fraction") config.changed_partner_min_fraction = v;
      else if (key == "changed_same_max_fraction") config.changed_same_max_fraction = v;
      else if (key == "low_residue_min_ground_points") {
        config.low_residue_min_ground_points = static_cast<int>(v);
      } else if (key == "low_residue_radius_m") config.low_residue_radius_m = v;
      else if (key == "low_residue_partner_distance_m") config.low_residue_partner_distance_m = v;
      else if (key == "low_residue_range_m") config.low_residue_range_m = v;
      else if (key == "low_residue_max_own_neighbours") {
        config.low_residue_max_own_neighbours = static_cast<int>(v);
      } else if (key == "low_residue_blob_radius_m") config.low_residue_blob_radius_m = v;
      else {
        std::fprintf(stderr, "dynamic_detection_benchmark: unknown --set key %s\n", key.c_str());
        return 2;
      }
    }
    core::StatusOr<core::DynamicDetector> detector = core::DynamicDetector::Create(config);
    if (!detector.ok()) {
      std::fprintf(stderr, "dynamic_detection_benchmark: %s\n", detector.status().message().c_str());
      return 1;
    }
    // Per session, per submap, per point: 1 bit removed, 2 bit paired, 4 bit low observed,
    // 8 bit within 2 m of the other submap; the changed-object step (step 5) in some pair:
    // 16 bit within its compare range of both submaps' scan origins (every scan origin and
    // every height: the detector also needs the point above its ground), 32 bit in an object
    // it examined, 64 bit in an object it found changed.
    std::vector<std::vector<std::uint8_t>> flags[2];
    for (int s = 0; s < 2; ++s) {
      const SessionData& d = s == 0 ? H : C;
      for (const auto& submap : d.submaps) flags[s].emplace_back(submap.points.size(), 0);
    }
    std::vector<double> times, cpu_times;
    // Per step of the detection (DynamicDetectionResult::StageTimes), in its order.
    using StageTimes = core::DynamicDetectionResult::StageTimes;
    std::vector<double> stage_times[StageTimes::kCount];
    std::size_t mending = 0;
    std::size_t grown[2] = {0, 0};  // points grown into the common parts, summed over pairs
    struct Examined {
      core::DynamicDetectionResult::ExaminedObject object;
      std::size_t submap;
    };
    std::vector<Examined> examined;
    // As in the merge: one neighbour index per submap, shared by its pairs (each pair is
    // charged its share of both indices' construction).
    std::vector<int> uses[2] = {std::vector<int>(H.submaps.size(), 0),
                                std::vector<int>(C.submaps.size(), 0)};
    for (const auto& [h, c] : pairs) {
      ++uses[0][h];
      ++uses[1][c];
    }
    core::PointIndexPool history_indices(
        uses[0], [&](std::size_t k) -> const core::PointVector& { return H.submaps[k].points; });
    core::PointIndexPool current_indices(
        uses[1], [&](std::size_t k) -> const core::PointVector& { return C.submaps[k].points; });
    for (const auto& [h, c] : pairs) {
      const Eigen::Isometry3d T_current_history = C.T_world_submap[c].inverse() * H.T_world_submap[h];
      const std::clock_t cpu_start = std::clock();
      core::StatusOr<core::DynamicDetectionResult> result =
          shared_indices
              ? detector.value().Detect(H.submaps[h], C.submaps[c], T_current_history,
                                        &history_indices, h, &current_indices, c)
              : detector.value().Detect(H.submaps[h], C.submaps[c], T_current_history);
      cpu_times.push_back(static_cast<double>(std::clock() - cpu_start) / CLOCKS_PER_SEC);
      if (!result.ok()) {
        std::fprintf(stderr, "pair %zu/%zu: %s\n", h, c, result.status().message().c_str());
        continue;
      }
      times.push_back(result.value().time_s);
      const auto steps = result.value().stage.Named();
      for (int k = 0; k < StageTimes::kCount; ++k) stage_times[k].push_back(steps[k].second);
      for (const auto& object : result.value().examined_objects) {
        examined.push_back({object, object.side == 0 ? h : c});
        auto& marks = flags[object.side][object.side == 0 ? h : c];
        for (std::uint32_t i : object.points) marks[i] |= object.changed ? 32 | 64 : 32;
      }
      mending += result.value().current_mending.size();
      for (int s = 0; s < 2; ++s) grown[s] += result.value().common_grown[s];
      for (std::uint32_t i : result.value().history_dynamic) flags[0][h][i] |= 1;
      for (std::uint32_t i : result.value().current_dynamic) flags[1][c][i] |= 1;
      // Paired / observed / near flags, in the world frame.
      for (int s = 0; s < 2; ++s) {
        const SessionData& self = s == 0 ? H : C;
        const SessionData& other = s == 0 ? C : H;
        const std::size_t mine = s == 0 ? h : c, theirs = s == 0 ? c : h;
        core::PointVector other_world;
        for (const Eigen::Vector3d& p : other.submaps[theirs].points) {
          other_world.push_back(other.T_world_submap[theirs] * p);
        }
        core::StatusOr<core::PointIndex> other_index = core::PointIndex::Create(other_world);
        std::map<std::uint32_t, bool> observed;
        std::vector<Eigen::Vector3d> other_origins, own_origins;
        for (const core::SubmapScanRecord& scan : other.submaps[theirs].scans) {
          other_origins.push_back(other.T_world_submap[theirs] * scan.T_submap_sensor.translation());
        }
        for (const core::SubmapScanRecord& scan : self.submaps[mine].scans) {
          own_origins.push_back(self.T_world_submap[mine] * scan.T_submap_sensor.translation());
        }
        const double compare_sq = config.changed_compare_range_m * config.changed_compare_range_m;
        for (std::size_t i = 0; i < self.submaps[mine].points.size(); ++i) {
          std::uint8_t& f = flags[s][mine][i];
          const Eigen::Vector3d p = self.T_world_submap[mine] * self.submaps[mine].points[i];
          if (eval_range > 0.0 && !core::NearAny(other_origins, p, eval_range * eval_range)) {
            continue;
          }
          f |= 2;
          if (other_index.value().CountWithin(p, 2.0, 1) > 0) f |= 8;
          const std::uint32_t id = self.objects[mine][i];
          if (is_low(id)) {
            auto it = observed.find(id);
            if (it == observed.end()) {
              it = observed.emplace(id, ObservedPlace(objects[id], other_index.value(), 0.3, 5)).first;
            }
            if (it->second) f |= 4;
            if (core::NearAny(own_origins, p, compare_sq) &&
                core::NearAny(other_origins, p, compare_sq)) {
              f |= 16;
            }
          }
        }
      }
    }
    long static_all = 0, static_kept = 0, static_near = 0, static_near_kept = 0;
    long canopy = 0, canopy_kept = 0, low = 0, low_removed = 0, high = 0, high_removed = 0;
    long low_unobserved = 0, unlabelled = 0, low_replaced = 0, low_replaced_removed = 0;
    // Replaced low-dynamic points by what the changed-object step did with them: out of its
    // compare range, in range but in no examined object (ground-level parts, too few points,
    // rejected by size or shape), examined and not found changed, found changed; {points,
    // removed} each.
    long replaced_by_step5[4][2] = {};
    std::map<std::uint32_t, std::pair<long, long>> vacated_objects;
    // Vacated low-dynamic points by height above their object's bottom (0.25 m bins).
    constexpr int kHeightBins = 12;
    long vacated_by_height[kHeightBins][2] = {};  // points, removed
    long static_removed_by_class[sim::kNumObjectClasses] = {};
    // Static objects of a movable class (parked cars that stayed, movables present throughout):
    // {points, removed outside a changed object (free-space detection), removed in one}.
    std::map<std::uint32_t, std::array<long, 3>> static_movables;
    for (int s = 0; s < 2; ++s) {
      const SessionData& d = s == 0 ? H : C;
      for (std::size_t m = 0; m < d.submaps.size(); ++m) {
        for (std::size_t i = 0; i < d.submaps[m].points.size(); ++i) {
          const std::uint8_t f = flags[s][m][i];
          if (!(f & 2)) continue;
          const int label = d.labels[m][i];
          const bool removed = f & 1;
          if (label == 255) {
            ++unlabelled;
          } else if (label == kMovingCar || label == kPedestrian) {
            ++high;
            high_removed += removed;
          } else if (is_low(d.objects[m][i])) {
            if (f & 4) {
              ++low;
              low_removed += removed;
              if (is_replaced(d.objects[m][i])) {
                ++low_replaced;
                low_replaced_removed += removed;
                const int k = (f & 64) ? 3 : (f & 32) ? 2 : (f & 16) ? 1 : 0;
                ++replaced_by_step5[k][0];
                replaced_by_step5[k][1] += removed;
              } else if (per_object) {
                const std::uint32_t id = d.objects[m][i];
                auto& counts = vacated_objects[id];
                ++counts.first;
                counts.second += removed;
                const WorldObject& obj = objects[id];
                const double above =
                    (d.T_world_submap[m] * d.submaps[m].points[i]).z() - (obj.pose[2] - obj.size[2] / 2.0);
                const int bin = std::min(std::max(static_cast<int>(above / 0.25), 0), kHeightBins - 1);
                ++vacated_by_height[bin][0];
                vacated_by_height[bin][1] += removed;
              }
            } else {
              ++low_unobserved;
            }
          } else {
            ++static_all;
            static_kept += !removed;
            if (removed && label < sim::kNumObjectClasses) ++static_removed_by_class[label];
            if (per_object && (label == kParkedCar || label == kMovable)) {
              auto& counts = static_movables[d.objects[m][i]];
              ++counts[0];
              if (removed) ++counts[(f & 64) ? 2 : 1];
            }
            if (f & 8) {
              ++static_near;
              static_near_kept += !removed;
            }
            if (label == kCanopy) {
              ++canopy;
              canopy_kept += !removed;
            }
          }
        }
      }
    }
    auto pct = [](long a, long b) { return b > 0 ? 100.0 * a / b : 0.0; };
    // Changed-object step by the truth of each examined object's majority label.
    std::map<std::string, std::pair<long, long>> examined_by_truth;  // objects, changed
    for (const Examined& e : examined) {
      const SessionData& d = e.object.side == 0 ? H : C;
      std::map<std::uint32_t, int> votes;
      for (std::uint32_t i : e.object.points) ++votes[d.objects[e.submap][i]];
      std::uint32_t id = 0;
      int best = 0;
      for (const auto& [object_id, count] : votes) {
        if (count > best) std::tie(id, best) = std::tie(object_id, count);
      }
      const auto it = objects.find(id);
      const std::string cls = id == 0 || it == objects.end() ? "none" : it->second.cls;
      const std::string truth =
          cls + (is_low(id) ? (is_replaced(id) ? " low replaced" : " low vacated") : " static");
      auto& counts = examined_by_truth[truth];
      ++counts.first;
      counts.second += e.object.changed;
      if (per_object) {
        std::printf("    examined %s %s/%zu object %u (%s): %zu points, %d/%d off the other's "
                    "surface (%.0f %%; %d seen through), ends %d/%d and %d/%d off%s\n",
                    e.object.side == 0 ? "history" : "current", d.name.c_str(), e.submap, id,
                    truth.c_str(),
                    e.object.points.size(), e.object.off_surface, e.object.compared,
                    pct(e.object.off_surface, e.object.compared), e.object.seen_through,
                    e.object.end_off[0], e.object.end_compared[0], e.object.end_off[1],
                    e.object.end_compared[1],
                    e.object.changed ? (e.object.by_partner ? ": CHANGED (partner)" : ": CHANGED")
                                     : "");
      }
    }
    std::printf("  changed-object step: examined objects by truth (majority label): ");
    for (const auto& [truth, counts] : examined_by_truth) {
      std::printf("%s %ld changed of %ld; ", truth.c_str(), counts.second, counts.first);
    }
    std::printf("\n");
    std::printf("height guard %s (voxel %.2f m):\n", guard ? "ON " : "OFF", config.voxel_size_m);
    std::printf("  low-dynamic DA %.2f %% (%ld/%ld removed; %ld low-dynamic points whose place "
                "the other session did not see)\n",
                pct(low_removed, low), low_removed, low, low_unobserved);
    std::printf("    of which on a place taken by another object in the other session: DA %.2f %% "
                "(%ld/%ld); on a vacated place: DA %.2f %% (%ld/%ld)\n",
                pct(low_replaced_removed, low_replaced), low_replaced_removed, low_replaced,
                pct(low_removed - low_replaced_removed, low - low_replaced),
                low_removed - low_replaced_removed, low - low_replaced);
    std::printf("    replaced points by the changed-object step (removed/all): out of its "
                "compare range %ld/%ld, in range but in no examined object %ld/%ld, examined "
                "and not changed %ld/%ld, changed %ld/%ld\n",
                replaced_by_step5[0][1], replaced_by_step5[0][0], replaced_by_step5[1][1],
                replaced_by_step5[1][0], replaced_by_step5[2][1], replaced_by_step5[2][0],
                replaced_by_step5[3][1], replaced_by_step5[3][0]);
    if (per_object) {
      std::printf("    vacated points by height above the object's bottom (0.25 m bins, removed/all):");
      for (int b = 0; b < kHeightBins; ++b) {
        std::printf(" %.2f: %ld/%ld", 0.25 * b, vacated_by_height[b][1], vacated_by_height[b][0]);
      }
      std::printf("\n");
    }
    for (const auto& [id, counts] : vacated_objects) {
      std::printf("    vacated object %u (%s, %.1f x %.1f x %.1f m): %ld/%ld points removed\n", id,
                  objects[id].cls.c_str(), objects[id].size[0], objects[id].size[1],
                  objects[id].size[2], counts.second, counts.first);
    }
    std::printf("  static SA %.3f %% (%ld/%ld kept); within 2 m of the other submap %.3f %% "
                "(%ld/%ld)\n",
                pct(static_kept, static_all), static_kept, static_all,
                pct(static_near_kept, static_near), static_near_kept, static_near);
    std::printf("    static points removed by class:");
    for (int k = 0; k < sim::kNumObjectClasses; ++k) {
      if (static_removed_by_class[k] > 0) {
        std::printf(" %s %ld", sim::ObjectClassName(static_cast<sim::ObjectClass>(k)),
                    static_removed_by_class[k]);
      }
    }
    std::printf("\n");
    for (const auto& [id, counts] : static_movables) {
      if (counts[1] + counts[2] == 0) continue;
      std::printf("    static object %u (%s) lost %ld/%ld points: %ld by the free-space "
                  "detection, %ld in changed objects\n",
                  id, objects[id].cls.c_str(), counts[1] + counts[2], counts[0], counts[1],
                  counts[2]);
    }
    std::printf("  canopy SA %.3f %% (%ld/%ld kept)\n", pct(canopy_kept, canopy), canopy_kept,
                canopy);
    std::printf("  high-dynamic leftovers in the submaps: %ld, removed %ld; unlabelled %ld\n",
                high, high_removed, unlabelled);
    const double max_time = times.empty() ? 0.0 : *std::max_element(times.begin(), times.end());
    std::printf("  time per pair: median %.3f s, max %.3f s over %zu pairs (wall); CPU time "
                "median %.3f s, max %.3f s; mending %zu points; grown into the common parts: "
                "%zu history, %zu current points\n",
                Median(times), max_time, times.size(), Median(cpu_times),
                cpu_times.empty() ? 0.0 : *std::max_element(cpu_times.begin(), cpu_times.end()),
                mending, grown[0], grown[1]);
    std::printf("    median per step [ms]:");
    const auto names = StageTimes().Named();
    for (int k = 0; k < StageTimes::kCount; ++k) {
      std::printf(" %s %.1f", names[k].first, 1e3 * Median(stage_times[k]));
    }
    std::printf("\n");
    char buffer[1024];
    std::snprintf(buffer, sizeof(buffer),
                  "%s\"height_guard_%s\": {\"low_dynamic_da\": %.5f, \"low_dynamic_points\": %ld, "
                  "\"static_sa\": %.5f, \"static_sa_near\": %.5f, \"canopy_sa\": %.5f, "
                  "\"canopy_points\": %ld, \"pairs\": %zu, \"median_pair_s\": %.4f, "
                  "\"max_pair_s\": %.4f, \"voxel_size_m\": %.3f}",
                  json.size() > 1 ? ", " : "", guard ? "on" : "off", pct(low_removed, low) / 100.0, low,
                  pct(static_kept, static_all) / 100.0, pct(static_near_kept, static_near) / 100.0,
                  pct(canopy_kept, canopy) / 100.0, canopy, times.size(), Median(times), max_time,
                  config.voxel_size_m);
    json += buffer;
  }
  if (!json_path.empty()) {
    std::ofstream out(json_path);
    out << json << ", \"sessions\": [\"" << H.name << "\", \"" << C.name
        << "\"], \"alignment\": \"truth per " << align << "\"";
    if (!near.empty()) {
      out << ", \"near\": {\"x\": " << near[0] << ", \"y\": " << near[1]
          << ", \"radius_m\": " << near[2] << "}";
    }
    out << "}\n";
    if (!out) {
      std::fprintf(stderr, "dynamic_detection_benchmark: cannot write %s\n", json_path.c_str());
      return 1;
    }
  }
  return 0;
}
