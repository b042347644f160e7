#include "multisession_mapper/core/pcd_scan_io.h"

#include <cstdint>
#include <cstring>
#include <fstream>

#include <pcl/PCLPointCloud2.h>
#include <pcl/io/pcd_io.h>

namespace multisession_mapper {
namespace core {
namespace {

const pcl::PCLPointField* FindField(const pcl::PCLPointCloud2& cloud, const std::string& name) {
  for (const pcl::PCLPointField& f : cloud.fields) {
    if (f.name == name) return &f;
  }
  return nullptr;
}

// One numeric value of any PCL datatype as double.
double ReadValue(const std::uint8_t* data, std::uint8_t datatype) {
  switch (datatype) {
    case pcl::PCLPointField::INT8: { std::int8_t v; std::memcpy(&v, data, 1); return v; }
    case pcl::PCLPointField::UINT8: { std::uint8_t v; std::memcpy(&v, data, 1); return v; }
    case pcl::PCLPointField::INT16: { std::int16_t v; std::memcpy(&v, data, 2); return v; }
    case pcl::PCLPointField::UINT16: { std::uint16_t v; std::memcpy(&v, data, 2); return v; }
    case pcl::PCLPointField::INT32: { std::int32_t v; std::memcpy(&v, data, 4); return v; }
    case pcl::PCLPointField::UINT32: { std::uint32_t v; std::memcpy(&v, data, 4); return v; }
    case pcl::PCLPointField::FLOAT32: { float v; std::memcpy(&v, data, 4); return v; }
    case pcl::PCLPointField::FLOAT64: { double v; std::memcpy(&v, data, 8); return v; }
    default: return 0.0;
  }
}

}  // namespace

StatusOr<LidarScan> LoadPcdScan(const std::string& path) {
  if (!std::ifstream(path).good()) return Status::Error("pcd_scan_io: cannot open " + path);
  pcl::PCLPointCloud2 cloud;
  if (pcl::io::loadPCDFile(path, cloud) != 0) {
    return Status::Error("pcd_scan_io: PCL could not parse " + path);
  }
  const pcl::PCLPointField* fx = FindField(cloud, "x");
  const pcl::PCLPointField* fy = FindField(cloud, "y");
  const pcl::PCLPointField* fz = FindField(cloud, "z");
  if (fx == nullptr || fy == nullptr || fz == nullptr) {
    return Status::Error("pcd_scan_io: " + path + " has no x/y/z fields");
  }
  const pcl::PCLPointField* fi = FindField(cloud, "intensity");
  const pcl::PCLPointField* fr = FindField(cloud, "ring");
  const pcl::PCLPointField* ft = FindField(cloud, "time");
  const pcl::PCLPointField* ft_ns = ft == nullptr ? FindField(cloud, "t") : nullptr;

  LidarScan scan;
  scan.has_ring = fr != nullptr;
  scan.has_time = ft != nullptr || ft_ns != nullptr;
  const std::size_t n = static_cast<std::size_t>(cloud.width) * cloud.height;
  if (cloud.data.size() < n * cloud.point_step) {
    return Status::Error("pcd_scan_io: " + path + " is truncated");
  }
  scan.points.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint8_t* base = cloud.data.data() + i * cloud.point_step;
    LidarPoint& p = scan.points[i];
    p.position_m = Eigen::Vector3f(static_cast<float>(ReadValue(base + fx->offset, fx->datatype)),
                                   static_cast<float>(ReadValue(base + fy->offset, fy->datatype)),
                                   static_cast<float>(ReadValue(base + fz->offset, fz->datatype)));
    if (fi != nullptr) p.intensity = static_cast<float>(ReadValue(base + fi->offset, fi->datatype));
    if (fr != nullptr) {
      p.ring = static_cast<std::uint16_t>(ReadValue(base + fr->offset, fr->datatype));
    }
    if (ft != nullptr) {
      p.time_s = static_cast<float>(ReadValue(base + ft->offset, ft->datatype));
    } else if (ft_ns != nullptr) {
      p.time_s = static_cast<float>(ReadValue(base + ft_ns->offset, ft_ns->datatype) * 1e-9);
    }
  }
  return scan;
}

Status SavePcdScan(const std::string& path, const LidarScan& scan) {
  pcl::PCLPointCloud2 cloud;
  const auto add = [&cloud](const std::string& name, std::uint32_t offset, std::uint8_t type) {
    pcl::PCLPointField f;
    f.name = name;
    f.offset = offset;
    f.datatype = type;
    f.count = 1;
    cloud.fields.push_back(f);
  };
  add("x", 0, pcl::PCLPointField::FLOAT32);
  add("y", 4, pcl::PCLPointField::FLOAT32);
  add("z", 8, pcl::PCLPointField::FLOAT32);
  add("intensity", 12, pcl::PCLPointField::FLOAT32);
  add("ring", 16, pcl::PCLPointField::UINT16);
  add("time", 18, pcl::PCLPointField::FLOAT32);
  cloud.point_step = 22;
  cloud.width = static_cast<std::uint32_t>(scan.points.size());
  cloud.height = 1;
  cloud.row_step = cloud.point_step * cloud.width;
  cloud.is_dense = false;
  cloud.data.resize(static_cast<std::size_t>(cloud.row_step));
  for (std::size_t i = 0; i < scan.points.size(); ++i) {
    std::uint8_t* base = cloud.data.data() + i * cloud.point_step;
    const LidarPoint& p = scan.points[i];
    std::memcpy(base, p.position_m.data(), 12);
    std::memcpy(base + 12, &p.intensity, 4);
    std::memcpy(base + 16, &p.ring, 2);
    std::memcpy(base + 18, &p.time_s, 4);
  }
  pcl::PCDWriter writer;
  if (writer.writeBinary(path, cloud) != 0) {
    return Status::Error("pcd_scan_io: cannot write " + path);
  }
  return Status::Ok();
}

}  // namespace core
}  // namespace multisession_mapper
