// Shared helpers of the libFuzzer targets on the map loader (test/fuzz/README.md): a per-process
// scratch folder, a small valid template map written with MapStore::Save (the files a fuzz input
// replaces are taken from it), and the container format of the whole-directory target.
#pragma once

#include <unistd.h>

#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <utility>
#include <vector>

#include "multisession_mapper/core/map_store.h"
#include "multisession_mapper/core/se3.h"

namespace multisession_mapper {
namespace fuzz {

namespace fs = std::filesystem;

/// Scratch folder of this process (removed at exit by the scripts' temporary parent).
inline const fs::path& ScratchDir() {
  static const fs::path dir = [] {
    const char* base = std::getenv("TMPDIR");
    fs::path d = fs::path(base != nullptr && *base != '\0' ? base : "/tmp") /
                 ("msm_fuzz_" + std::to_string(::getpid()));
    fs::create_directories(d);
    return d;
  }();
  return dir;
}

inline void WriteFile(const fs::path& path, const std::string& bytes) {
  fs::create_directories(path.parent_path());
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

inline std::string ReadFile(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

/// A small deterministic map: two sessions, three submaps of a few points, a pose graph with an
/// odometry and a loop edge, trajectories, one opaque file. Everything a loader reads.
inline core::MapContents TemplateContents() {
  core::MapContents map;
  for (const char* name : {"a", "b"}) {
    core::SessionRecord record;
    record.name = name;
    record.bag = std::string(name) + ".bag";
    record.scans = 2;
    record.duration_s = 0.1;
    record.merged_at = "2024-01-01T00:00:00Z";
    map.sessions.push_back(record);
  }
  const struct {
    const char* session;
    std::uint32_t id;
    double x;
  } kSubmaps[] = {{"a", 0, 0.0}, {"a", 1, 20.0}, {"b", 0, 5.0}};
  std::uint32_t node = 0;
  for (const auto& s : kSubmaps) {
    core::Submap submap;
    submap.session = s.session;
    submap.id = s.id;
    submap.T_map_submap = core::Pose3::Identity();
    submap.T_map_submap.translation() = Eigen::Vector3d(s.x, 1.0, 0.0);
    submap.length_m = 1.5;
    for (int i = 0; i < 2; ++i) {
      core::SubmapScanRecord scan;
      scan.stamp_s = 100.0 + s.x + 0.1 * i;
      scan.T_submap_sensor.translation() = Eigen::Vector3d(0.5 * i, 0.0, 0.0);
      submap.scans.push_back(scan);
    }
    for (int i = 0; i < 12; ++i) {
      submap.points.emplace_back(0.25 * i, 0.1 * (i % 3), 0.05 * i - s.x * 0.01);
    }
    map.graph.SetNodePose(node++, submap.T_map_submap);
    map.submaps.push_back(std::move(submap));
  }
  map.graph.SetFixed(0, true);
  core::PoseGraphEdge edge;
  edge.from = 0;
  edge.to = 1;
  edge.T_from_to.translation() = Eigen::Vector3d(20.0, 0.0, 0.0);
  map.graph.AddEdge(edge);
  edge.to = 2;
  edge.kind = core::EdgeKind::kInterLoop;
  edge.T_from_to.translation() = Eigen::Vector3d(5.0, 0.0, 0.0);
  map.graph.AddEdge(edge);
  for (const char* name : {"a", "b"}) {
    core::Trajectory trajectory;
    for (int i = 0; i < 3; ++i) {
      core::StampedPose pose;
      pose.stamp_s = 100.0 + i;
      pose.pose.translation() = Eigen::Vector3d(i, 0.0, 0.0);
      trajectory.push_back(pose);
    }
    map.trajectories[name] = trajectory;
    map.odom_trajectories[name] = trajectory;
  }
  map.parameters_yaml = "odometry:\n  map_voxel_size_m: 0.5\n";
  map.files["loops/b.csv"] = "kind,current,history,status\ninter,b/0,a/0,accepted\n";
  return map;
}

/// The template map, saved once per process; returns its folder.
inline const fs::path& TemplateDir() {
  static const fs::path dir = [] {
    const fs::path d = ScratchDir() / "template";
    fs::remove_all(d);
    const core::Status saved = core::MapStore().Save(TemplateContents(), d.string());
    if (!saved.ok()) {
      std::fprintf(stderr, "fuzz: cannot write the template map: %s\n", saved.message().c_str());
      std::abort();
    }
    return d;
  }();
  return dir;
}

/// A fresh copy of the template map at ScratchDir()/map.
inline fs::path FreshMapCopy() {
  const fs::path dst = ScratchDir() / "map";
  std::error_code ec;
  for (const char* suffix : {"", ".new", ".old"}) fs::remove_all(dst.string() + suffix, ec);
  fs::copy(TemplateDir(), dst, fs::copy_options::recursive);
  return dst;
}

/// Container of the whole-directory target: a sequence of `=== <relative path>\n<content>`
/// sections (a file's content runs up to the next line starting with "=== ").
inline std::vector<std::pair<std::string, std::string>> SplitContainer(const std::string& data) {
  std::vector<std::pair<std::string, std::string>> files;
  const std::string marker = "=== ";
  std::size_t pos = data.rfind(marker, 0) == 0 ? 0 : data.find("\n" + marker);
  if (pos == std::string::npos) return files;
  if (pos != 0) ++pos;
  while (pos != std::string::npos && pos < data.size()) {
    const std::size_t name_start = pos + marker.size();
    const std::size_t name_end = data.find('\n', name_start);
    if (name_end == std::string::npos) break;
    const std::size_t next = data.find("\n" + marker, name_end);
    const std::size_t content_end = next == std::string::npos ? data.size() : next + 1;
    files.emplace_back(data.substr(name_start, name_end - name_start),
                       data.substr(name_end + 1, content_end - name_end - 1));
    pos = next == std::string::npos ? std::string::npos : next + 1;
  }
  return files;
}

}  // namespace fuzz
}  // namespace multisession_mapper
