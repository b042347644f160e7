#include "multisession_mapper/sim/world_io.h"

#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>

#include <yaml-cpp/yaml.h>

namespace multisession_mapper {
namespace sim {
namespace {

// Fixed decimals with trailing zeros removed: compact and locale-independent.
std::string Num(double value, int decimals) {
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), "%.*f", decimals, value);
  std::string s(buffer);
  if (s.find('.') != std::string::npos) {
    while (!s.empty() && s.back() == '0') s.pop_back();
    if (!s.empty() && s.back() == '.') s.pop_back();
  }
  if (s == "-0") s = "0";
  return s;
}

std::string Vec(const Eigen::Vector3d& v, int decimals) {
  return "[" + Num(v.x(), decimals) + ", " + Num(v.y(), decimals) + ", " +
         Num(v.z(), decimals) + "]";
}

std::string SessionList(std::uint64_t mask, const std::vector<std::string>& names) {
  std::string s = "[";
  bool first = true;
  for (std::size_t i = 0; i < names.size(); ++i) {
    if (!(mask & (1ULL << i))) continue;
    if (!first) s += ", ";
    s += names[i];
    first = false;
  }
  return s + "]";
}

template <typename T>
core::StatusOr<T> Get(const YAML::Node& node, const char* key, const std::string& where) {
  const YAML::Node child = node[key];
  if (!child) return core::Status::Error(where + ": missing '" + key + "'");
  try {
    return child.as<T>();
  } catch (const YAML::Exception& e) {
    return core::Status::Error(where + ": bad '" + key + "': " + e.what());
  }
}

core::StatusOr<Eigen::Vector3d> GetVec3(const YAML::Node& node, const char* key,
                                        const std::string& where) {
  auto values = Get<std::vector<double>>(node, key, where);
  if (!values.ok()) return values.status();
  if (values.value().size() != 3) {
    return core::Status::Error(where + ": '" + key + "' needs 3 numbers");
  }
  return Eigen::Vector3d(values.value()[0], values.value()[1], values.value()[2]);
}

}  // namespace

core::Status WriteWorldYaml(std::ostream& out, const World& world) {
  core::Status status = world.Validate();
  if (!status.ok()) return status;
  out << "format: " << world.format << "\n";
  out << "profile: " << world.profile << "\n";
  out << "seed: " << world.seed << "\n";
  out << "sessions: " << SessionList(world.AllSessionsMask(), world.session_names) << "\n";
  const TerrainGrid& g = world.terrain;
  out << "terrain:\n";
  out << "  origin: [" << Num(g.origin_m.x(), 6) << ", " << Num(g.origin_m.y(), 6) << "]\n";
  out << "  resolution_m: " << Num(g.resolution_m, 6) << "\n";
  out << "  cols: " << g.cols << "\n";
  out << "  rows: " << g.rows << "\n";
  out << "  # vertex heights [m], one row per y index, x = origin.x + col * resolution_m;\n"
         "  # cells are split into triangles along the (col,row)-(col+1,row+1) diagonal\n";
  out << "  heights:\n";
  for (int r = 0; r < g.rows; ++r) {
    out << "    - [";
    for (int c = 0; c < g.cols; ++c) {
      if (c) out << ", ";
      out << Num(g.heights_m[r * g.cols + c], 3);
    }
    out << "]\n";
  }
  out << "  # cell materials, one string per cell row: 0 grass, 1 asphalt, 2 pavement\n";
  out << "  materials:\n";
  for (int r = 0; r + 1 < g.rows; ++r) {
    out << "    - \"";
    for (int c = 0; c + 1 < g.cols; ++c) {
      out << static_cast<char>('0' + g.materials[r * (g.cols - 1) + c]);
    }
    out << "\"\n";
  }
  out << "objects:\n";
  for (const WorldObject& o : world.objects) {
    out << "  - id: " << o.id << "\n";
    out << "    class: " << ObjectClassName(o.object_class) << "\n";
    if (!o.kind.empty()) out << "    kind: " << o.kind << "\n";
    out << "    shape: " << ShapeName(o.shape) << "\n";
    out << "    pose: [" << Num(o.position_m.x(), 6) << ", " << Num(o.position_m.y(), 6) << ", "
        << Num(o.position_m.z(), 6) << ", " << Num(o.yaw_rad, 9) << "]\n";
    if (o.roll_rad != 0.0 || o.pitch_rad != 0.0) {
      out << "    rpy: " << Vec(Eigen::Vector3d(o.roll_rad, o.pitch_rad, o.yaw_rad), 9) << "\n";
    }
    out << "    size: " << Vec(o.size_m, 6) << "\n";
    out << "    sessions: " << SessionList(o.sessions_mask, world.session_names) << "\n";
    if (!o.parts.empty()) {
      out << "    parts:\n";
      for (const ObjectPart& p : o.parts) {
        out << "      - {shape: " << ShapeName(p.shape) << ", center: " << Vec(p.center_m, 6)
            << ", rpy: " << Vec(p.rpy_rad, 9) << ", size: " << Vec(p.size_m, 6)
            << ", density: " << Num(p.density_per_m, 6)
            << ", reflectivity: " << Num(p.reflectivity, 6) << "}\n";
      }
    }
    if (!o.trajectory.empty()) {
      out << "    trajectory:\n";
      for (const TrajectoryRow& row : o.trajectory) {
        out << "      - [" << Num(row.stamp_s, 6) << ", " << Num(row.position_m.x(), 6) << ", "
            << Num(row.position_m.y(), 6) << ", " << Num(row.position_m.z(), 6) << ", "
            << Num(row.yaw_rad, 9) << "]\n";
      }
    }
  }
  if (!out) return core::Status::Error("world.yaml: write error");
  return core::Status::Ok();
}

core::Status WriteWorldYamlFile(const std::string& path, const World& world) {
  std::ofstream out(path, std::ios::binary);
  if (!out) return core::Status::Error("cannot open '" + path + "' for writing");
  core::Status status = WriteWorldYaml(out, world);
  if (!status.ok()) return status;
  out.close();
  if (!out) return core::Status::Error("write error on '" + path + "'");
  return core::Status::Ok();
}

core::StatusOr<World> ReadWorldYaml(const std::string& text) {
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    return core::Status::Error(std::string("world.yaml: parse error: ") + e.what());
  }
  World world;
  auto format = Get<std::string>(root, "format", "world.yaml");
  if (!format.ok()) return format.status();
  if (format.value() != world.format) {
    return core::Status::Error("world.yaml: unsupported format '" + format.value() + "'");
  }
  auto profile = Get<std::string>(root, "profile", "world.yaml");
  auto seed = Get<std::uint64_t>(root, "seed", "world.yaml");
  auto sessions = Get<std::vector<std::string>>(root, "sessions", "world.yaml");
  if (!profile.ok()) return profile.status();
  if (!seed.ok()) return seed.status();
  if (!sessions.ok()) return sessions.status();
  world.profile = profile.value();
  world.seed = seed.value();
  world.session_names = sessions.value();
  std::map<std::string, int> session_index;
  for (std::size_t i = 0; i < world.session_names.size(); ++i) {
    session_index[world.session_names[i]] = static_cast<int>(i);
  }

  const YAML::Node terrain = root["terrain"];
  if (!terrain) return core::Status::Error("world.yaml: missing 'terrain'");
  {
    auto origin = Get<std::vector<double>>(terrain, "origin", "terrain");
    auto res = Get<double>(terrain, "resolution_m", "terrain");
    auto cols = Get<int>(terrain, "cols", "terrain");
    auto rows = Get<int>(terrain, "rows", "terrain");
    if (!origin.ok()) return origin.status();
    if (!res.ok()) return res.status();
    if (!cols.ok()) return cols.status();
    if (!rows.ok()) return rows.status();
    if (origin.value().size() != 2) return core::Status::Error("terrain: origin needs 2 numbers");
    TerrainGrid& g = world.terrain;
    g.origin_m = Eigen::Vector2d(origin.value()[0], origin.value()[1]);
    g.resolution_m = res.value();
    g.cols = cols.value();
    g.rows = rows.value();
    const YAML::Node heights = terrain["heights"];
    const YAML::Node materials = terrain["materials"];
    if (!heights || !materials || !heights.IsSequence() || !materials.IsSequence()) {
      return core::Status::Error("terrain: missing 'heights' or 'materials'");
    }
    try {
      for (const YAML::Node& row : heights) {
        for (const YAML::Node& h : row) g.heights_m.push_back(h.as<float>());
      }
      for (const YAML::Node& row : materials) {
        for (char c : row.as<std::string>()) {
          if (c < '0' || c > '2') return core::Status::Error("terrain: bad material digit");
          g.materials.push_back(static_cast<std::uint8_t>(c - '0'));
        }
      }
    } catch (const YAML::Exception& e) {
      return core::Status::Error(std::string("terrain: ") + e.what());
    }
  }

  const YAML::Node objects = root["objects"];
  if (!objects || !objects.IsSequence()) {
    return core::Status::Error("world.yaml: missing 'objects' list");
  }
  for (const YAML::Node& node : objects) {
    WorldObject o;
    auto id = Get<std::uint32_t>(node, "id", "object");
    if (!id.ok()) return id.status();
    o.id = id.value();
    const std::string where = "object " + std::to_string(o.id);
    auto cls = Get<std::string>(node, "class", where);
    auto shape = Get<std::string>(node, "shape", where);
    auto pose = Get<std::vector<double>>(node, "pose", where);
    auto size = GetVec3(node, "size", where);
    auto obj_sessions = Get<std::vector<std::string>>(node, "sessions", where);
    if (!cls.ok()) return cls.status();
    if (!shape.ok()) return shape.status();
    if (!pose.ok()) return pose.status();
    if (!size.ok()) return size.status();
    if (!obj_sessions.ok()) return obj_sessions.status();
    auto parsed_class = ParseObjectClass(cls.value());
    auto parsed_shape = ParseShape(shape.value());
    if (!parsed_class.ok()) {
      return core::Status::Error(where + ": " + parsed_class.status().message());
    }
    if (!parsed_shape.ok()) {
      return core::Status::Error(where + ": " + parsed_shape.status().message());
    }
    o.object_class = parsed_class.value();
    o.shape = parsed_shape.value();
    if (pose.value().size() != 4) return core::Status::Error(where + ": pose needs [x, y, z, yaw]");
    o.position_m = Eigen::Vector3d(pose.value()[0], pose.value()[1], pose.value()[2]);
    o.yaw_rad = pose.value()[3];
    if (node["rpy"]) {
      auto rpy = GetVec3(node, "rpy", where);
      if (!rpy.ok()) return rpy.status();
      o.roll_rad = rpy.value().x();
      o.pitch_rad = rpy.value().y();
    }
    if (node["kind"]) o.kind = node["kind"].as<std::string>();
    o.size_m = size.value();
    o.sessions_mask = 0;
    for (const std::string& s : obj_sessions.value()) {
      auto it = session_index.find(s);
      if (it == session_index.end()) {
        return core::Status::Error(where + ": unknown session '" + s + "'");
      }
      o.sessions_mask |= 1ULL << it->second;
    }
    if (const YAML::Node parts = node["parts"]) {
      for (const YAML::Node& pn : parts) {
        ObjectPart part;
        auto ps = Get<std::string>(pn, "shape", where + " part");
        auto center = GetVec3(pn, "center", where + " part");
        auto rpy = GetVec3(pn, "rpy", where + " part");
        auto psize = GetVec3(pn, "size", where + " part");
        auto density = Get<double>(pn, "density", where + " part");
        auto refl = Get<double>(pn, "reflectivity", where + " part");
        if (!ps.ok()) return ps.status();
        if (!center.ok()) return center.status();
        if (!rpy.ok()) return rpy.status();
        if (!psize.ok()) return psize.status();
        if (!density.ok()) return density.status();
        if (!refl.ok()) return refl.status();
        auto part_shape = ParseShape(ps.value());
        if (!part_shape.ok()) {
          return core::Status::Error(where + ": " + part_shape.status().message());
        }
        part.shape = part_shape.value();
        part.center_m = center.value();
        part.rpy_rad = rpy.value();
        part.size_m = psize.value();
        part.density_per_m = density.value();
        part.reflectivity = refl.value();
        o.parts.push_back(part);
      }
    }
    if (const YAML::Node traj = node["trajectory"]) {
      try {
        for (const YAML::Node& rn : traj) {
          const std::vector<double> v = rn.as<std::vector<double>>();
          if (v.size() != 5) {
            return core::Status::Error(where + ": trajectory rows need [t, x, y, z, yaw]");
          }
          TrajectoryRow row;
          row.stamp_s = v[0];
          row.position_m = Eigen::Vector3d(v[1], v[2], v[3]);
          row.yaw_rad = v[4];
          o.trajectory.push_back(row);
        }
      } catch (const YAML::Exception& e) {
        return core::Status::Error(where + ": trajectory: " + e.what());
      }
    }
    world.objects.push_back(std::move(o));
  }
  core::Status status = world.Validate();
  if (!status.ok()) return status;
  return world;
}

core::StatusOr<World> ReadWorldYamlFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return core::Status::Error("cannot open '" + path + "'");
  std::stringstream buffer;
  buffer << in.rdbuf();
  return ReadWorldYaml(buffer.str());
}

}  // namespace sim
}  // namespace multisession_mapper
