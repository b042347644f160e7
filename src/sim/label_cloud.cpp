#include "multisession_mapper/sim/label_cloud.h"

#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>

namespace multisession_mapper {
namespace sim {

LabelCloud::LabelCloud(double voxel_m) : voxel_m_(voxel_m > 0.0 ? voxel_m : 0.0) {}

void LabelCloud::Add(const TruthPoint& point) {
  if (voxel_m_ > 0.0) {
    const auto found =
        voxels_.FindOrInsert(core::ToVoxelKey(point.position_m.cast<double>(), voxel_m_),
                             static_cast<std::uint32_t>(points_.size()));
    if (!found.second) {
      float& range = points_[found.first].range_m;
      if (point.range_m > 0.0f && (range <= 0.0f || point.range_m < range)) range = point.range_m;
      return;
    }
  }
  points_.push_back(point);
}

void LabelCloud::Add(const std::vector<TruthPoint>& points) {
  for (const TruthPoint& p : points) Add(p);
}

core::Status LabelCloud::WritePcd(const std::string& path) const {
  std::ofstream out(path, std::ios::binary);
  if (!out) return core::Status::Error("cannot open '" + path + "' for writing");
  const std::size_t n = points_.size();
  out << "# .PCD v0.7 - Point Cloud Data file format\n"
      << "VERSION 0.7\n"
      << "FIELDS x y z label object_id range\n"
      << "SIZE 4 4 4 1 4 4\n"
      << "TYPE F F F U U F\n"
      << "COUNT 1 1 1 1 1 1\n"
      << "WIDTH " << n << "\n"
      << "HEIGHT 1\n"
      << "VIEWPOINT 0 0 0 1 0 0 0\n"
      << "POINTS " << n << "\n"
      << "DATA binary\n";
  std::vector<char> buffer(n * 21);
  for (std::size_t i = 0; i < n; ++i) {
    char* b = buffer.data() + i * 21;
    const TruthPoint& p = points_[i];
    std::memcpy(b, p.position_m.data(), 12);
    b[12] = static_cast<char>(static_cast<std::uint8_t>(p.label));
    std::memcpy(b + 13, &p.object_id, 4);
    std::memcpy(b + 17, &p.range_m, 4);
  }
  out.write(buffer.data(), static_cast<std::streamsize>(buffer.size()));
  out.close();
  if (!out) return core::Status::Error("write error on '" + path + "'");
  return core::Status::Ok();
}

core::StatusOr<std::vector<TruthPoint>> LabelCloud::ReadPcd(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return core::Status::Error("cannot open '" + path + "'");
  std::string line;
  std::size_t n = 0;
  std::string data;
  std::string fields;
  while (std::getline(in, line)) {
    if (line.rfind("FIELDS", 0) == 0) fields = line;
    if (line.rfind("POINTS", 0) == 0) n = std::stoul(line.substr(7));
    if (line.rfind("DATA", 0) == 0) {
      data = line.substr(5);
      break;
    }
  }
  const bool with_range = fields == "FIELDS x y z label object_id range";
  if (!with_range && fields != "FIELDS x y z label object_id") {
    return core::Status::Error(path + ": expected fields x y z label object_id [range]");
  }
  std::vector<TruthPoint> points(n);
  if (data == "binary") {
    const std::size_t stride = with_range ? 21 : 17;
    std::vector<char> buffer(n * stride);
    in.read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    if (!in) return core::Status::Error(path + ": truncated data");
    for (std::size_t i = 0; i < n; ++i) {
      const char* b = buffer.data() + i * stride;
      std::memcpy(points[i].position_m.data(), b, 12);
      points[i].label = static_cast<ObjectClass>(static_cast<std::uint8_t>(b[12]));
      std::memcpy(&points[i].object_id, b + 13, 4);
      if (with_range) std::memcpy(&points[i].range_m, b + 17, 4);
    }
  } else if (data == "ascii") {
    for (std::size_t i = 0; i < n; ++i) {
      unsigned label = 0;
      if (!(in >> points[i].position_m.x() >> points[i].position_m.y() >>
            points[i].position_m.z() >> label >> points[i].object_id) ||
          (with_range && !(in >> points[i].range_m))) {
        return core::Status::Error(path + ": truncated ascii data");
      }
      points[i].label = static_cast<ObjectClass>(label);
    }
  } else {
    return core::Status::Error(path + ": unsupported DATA '" + data + "'");
  }
  return points;
}

}  // namespace sim
}  // namespace multisession_mapper
