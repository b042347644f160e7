#include "multisession_mapper/core/map_store.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <sstream>

#include <pcl/io/pcd_io.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <yaml-cpp/yaml.h>

#include "multisession_mapper/core/checksum.h"
#include "multisession_mapper/core/parallel_for.h"
#include "multisession_mapper/core/se3.h"
#include "multisession_mapper/core/trajectory_io.h"


// A submap point with the scans that measured it (Submap::views), as stored in the submap's
// PCD file (extra fields nearest_scan and last_scan; viewers show x, y, z as usual).
struct EIGEN_ALIGN16 MsmPointWithViews {
  PCL_ADD_POINT4D;
  std::uint32_t nearest_scan;
  std::uint32_t last_scan;
  PCL_MAKE_ALIGNED_OPERATOR_NEW
};
POINT_CLOUD_REGISTER_POINT_STRUCT(MsmPointWithViews,
                                  (float, x, x)(float, y, y)(float, z, z)
                                  (std::uint32_t, nearest_scan, nearest_scan)
                                  (std::uint32_t, last_scan, last_scan))

namespace multisession_mapper {
namespace core {
namespace fs = std::filesystem;

namespace {

constexpr const char* kManifest = "manifest.yaml";
constexpr const char* kGraph = "graph.g2o";
// Files larger than this are refused on load: a corrupt manifest must not make us allocate.
constexpr std::uintmax_t kMaxFileBytes = 4ull << 30;

std::string Hex(std::uint64_t v) {
  std::ostringstream out;
  out << std::hex << std::setw(16) << std::setfill('0') << v;
  return out.str();
}

StatusOr<std::string> ReadWholeFile(const fs::path& path) {
  std::error_code ec;
  const std::uintmax_t size = fs::file_size(path, ec);
  if (ec) return Status::Error("missing file '" + path.string() + "'");
  if (size > kMaxFileBytes) return Status::Error("file '" + path.string() + "' is too large");
  std::ifstream in(path, std::ios::binary);
  if (!in) return Status::Error("cannot open '" + path.string() + "'");
  std::string bytes(static_cast<std::size_t>(size), '\0');
  in.read(bytes.data(), static_cast<std::streamsize>(size));
  if (!in) return Status::Error("cannot read '" + path.string() + "'");
  return bytes;
}

// Size and FNV-1a checksum of a file as written (the manifest's record of it).
StatusOr<std::pair<std::uint64_t, std::uint64_t>> SizeAndChecksum(const fs::path& path) {
  StatusOr<std::string> bytes = ReadWholeFile(path);
  if (!bytes.ok()) return bytes.status();
  return std::make_pair(static_cast<std::uint64_t>(bytes.value().size()), Fnv1a64(bytes.value()));
}

Status FsyncPath(const fs::path& path, bool directory) {
  const int fd = ::open(path.c_str(), directory ? O_RDONLY | O_DIRECTORY : O_RDONLY);
  if (fd < 0) return Status::Error("cannot open '" + path.string() + "' to sync it");
  const int rc = ::fsync(fd);
  ::close(fd);
  if (rc != 0) return Status::Error("fsync failed for '" + path.string() + "'");
  return Status::Ok();
}

// Writes a file durably: content, flush, fsync.
Status WriteDurably(const fs::path& path, const std::string& bytes) {
  std::error_code ec;
  fs::create_directories(path.parent_path(), ec);
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    if (!out) return Status::Error("cannot create '" + path.string() + "'");
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    out.flush();
    if (!out) return Status::Error("error writing '" + path.string() + "' (disk full?)");
  }
  return FsyncPath(path, false);
}

YAML::Node PoseNode(const Pose3& pose) {
  const Eigen::Quaterniond q(pose.rotation());
  YAML::Node node;
  node.SetStyle(YAML::EmitterStyle::Flow);
  for (double v : {pose.translation().x(), pose.translation().y(), pose.translation().z(), q.x(),
                   q.y(), q.z(), q.w()}) {
    node.push_back(v);
  }
  return node;
}

StatusOr<Pose3> PoseFromNode(const YAML::Node& node, const std::string& what) {
  if (!node || !node.IsSequence() || node.size() != 7) {
    return Status::Error(what + ": a pose must be a list of 7 numbers");
  }
  double v[7];
  for (int i = 0; i < 7; ++i) {
    v[i] = node[i].as<double>();
    if (!std::isfinite(v[i])) return Status::Error(what + ": non-finite pose value");
  }
  const Eigen::Quaterniond q(v[6], v[3], v[4], v[5]);
  if (q.norm() < 1e-6) return Status::Error(what + ": zero quaternion");
  return se3::FromTranslationQuaternion(Eigen::Vector3d(v[0], v[1], v[2]), q);
}

std::string SubmapFile(const Submap& submap) {
  return "submaps/" + submap.session + "/" + std::to_string(submap.id) + ".pcd";
}

bool SafeName(const std::string& name) {
  if (name.empty() || name.size() > 200 || name == "." || name == "..") return false;
  for (char c : name) {
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.')) {
      return false;
    }
  }
  return true;
}

// A relative path inside the map: no absolute paths, no "..", no empty components.
bool SafeRelativePath(const std::string& path) {
  if (path.empty() || path.front() == '/') return false;
  std::stringstream parts(path);
  std::string part;
  while (std::getline(parts, part, '/')) {
    if (!SafeName(part)) return false;
  }
  return true;
}

Status WritePcd(const fs::path& path, const PointVector& points,
                const std::vector<PointViews>* views = nullptr) {
  std::error_code ec;
  fs::create_directories(path.parent_path(), ec);
  if (points.empty()) {
    // PCL refuses to write empty clouds; an empty ASCII PCD is still a valid PCD.
    return WriteDurably(path,
                        "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\n"
                        "COUNT 1 1 1\nWIDTH 0\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 0\n"
                        "DATA ascii\n");
  }
  int written = 0;
  if (views != nullptr && views->size() == points.size()) {
    pcl::PointCloud<MsmPointWithViews> cloud;
    cloud.resize(points.size());
    for (std::size_t i = 0; i < points.size(); ++i) {
      cloud[i].x = static_cast<float>(points[i].x());
      cloud[i].y = static_cast<float>(points[i].y());
      cloud[i].z = static_cast<float>(points[i].z());
      cloud[i].nearest_scan = (*views)[i].nearest_scan;
      cloud[i].last_scan = (*views)[i].last_scan;
    }
    written = pcl::io::savePCDFileBinaryCompressed(path.string(), cloud);
  } else {
    pcl::PointCloud<pcl::PointXYZ> cloud;
    cloud.reserve(points.size());
    for (const Eigen::Vector3d& p : points) {
      cloud.push_back(pcl::PointXYZ(static_cast<float>(p.x()), static_cast<float>(p.y()),
                                    static_cast<float>(p.z())));
    }
    written = pcl::io::savePCDFileBinaryCompressed(path.string(), cloud);
  }
  if (written != 0) return Status::Error("cannot write '" + path.string() + "'");
  return FsyncPath(path, false);
}

// Checks a PCD file's header against the PCD v0.7 format and the file's length before PCL's
// reader sees it. PCL's PCDReader trusts the header: fuzzing the map loader
// (test/fuzz/fuzz_submap_pcd) crashed it with an empty file (null dereference in
// PCDReader::read, test map_store_fuzz_regression_test). We keep PCL for the parsing (ascii,
// binary, LZF-compressed binary) and refuse here whatever it would have to trust: a missing or
// inconsistent header, sizes that do not add up, data shorter than the header promises.
Status ValidatePcd(const std::string& bytes, const std::string& name, std::uint64_t* num_points,
                   std::vector<std::string>* fields_out = nullptr) {
  const auto error = [&](const std::string& what) {
    return Status::Error("corrupt point cloud '" + name + "': " + what);
  };
  constexpr std::size_t kMaxHeaderBytes = 1 << 16;
  constexpr std::uint64_t kMaxPoints = 1ull << 31;
  std::vector<std::string> fields, sizes, types, counts;
  std::uint64_t width = 0, height = 0, points = 0;
  bool has_width = false, has_height = false, has_points = false;
  std::string data_kind;
  std::size_t pos = 0;
  const auto parse_count = [](const std::string& text, std::uint64_t* out) {
    if (text.empty() || text.size() > 12) return false;
    for (char c : text) {
      if (c < '0' || c > '9') return false;
    }
    *out = std::stoull(text);
    return true;
  };
  while (data_kind.empty()) {
    if (pos >= bytes.size() || pos > kMaxHeaderBytes) return error("no DATA line in the header");
    std::size_t end = bytes.find('\n', pos);
    if (end == std::string::npos) end = bytes.size();
    std::istringstream line(bytes.substr(pos, end - pos));
    pos = end + 1;
    std::string key;
    if (!(line >> key) || key[0] == '#') continue;
    std::vector<std::string> values;
    for (std::string v; line >> v;) values.push_back(v);
    if (key == "FIELDS") {
      fields = values;
    } else if (key == "SIZE") {
      sizes = values;
    } else if (key == "TYPE") {
      types = values;
    } else if (key == "COUNT") {
      counts = values;
    } else if (key == "WIDTH") {
      has_width = values.size() == 1 && parse_count(values[0], &width);
      if (!has_width) return error("bad WIDTH");
    } else if (key == "HEIGHT") {
      has_height = values.size() == 1 && parse_count(values[0], &height);
      if (!has_height) return error("bad HEIGHT");
    } else if (key == "POINTS") {
      has_points = values.size() == 1 && parse_count(values[0], &points);
      if (!has_points) return error("bad POINTS");
    } else if (key == "DATA") {
      if (values.size() != 1) return error("bad DATA line");
      data_kind = values[0];
    } else if (key != "VERSION" && key != "VIEWPOINT") {
      return error("unknown header line '" + key + "'");
    }
  }
  if (fields.empty() || fields.size() > 64) return error("FIELDS must list 1 to 64 fields");
  if (counts.empty()) counts.assign(fields.size(), "1");
  if (sizes.size() != fields.size() || types.size() != fields.size() ||
      counts.size() != fields.size()) {
    return error("FIELDS, SIZE, TYPE and COUNT differ in length");
  }
  std::uint64_t point_bytes = 0;
  std::uint64_t point_values = 0;
  int xyz = 0;
  for (std::size_t i = 0; i < fields.size(); ++i) {
    std::uint64_t size = 0, count = 0;
    if (!parse_count(sizes[i], &size) || !(size == 1 || size == 2 || size == 4 || size == 8)) {
      return error("field '" + fields[i] + "' has SIZE '" + sizes[i] + "'");
    }
    if (!(types[i] == "F" || types[i] == "I" || types[i] == "U") ||
        (types[i] == "F" && size != 4 && size != 8)) {
      return error("field '" + fields[i] + "' has TYPE '" + types[i] + "'");
    }
    if (!parse_count(counts[i], &count) || count < 1 || count > 4096) {
      return error("field '" + fields[i] + "' has COUNT '" + counts[i] + "'");
    }
    if (fields[i] == "x" || fields[i] == "y" || fields[i] == "z") {
      if (types[i] != "F" || count != 1) return error("field '" + fields[i] + "' must be one float");
      ++xyz;
    }
    point_bytes += size * count;
    point_values += count;
  }
  if (xyz != 3) return error("needs the fields x, y and z once each");
  if (fields_out != nullptr) *fields_out = fields;
  if (!has_width || !has_height || !has_points) return error("WIDTH, HEIGHT or POINTS missing");
  if (width > kMaxPoints || height > kMaxPoints || width * height != points || points > kMaxPoints) {
    return error("POINTS is not WIDTH x HEIGHT");
  }
  *num_points = points;
  const std::uint64_t body = pos <= bytes.size() ? bytes.size() - pos : 0;
  if (data_kind == "ascii") {
    // Every value takes at least one character and a separator.
    if (points * point_values * 2 > body + 1) return error("fewer data than POINTS");
  } else if (data_kind == "binary") {
    if (points * point_bytes > body) return error("binary data shorter than POINTS");
  } else if (data_kind == "binary_compressed") {
    if (points == 0) return Status::Ok();
    std::uint32_t compressed = 0, uncompressed = 0;
    if (body < 8) return error("compressed data has no size header");
    std::memcpy(&compressed, bytes.data() + pos, 4);
    std::memcpy(&uncompressed, bytes.data() + pos + 4, 4);
    if (compressed == 0 || compressed > body - 8) return error("compressed size exceeds the file");
    if (uncompressed != points * point_bytes) {
      return error("uncompressed size does not match POINTS");
    }
  } else {
    return error("unknown DATA '" + data_kind + "'");
  }
  return Status::Ok();
}

// Reads a point cloud; with `views`, also the submap's per-point views when the file has
// them (fields nearest_scan and last_scan), else `views` is left empty.
StatusOr<PointVector> ReadPcd(const fs::path& path, std::vector<PointViews>* views = nullptr) {
  StatusOr<std::string> bytes = ReadWholeFile(path);
  if (!bytes.ok()) return bytes.status();
  std::uint64_t num_points = 0;
  std::vector<std::string> fields;
  Status valid = ValidatePcd(bytes.value(), path.string(), &num_points, &fields);
  if (!valid.ok()) return valid;
  if (views != nullptr) views->clear();
  // Fused submaps and empty change clouds have no points; PCL's reader would print a warning
  // ("No points to read") for each of them.
  if (num_points == 0) return PointVector();
  const auto has = [&](const char* name) {
    return std::find(fields.begin(), fields.end(), name) != fields.end();
  };
  PointVector points;
  const auto add = [&](const auto& p) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) return false;
    points.emplace_back(p.x, p.y, p.z);
    return true;
  };
  const Status non_finite =
      Status::Error("point cloud '" + path.string() + "' has non-finite points");
  pcl::PCDReader reader;
  if (views != nullptr && has("nearest_scan") && has("last_scan")) {
    pcl::PointCloud<MsmPointWithViews> cloud;
    if (reader.read(path.string(), cloud) < 0) {
      return Status::Error("corrupt or unreadable point cloud '" + path.string() + "'");
    }
    points.reserve(cloud.size());
    views->reserve(cloud.size());
    for (const auto& p : cloud) {
      if (!add(p)) return non_finite;
      PointViews v;
      v.nearest_scan = p.nearest_scan;
      v.last_scan = p.last_scan;
      views->push_back(v);
    }
    return points;
  }
  pcl::PointCloud<pcl::PointXYZ> cloud;
  if (reader.read(path.string(), cloud) < 0) {
    return Status::Error("corrupt or unreadable point cloud '" + path.string() + "'");
  }
  points.reserve(cloud.size());
  for (const auto& p : cloud) {
    if (!add(p)) return non_finite;
  }
  return points;
}

fs::path Sibling(const std::string& dir, const char* suffix) {
  fs::path p = fs::path(dir).lexically_normal();
  if (p.filename().empty()) p = p.parent_path();
  return fs::path(p.string() + suffix);
}

}  // namespace

std::string SubmapKey(const std::string& session, std::uint32_t id) {
  return session + "/" + std::to_string(id);
}

Status MapStore::Recover(const std::string& dir) {
  std::error_code ec;
  const fs::path current = Sibling(dir, "");
  const fs::path fresh = Sibling(dir, ".new");
  const fs::path old = Sibling(dir, ".old");
  const bool has_current = fs::exists(current / kManifest, ec);
  if (!has_current && fs::exists(fresh / kManifest, ec) && fs::exists(old, ec)) {
    // Interrupted between the two renames: the new map is complete (it was synced first).
    if (fs::exists(current, ec)) fs::remove_all(current, ec);
    fs::rename(fresh, current, ec);
    if (ec) return Status::Error("cannot finish interrupted save of '" + dir + "': " + ec.message());
  } else if (!has_current && fs::exists(old / kManifest, ec)) {
    if (fs::exists(current, ec)) fs::remove_all(current, ec);
    fs::rename(old, current, ec);
    if (ec) return Status::Error("cannot restore '" + old.string() + "': " + ec.message());
  }
  // Left-overs of a save that did not reach the swap, or of one that did not clean up.
  if (fs::exists(fresh, ec)) fs::remove_all(fresh, ec);
  if (fs::exists(current / kManifest, ec) && fs::exists(old, ec)) fs::remove_all(old, ec);
  return Status::Ok();
}

bool MapStore::Exists(const std::string& dir) {
  if (!Recover(dir).ok()) return false;
  std::error_code ec;
  return fs::exists(Sibling(dir, "") / kManifest, ec);
}

Status MapStore::Save(const MapContents& contents, const std::string& dir) const {
  const Status valid = config_.Validate();
  if (!valid.ok()) return valid;
  Status recovered = Recover(dir);
  if (!recovered.ok()) return recovered;
  const fs::path current = Sibling(dir, "");
  const fs::path fresh = Sibling(dir, ".new");
  const fs::path old = Sibling(dir, ".old");
  std::error_code ec;
  fs::create_directories(fresh, ec);
  if (ec) return Status::Error("cannot create '" + fresh.string() + "': " + ec.message());

  std::atomic<int> files_written{0};  // counted from the submap writers' threads too
  auto crash_hook = [&]() {
    const int written_now = ++files_written;
    return config_.test_abort_after_files >= 0 && written_now >= config_.test_abort_after_files;
  };
  const Status kAborted = Status::Error("save aborted by the test hook (simulated crash)");
  std::vector<std::string> written;  // relative paths, for the manifest's file list
  // Size and checksum of files written from memory; the others (PCL's PCDs, hard links) are
  // read back once for the manifest.
  std::map<std::string, std::pair<std::uint64_t, std::uint64_t>> known_sums;

  auto put = [&](const std::string& rel, const std::string& bytes) -> Status {
    if (!SafeRelativePath(rel)) return Status::Error("refusing unsafe map file name '" + rel + "'");
    Status s = WriteDurably(fresh / rel, bytes);
    if (s.ok()) {
      written.push_back(rel);
      known_sums[rel] = {bytes.size(), Fnv1a64(bytes)};
    }
    return s;
  };

  // Pose graph.
  {
    std::ostringstream g2o;
    Status s = contents.graph.WriteG2o(g2o);
    if (s.ok()) s = put(kGraph, g2o.str());
    if (!s.ok()) return s;
    if (crash_hook()) return kAborted;
  }
  // Trajectories.
  for (const auto* group : {&contents.trajectories, &contents.odom_trajectories}) {
    const bool odom = group == &contents.odom_trajectories;
    for (const auto& [session, trajectory] : *group) {
      if (!SafeName(session)) return Status::Error("invalid session name '" + session + "'");
      std::ostringstream tum;
      Status s = WriteTum(tum, trajectory);
      if (s.ok()) s = put("trajectories/" + session + (odom ? "_odom" : "") + ".tum", tum.str());
      if (!s.ok()) return s;
      if (crash_hook()) return kAborted;
    }
  }
  // Submaps: unchanged ones are hard-linked from the current map, the others are written on
  // write_threads threads, each file read back for its checksum by the thread that wrote it.
  std::vector<std::string> submap_files;  // relative paths, by submap
  std::vector<std::size_t> to_write;       // indices into contents.submaps
  submap_files.reserve(contents.submaps.size());  // `rel` below stays valid
  for (std::size_t k = 0; k < contents.submaps.size(); ++k) {
    const Submap& submap = contents.submaps[k];
    if (!SafeName(submap.session)) return Status::Error("invalid session name '" + submap.session + "'");
    const std::string& rel = submap_files.emplace_back(SubmapFile(submap));
    const fs::path target = fresh / rel;
    fs::create_directories(target.parent_path(), ec);
    bool linked = false;
    if (contents.clean_submaps.count(SubmapKey(submap.session, submap.id)) &&
        fs::exists(current / rel, ec)) {
      fs::create_hard_link(current / rel, target, ec);
      linked = !ec;
      if (!linked) {
        fs::copy_file(current / rel, target, fs::copy_options::overwrite_existing, ec);
        linked = !ec;
      }
    }
    if (!linked) {
      to_write.push_back(k);
    } else if (crash_hook()) {
      return kAborted;
    }
  }
  {
    std::vector<Status> statuses(to_write.size());  // Ok for files skipped after a stop
    std::vector<std::pair<std::uint64_t, std::uint64_t>> sums(to_write.size());
    std::atomic<bool> stop{false};  // a write failed or the crash hook fired: start no more
    std::atomic<bool> hook_fired{false};
    ParallelFor(to_write.size(), config_.write_threads, [&](std::size_t j) {
      if (stop) return;
      const Submap& submap = contents.submaps[to_write[j]];
      const fs::path target = fresh / submap_files[to_write[j]];
      statuses[j] = WritePcd(target, submap.points, &submap.views);
      if (statuses[j].ok()) {
        StatusOr<std::pair<std::uint64_t, std::uint64_t>> sum = SizeAndChecksum(target);
        if (sum.ok()) {
          sums[j] = sum.value();
        } else {
          statuses[j] = sum.status();
        }
      }
      if (!statuses[j].ok()) {
        stop = true;
      } else if (crash_hook()) {
        hook_fired = true;
        stop = true;
      }
    });
    for (const Status& s : statuses) {
      if (!s.ok()) return s;  // a real error comes first, even when the hook fired too
    }
    if (hook_fired) return kAborted;
    for (std::size_t j = 0; j < to_write.size(); ++j) {
      known_sums[submap_files[to_write[j]]] = sums[j];
    }
  }
  written.insert(written.end(), submap_files.begin(), submap_files.end());
  // Files of other modules: new contents, or carried over from the current map.
  for (const auto& [rel, bytes] : contents.files) {
    Status s = put(rel, bytes);
    if (!s.ok()) return s;
    if (crash_hook()) return kAborted;
  }
  for (const auto& [rel, points] : contents.clouds) {
    if (!SafeRelativePath(rel)) return Status::Error("invalid cloud file name '" + rel + "'");
    Status s = WritePcd(fresh / rel, points);
    if (!s.ok()) return s;
    written.push_back(rel);
    if (crash_hook()) return kAborted;
  }
  if (fs::exists(current / kManifest, ec)) {
    StatusOr<std::string> old_manifest = ReadWholeFile(current / kManifest);
    if (old_manifest.ok()) {
      try {
        const YAML::Node files = YAML::Load(old_manifest.value())["files"];
        for (auto it = files.begin(); files && it != files.end(); ++it) {
          const std::string rel = it->first.as<std::string>();
          if (!SafeRelativePath(rel) || fs::exists(fresh / rel, ec)) continue;
          if (contents.retired_files.count(rel)) continue;  // past its retention: dropped
          if (rel == kGraph || rel.rfind("submaps/", 0) == 0 || rel.rfind("trajectories/", 0) == 0) {
            continue;  // managed above: absent now means removed
          }
          fs::create_directories((fresh / rel).parent_path(), ec);
          fs::create_hard_link(current / rel, fresh / rel, ec);
          if (ec) fs::copy_file(current / rel, fresh / rel, ec);
          if (!ec) written.push_back(rel);
        }
      } catch (const std::exception&) {
        // The current map's manifest is unreadable: nothing to carry over.
      }
    }
  }

  // Manifest last: it lists every file with size and checksum.
  YAML::Emitter out;
  out.SetDoublePrecision(15);
  out << YAML::BeginMap;
  out << YAML::Key << "format_version" << YAML::Value << kMapFormatVersion;
  out << YAML::Key << "map_frame" << YAML::Value << "map";
  out << YAML::Key << "sessions" << YAML::Value << YAML::BeginSeq;
  for (const SessionRecord& s : contents.sessions) {
    out << YAML::BeginMap << YAML::Key << "name" << YAML::Value << s.name << YAML::Key << "bag"
        << YAML::Value << s.bag << YAML::Key << "scans" << YAML::Value << s.scans << YAML::Key
        << "duration_s" << YAML::Value << s.duration_s << YAML::Key << "merged_at" << YAML::Value
        << s.merged_at << YAML::EndMap;
  }
  out << YAML::EndSeq;
  out << YAML::Key << "submaps" << YAML::Value << YAML::BeginSeq;
  for (const Submap& m : contents.submaps) {
    YAML::Node stamps, poses;
    stamps.SetStyle(YAML::EmitterStyle::Flow);
    for (const SubmapScanRecord& scan : m.scans) {
      stamps.push_back(scan.stamp_s);
      poses.push_back(PoseNode(scan.T_submap_sensor));
    }
    out << YAML::BeginMap << YAML::Key << "session" << YAML::Value << m.session << YAML::Key
        << "id" << YAML::Value << m.id << YAML::Key << "origin" << YAML::Value
        << PoseNode(m.T_map_submap) << YAML::Key << "first_stamp" << YAML::Value
        << m.first_stamp_s() << YAML::Key << "last_stamp" << YAML::Value << m.last_stamp_s()
        << YAML::Key << "length_m" << YAML::Value << m.length_m << YAML::Key << "points"
        << YAML::Value << m.points.size() << YAML::Key << "file" << YAML::Value << SubmapFile(m)
        << YAML::Key << "status" << YAML::Value << SubmapStateName(m.state) << YAML::Key
        << "scan_stamps" << YAML::Value << stamps << YAML::Key << "scan_poses" << YAML::Value
        << poses << YAML::EndMap;
  }
  out << YAML::EndSeq;
  out << YAML::Key << "files" << YAML::Value << YAML::BeginMap;
  for (const std::string& rel : written) {
    auto sum = known_sums.find(rel);
    if (sum == known_sums.end()) {
      StatusOr<std::pair<std::uint64_t, std::uint64_t>> read = SizeAndChecksum(fresh / rel);
      if (!read.ok()) return read.status();
      sum = known_sums.emplace(rel, read.value()).first;
    }
    out << YAML::Key << rel << YAML::Value << YAML::Flow << YAML::BeginMap << YAML::Key << "bytes"
        << YAML::Value << sum->second.first << YAML::Key << "fnv1a64" << YAML::Value
        << Hex(sum->second.second) << YAML::EndMap;
  }
  out << YAML::EndMap;
  out << YAML::EndMap;
  std::string manifest = std::string("# multisession_mapper map, see docs/map_format.md\n") +
                         out.c_str() + "\n";
  if (!contents.parameters_yaml.empty()) {
    // Parameters are appended as their own mapping so that any YAML config is kept verbatim.
    try {
      YAML::Node params = YAML::Load(contents.parameters_yaml);
      YAML::Emitter p;
      p << YAML::BeginMap << YAML::Key << "parameters" << YAML::Value << params << YAML::EndMap;
      manifest += std::string(p.c_str()) + "\n";
    } catch (const std::exception& e) {
      return Status::Error(std::string("parameters are not valid YAML: ") + e.what());
    }
  }
  if (crash_hook()) return kAborted;
  Status s = WriteDurably(fresh / kManifest, manifest);
  if (!s.ok()) return s;
  for (const auto& entry : fs::recursive_directory_iterator(fresh, ec)) {
    if (entry.is_directory()) FsyncPath(entry.path(), true);
  }
  s = FsyncPath(fresh, true);
  if (!s.ok()) return s;

  // The swap.
  if (fs::exists(current, ec)) {
    fs::rename(current, old, ec);
    if (ec) return Status::Error("cannot move the old map aside: " + ec.message());
  }
  if (crash_hook()) return kAborted;
  fs::rename(fresh, current, ec);
  if (ec) return Status::Error("cannot move the new map in place: " + ec.message());
  FsyncPath(current.parent_path().empty() ? fs::path(".") : current.parent_path(), true);
  fs::remove_all(old, ec);
  return Status::Ok();
}

StatusOr<MapContents> MapStore::Load(const std::string& dir) const {
  Status recovered = Recover(dir);
  if (!recovered.ok()) return recovered;
  const fs::path root = Sibling(dir, "");
  StatusOr<std::string> manifest_text = ReadWholeFile(root / kManifest);
  if (!manifest_text.ok()) {
    return Status::Error("no map at '" + dir + "': " + manifest_text.status().message());
  }
  const std::string manifest_path = (root / kManifest).string();
  MapContents contents;
  try {
    const YAML::Node manifest = YAML::Load(manifest_text.value());
    if (!manifest.IsMap()) return Status::Error(manifest_path + ": not a YAML mapping");
    if (!manifest["format_version"]) {
      return Status::Error(manifest_path + ": no format_version");
    }
    const int version = manifest["format_version"].as<int>();
    if (version != kMapFormatVersion) {
      return Status::Error(manifest_path + ": format_version " + std::to_string(version) +
                           " is not supported (this build reads version " +
                           std::to_string(kMapFormatVersion) + ")");
    }
    // Every listed file: present, of the recorded size and checksum.
    const YAML::Node files = manifest["files"];
    if (!files || !files.IsMap()) return Status::Error(manifest_path + ": no file list");
    for (auto it = files.begin(); it != files.end(); ++it) {
      const std::string rel = it->first.as<std::string>();
      if (!SafeRelativePath(rel)) {
        return Status::Error(manifest_path + ": unsafe file name '" + rel + "'");
      }
      const std::uint64_t bytes = it->second["bytes"].as<std::uint64_t>();
      std::error_code ec;
      const std::uintmax_t size = fs::file_size(root / rel, ec);
      if (ec) return Status::Error("map file missing: '" + (root / rel).string() + "'");
      if (size != bytes) {
        return Status::Error("map file '" + (root / rel).string() + "' has " +
                             std::to_string(size) + " bytes, the manifest says " +
                             std::to_string(bytes) + " (truncated or modified)");
      }
      if (config_.verify_checksums) {
        StatusOr<std::string> data = ReadWholeFile(root / rel);
        if (!data.ok()) return data.status();
        if (Hex(Fnv1a64(data.value())) != it->second["fnv1a64"].as<std::string>()) {
          return Status::Error("map file '" + (root / rel).string() +
                               "' is corrupt (checksum mismatch)");
        }
      }
    }
    auto listed = [&](const std::string& rel) { return static_cast<bool>(files[rel]); };

    for (const YAML::Node& s : manifest["sessions"]) {
      SessionRecord record;
      record.name = s["name"].as<std::string>();
      if (!SafeName(record.name)) {
        return Status::Error(manifest_path + ": invalid session name '" + record.name + "'");
      }
      record.bag = s["bag"] ? s["bag"].as<std::string>() : "";
      record.scans = s["scans"].as<std::uint32_t>();
      record.duration_s = s["duration_s"].as<double>();
      record.merged_at = s["merged_at"] ? s["merged_at"].as<std::string>() : "";
      contents.sessions.push_back(record);
      for (bool odom : {false, true}) {
        const std::string rel = "trajectories/" + record.name + (odom ? "_odom" : "") + ".tum";
        if (!listed(rel)) continue;
        StatusOr<Trajectory> t = ReadTumFile((root / rel).string());
        if (!t.ok()) return t.status();
        (odom ? contents.odom_trajectories : contents.trajectories)[record.name] = t.value();
      }
    }
    for (const YAML::Node& m : manifest["submaps"]) {
      Submap submap;
      submap.session = m["session"].as<std::string>();
      submap.id = m["id"].as<std::uint32_t>();
      const std::string what =
          manifest_path + ": submap " + SubmapKey(submap.session, submap.id);
      if (!SafeName(submap.session)) return Status::Error(what + ": invalid session name");
      StatusOr<Pose3> origin = PoseFromNode(m["origin"], what);
      if (!origin.ok()) return origin.status();
      submap.T_map_submap = origin.value();
      submap.length_m = m["length_m"] ? m["length_m"].as<double>() : 0.0;
      const std::string state = m["status"] ? m["status"].as<std::string>() : "active";
      if (state == "active") {
        submap.state = SubmapState::kActive;
      } else if (state == "fused") {
        submap.state = SubmapState::kFused;
      } else {
        return Status::Error(what + ": unknown status '" + state + "'");
      }
      const YAML::Node stamps = m["scan_stamps"];
      const YAML::Node poses = m["scan_poses"];
      if (!stamps || !poses || !stamps.IsSequence() || !poses.IsSequence() ||
          stamps.size() != poses.size()) {
        return Status::Error(what + ": scan_stamps and scan_poses must be lists of equal length");
      }
      for (std::size_t i = 0; i < stamps.size(); ++i) {
        SubmapScanRecord scan;
        scan.stamp_s = stamps[i].as<double>();
        StatusOr<Pose3> pose = PoseFromNode(poses[i], what);
        if (!pose.ok()) return pose.status();
        scan.T_submap_sensor = pose.value();
        submap.scans.push_back(scan);
      }
      const std::string rel = SubmapFile(submap);
      if (!listed(rel)) return Status::Error(what + ": its file '" + rel + "' is not listed");
      StatusOr<PointVector> points = ReadPcd(root / rel, &submap.views);
      if (!points.ok()) return points.status();
      submap.points = std::move(points.value());
      for (const PointViews& v : submap.views) {
        for (std::uint32_t scan : {v.nearest_scan, v.last_scan}) {
          if (scan != PointViews::kUnknownScan && scan >= submap.scans.size()) {
            return Status::Error("corrupt point cloud '" + (root / rel).string() +
                                 "': a point's scan index " + std::to_string(scan) +
                                 " exceeds the submap's " + std::to_string(submap.scans.size()) +
                                 " scans");
          }
        }
      }
      contents.clean_submaps.insert(SubmapKey(submap.session, submap.id));
      contents.submaps.push_back(std::move(submap));
    }
    if (manifest["parameters"]) {
      YAML::Emitter p;
      p << manifest["parameters"];
      contents.parameters_yaml = p.c_str();
    }
  } catch (const std::exception& e) {
    return Status::Error(manifest_path + ": malformed manifest (" + e.what() + ")");
  }
  std::ifstream graph_in(root / kGraph);
  if (!graph_in) return Status::Error("map file missing: '" + (root / kGraph).string() + "'");
  StatusOr<PoseGraph> graph = PoseGraph::ReadG2o(graph_in, (root / kGraph).string());
  if (!graph.ok()) return graph.status();
  contents.graph = std::move(graph.value());
  return contents;
}

}  // namespace core
}  // namespace multisession_mapper
