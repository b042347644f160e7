#include "multisession_mapper/nodelets/nodelet_common.h"

#include <cmath>
#include <ctime>
#include <vector>

#include <ros/console.h>

#ifdef __GLIBC__
#include <malloc.h>
#endif

namespace multisession_mapper {
namespace nodelets {

std::string SearchString(const ros::NodeHandle& pnh, const std::string& name,
                         const std::string& fallback) {
  std::string key;
  std::string value = fallback;
  if (pnh.searchParam(name, key)) pnh.getParam(key, value);
  return value;
}

double SearchDouble(const ros::NodeHandle& pnh, const std::string& name, double fallback) {
  std::string key;
  double value = fallback;
  if (pnh.searchParam(name, key)) pnh.getParam(key, value);
  return value;
}

bool LoadConfigParam(const ros::NodeHandle& pnh, core::PipelineConfig* config,
                     std::string* path) {
  *path = SearchString(pnh, "config", "");
  if (path->empty()) {
    *config = core::PipelineConfig();
    return true;
  }
  core::StatusOr<core::PipelineConfig> loaded = core::LoadPipelineConfig(*path);
  if (!loaded.ok()) {
    ROS_ERROR_STREAM("configuration: " << loaded.status().message());
    return false;
  }
  *config = loaded.value();
  return true;
}

bool BaseToSensorParam(const ros::NodeHandle& pnh, core::Pose3* T_base_sensor) {
  *T_base_sensor = core::Pose3::Identity();
  std::string key;
  if (!pnh.searchParam("base_to_sensor", key)) return true;
  std::vector<double> v;
  if (!pnh.getParam(key, v) || v.size() != 6) {
    ROS_ERROR("base_to_sensor must be a list [x, y, z, roll, pitch, yaw] (m, rad)");
    return false;
  }
  for (double x : v) {
    if (!std::isfinite(x)) {
      ROS_ERROR("base_to_sensor has a non-finite value");
      return false;
    }
  }
  T_base_sensor->translation() = Eigen::Vector3d(v[0], v[1], v[2]);
  T_base_sensor->linear() = (Eigen::AngleAxisd(v[5], Eigen::Vector3d::UnitZ()) *
                             Eigen::AngleAxisd(v[4], Eigen::Vector3d::UnitY()) *
                             Eigen::AngleAxisd(v[3], Eigen::Vector3d::UnitX()))
                                .toRotationMatrix();
  return true;
}

std::string SessionName(const std::string& base, int index) {
  std::string name = base;
  if (name.empty()) {
    char buffer[32];
    const std::time_t now = std::time(nullptr);
    std::strftime(buffer, sizeof(buffer), "session_%Y%m%d_%H%M%S", std::gmtime(&now));
    return buffer;  // unique per session already
  }
  return index == 0 ? name : name + "_" + std::to_string(index + 1);
}

void ReleaseFreeHeap() {
#ifdef __GLIBC__
  malloc_trim(0);
#endif
}

std::size_t HeapInUseBytes() {
#ifdef __GLIBC__
  const struct mallinfo2 info = mallinfo2();  // all arenas (glibc >= 2.33)
  return info.uordblks + info.hblkhd;
#else
  return 0;
#endif
}

Frames FramesParam(const ros::NodeHandle& pnh) {
  Frames f;
  f.map = SearchString(pnh, "map_frame", f.map);
  f.odom = SearchString(pnh, "odom_frame", f.odom);
  f.base = SearchString(pnh, "base_frame", f.base);
  return f;
}

}  // namespace nodelets
}  // namespace multisession_mapper
