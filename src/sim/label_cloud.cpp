#include "multisession_mapper/sim/label_cloud.h"

#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>

#include "multisession_mapper/sim/counter_rng.h"

namespace multisession_mapper {
namespace sim {

LabelCloud::LabelCloud(double voxel_m) : voxel_m_(voxel_m > 0.0 ? voxel_m : 0.0) {}

void LabelCloud::Add(const TruthPoint& point) {
  if (voxel_m_ > 0.0) {
    // 21 bits per axis around the origin: +-104 km at 0.1 m.
    auto q = [&](float v) {
      return static_cast<std::uint64_t>(
                 static_cast<std::int64_t>(std::floor(v / voxel_m_)) + (1 << 20)) &
             0x1FFFFF;
    };
    const std::uint64_t key =
        q(point.position_m.x()) | (q(point.position_m.y()) << 21) | (q(point.position_m.z()) << 42);
    const auto found = InsertKey(key + 1, static_cast<std::uint32_t>(points_.size()));
    if (!found.second) {
      float& range = points_[found.first].range_m;
      if (point.range_m > 0.0f && (range <= 0.0f || point.range_m < range)) range = point.range_m;
      return;
    }
  }
  points_.push_back(point);
}

std::pair<std::uint32_t, bool> LabelCloud::InsertKey(std::uint64_t key,
                                                     std::uint32_t index_if_new) {
  if (2 * (table_used_ + 1) > table_.size()) {
    std::vector<std::uint64_t> old;
    std::vector<std::uint32_t> old_index;
    old.swap(table_);
    old_index.swap(table_index_);
    table_.assign(std::max<std::size_t>(1 << 16, old.size() * 2), 0);
    table_index_.assign(table_.size(), 0);
    table_used_ = 0;
    for (std::size_t i = 0; i < old.size(); ++i) {
      if (old[i] != 0) InsertKey(old[i], old_index[i]);
    }
  }
  const std::size_t mask = table_.size() - 1;
  for (std::size_t i = Mix64(key) & mask;; i = (i + 1) & mask) {
    if (table_[i] == key) return {table_index_[i], false};
    if (table_[i] == 0) {
      table_[i] = key;
      table_index_[i] = index_if_new;
      ++table_used_;
      return {index_if_new, true};
    }
  }
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
