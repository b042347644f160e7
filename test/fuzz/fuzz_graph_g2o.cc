// libFuzzer target: the pose graph file (graph.g2o) through PoseGraph::ReadG2o. A graph that
// loads is written again and re-read: what the reader accepts, the writer must round-trip.
#include <cstddef>
#include <cstdint>
#include <sstream>
#include <string>

#include "multisession_mapper/core/pose_graph.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  namespace core = multisession_mapper::core;
  std::istringstream in(std::string(reinterpret_cast<const char*>(data), size));
  core::StatusOr<core::PoseGraph> graph = core::PoseGraph::ReadG2o(in, "fuzz.g2o");
  if (!graph.ok()) return 0;
  std::ostringstream out;
  if (!graph.value().WriteG2o(out).ok()) return 0;
  std::istringstream again(out.str());
  core::StatusOr<core::PoseGraph> reread = core::PoseGraph::ReadG2o(again, "rewritten.g2o");
  if (!reread.ok() || reread.value().edges().size() != graph.value().edges().size()) {
    __builtin_trap();
  }
  return 0;
}
