// Parameter helpers shared by the four nodelets (no algorithm here).
// Parameters common to all nodelets (config, session, map_dir, frames, base_to_sensor) are set
// once in the launch file's namespace and found with searchParam from each private namespace.
#pragma once

#include <cstddef>
#include <memory>
#include <string>

#include <boost/thread/recursive_mutex.hpp>
#include <dynamic_reconfigure/server.h>
#include <ros/node_handle.h>

#include "multisession_mapper/core/pipeline_config.h"
#include "multisession_mapper/core/types.h"

namespace multisession_mapper {
namespace nodelets {

/// `name` from the private namespace or the nearest enclosing one; `fallback` when absent.
std::string SearchString(const ros::NodeHandle& pnh, const std::string& name,
                         const std::string& fallback);
double SearchDouble(const ros::NodeHandle& pnh, const std::string& name, double fallback);

/// The pipeline configuration from the YAML file named by the `config` parameter (defaults
/// when the parameter is empty). Logs and returns false on a bad file.
bool LoadConfigParam(const ros::NodeHandle& pnh, core::PipelineConfig* config,
                     std::string* path);

/// T_base_sensor from the `base_to_sensor` parameter [x y z roll pitch yaw] (m, rad);
/// identity when absent. Logs and returns false on a malformed value.
bool BaseToSensorParam(const ros::NodeHandle& pnh, core::Pose3* T_base_sensor);

/// Name of the index-th session of this run: the `session` parameter (default: wall-clock time
/// "session_YYYYmmdd_HHMMSS"), with "_<index+1>" appended from the second session on.
std::string SessionName(const std::string& base, int index);

/// Returns the free pages of the heap to the system (glibc malloc_trim; nothing elsewhere).
void ReleaseFreeHeap();

/// Bytes of the process's live heap allocations: glibc's mallinfo2 summed over every arena
/// (allocated chunks plus mmapped blocks); what a leak makes grow, unlike the RSS, which also
/// holds freed pages the allocator keeps. 0 without glibc.
std::size_t HeapInUseBytes();

/// Frame names: map, odom, base (REP-105).
struct Frames {
  std::string map = "map";
  std::string odom = "odom";
  std::string base = "base_link";
};
Frames FramesParam(const ros::NodeHandle& pnh);

/// A dynamic_reconfigure server whose very first published configuration is `initial` (the
/// values of the configuration YAML), with `callback` set. The values are put on the parameter
/// server first, where the server's constructor reads them: setting them only afterwards
/// (updateConfig) left a moment in which clients saw the .cfg defaults (found by the rostest).
/// The server answers requests as soon as its constructor has advertised its service, and
/// one that came before the callback was set was applied unchecked (the rostest once got its
/// refused fuse_fine_above_m 0.1 back); the server's mutex is held until the callback is set,
/// so such a request waits for it.
template <class Config, class Callback>
std::unique_ptr<dynamic_reconfigure::Server<Config>> StartReconfigureServer(
    boost::recursive_mutex& mutex, const ros::NodeHandle& pnh, const Config& initial,
    Callback callback) {
  boost::recursive_mutex::scoped_lock lock(mutex);
  initial.__toServer__(pnh);
  auto server = std::make_unique<dynamic_reconfigure::Server<Config>>(mutex, pnh);
  server->updateConfig(initial);  // the same values again, in case one did not survive the
                                  // parameter server round trip
  server->setCallback(callback);
  return server;
}

}  // namespace nodelets
}  // namespace multisession_mapper
