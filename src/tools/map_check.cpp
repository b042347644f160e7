// map_check: loads a map directory with MapStore (finishing an interrupted save, verifying every
// file's size and checksum) and prints what it holds with two digests, for the crash-safety
// loop of scripts/stress.sh:
//   files_digest    FNV-1a 64 of manifest.yaml, which lists the size and checksum of every file:
//                   equal digests of two verified maps mean byte-identical maps.
//   content_digest  FNV-1a 64 of the map's content (sessions, submap origins, scan poses,
//                   points, pose graph, trajectories, parameters, further files) without what
//                   differs between two runs of the same input: the timing records and the
//                   merged_at stamps (of the manifest and of the change logs).
// Exit codes: 0 map loaded, 1 the directory holds a map that does not load (the message says
// why), 3 no map at the directory.
//   map_check DIR
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iomanip>
#include <iterator>
#include <sstream>
#include <string>

#include <yaml-cpp/yaml.h>

#include "multisession_mapper/core/checksum.h"
#include "multisession_mapper/core/map_store.h"
#include "multisession_mapper/core/trajectory_io.h"

namespace core = multisession_mapper::core;

namespace {

std::string Hex(std::uint64_t v) {
  std::ostringstream out;
  out << std::hex << std::setw(16) << std::setfill('0') << v;
  return out.str();
}

void AppendPose(std::ostringstream& out, const core::Pose3& pose) {
  out << std::setprecision(17);
  for (int i = 0; i < 12; ++i) out << pose.matrix()(i % 3, i / 3) << ' ';
  out << '\n';
}

// A change log (changes/<session>.yaml) without its merged_at line: the same merge gives the
// same log apart from that wall-clock stamp.
std::string ChangeLogDigest(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::string line, kept;
  while (std::getline(in, line)) {
    if (line.rfind("merged_at:", 0) != 0) kept += line + '\n';
  }
  return Hex(core::Fnv1a64(kept));
}

std::string ContentDigest(const std::string& dir, const core::MapContents& map,
                          const YAML::Node& manifest) {
  std::ostringstream out;
  out << std::setprecision(17);
  for (const core::SessionRecord& s : map.sessions) {
    out << "session " << s.name << ' ' << s.bag << ' ' << s.scans << ' ' << s.duration_s << '\n';
  }
  for (const core::Submap& m : map.submaps) {
    out << "submap " << m.session << ' ' << m.id << ' ' << core::SubmapStateName(m.state) << ' '
        << m.length_m << '\n';
    AppendPose(out, m.T_map_submap);
    for (const core::SubmapScanRecord& scan : m.scans) {
      out << scan.stamp_s << ' ';
      AppendPose(out, scan.T_submap_sensor);
    }
    for (const Eigen::Vector3d& p : m.points) {
      const float xyz[3] = {static_cast<float>(p.x()), static_cast<float>(p.y()),
                            static_cast<float>(p.z())};
      out.write(reinterpret_cast<const char*>(xyz), sizeof(xyz));
    }
  }
  map.graph.WriteG2o(out);
  for (const auto* group : {&map.trajectories, &map.odom_trajectories}) {
    for (const auto& [session, trajectory] : *group) {
      out << "trajectory " << session << '\n';
      core::WriteTum(out, trajectory);
    }
  }
  out << map.parameters_yaml << '\n';
  // Files the store carries opaquely (loops, place recognition, database): their verified
  // checksums from the manifest.
  const YAML::Node files = manifest["files"];
  for (auto it = files.begin(); files && it != files.end(); ++it) {
    const std::string rel = it->first.as<std::string>();
    if (rel.rfind("timing/", 0) == 0 || rel.rfind("submaps/", 0) == 0 ||
        rel.rfind("trajectories/", 0) == 0 || rel == "graph.g2o") {
      continue;  // timing differs between runs; the others are part of the content above
    }
    if (rel.rfind("changes/", 0) == 0) {  // verified by the load; hashed without merged_at
      out << "file " << rel << ' ' << ChangeLogDigest(dir + "/" + rel) << '\n';
      continue;
    }
    out << "file " << rel << ' ' << it->second["fnv1a64"].as<std::string>() << '\n';
  }
  return Hex(core::Fnv1a64(out.str()));
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2 || std::strcmp(argv[1], "-h") == 0 || std::strcmp(argv[1], "--help") == 0) {
    std::fprintf(argc == 2 ? stdout : stderr, "usage: map_check DIR\n");
    return argc == 2 ? 0 : 2;
  }
  const std::string dir = argv[1];
  if (!core::MapStore::Exists(dir)) {
    std::printf("map: none at %s\n", dir.c_str());
    return 3;
  }
  const core::StatusOr<core::MapContents> map = core::MapStore().Load(dir);
  if (!map.ok()) {
    std::fprintf(stderr, "map_check: %s\n", map.status().message().c_str());
    return 1;
  }
  std::ifstream manifest(dir + "/manifest.yaml", std::ios::binary);
  const std::string manifest_bytes((std::istreambuf_iterator<char>(manifest)),
                                   std::istreambuf_iterator<char>());
  std::string content;
  try {
    content = ContentDigest(dir, map.value(), YAML::Load(manifest_bytes));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "map_check: manifest: %s\n", e.what());
    return 1;
  }
  std::size_t points = 0;
  for (const core::Submap& m : map.value().submaps) points += m.points.size();
  std::string sessions;
  for (const core::SessionRecord& s : map.value().sessions) sessions += " " + s.name;
  std::printf("map: %s\nsessions:%s\nsubmaps: %zu\npoints: %zu\nfiles_digest: %s\n"
              "content_digest: %s\n",
              dir.c_str(), sessions.c_str(), map.value().submaps.size(), points,
              Hex(core::Fnv1a64(manifest_bytes)).c_str(), content.c_str());
  return 0;
}
