#include "multisession_mapper/core/map_update.h"

namespace multisession_mapper {
namespace core {

NodeId SubmapNodeId(std::size_t session_index, std::uint32_t submap_id) {
  return static_cast<NodeId>(session_index) * 1000000 + submap_id;
}

Status AddSessionGraph(const PoseGraph& session_graph, std::size_t session_index,
                       PoseGraph* map_graph) {
  auto node = [&](NodeId id) { return SubmapNodeId(session_index, static_cast<std::uint32_t>(id)); };
  for (const PoseGraphEdge& edge : session_graph.edges()) {
    PoseGraphEdge copy = edge;
    copy.from = node(edge.from);
    copy.to = node(edge.to);
    StatusOr<std::size_t> added = map_graph->AddEdge(copy);
    if (!added.ok()) return added.status();
  }
  for (const auto& [id, information] : session_graph.vertical_priors()) {
    const Status set = map_graph->SetVerticalPrior(node(id), information);
    if (!set.ok()) return set;
  }
  return Status::Ok();
}

Status AddFirstSession(const SessionResult& session, const SessionRecord& record,
                       const SessionFiles& files, MapContents* map) {
  if (!map->sessions.empty()) {
    return Status::Error("the map already has sessions; '" + record.name +
                         "' must be merged, not added as the first session");
  }
  if (session.submaps.empty()) return Status::Error("session '" + record.name + "' has no submaps");
  map->sessions.push_back(record);
  for (const Submap& submap : session.submaps) {
    map->submaps.push_back(submap);
    map->graph.SetNodePose(SubmapNodeId(0, submap.id), submap.T_map_submap);
  }
  map->graph.SetFixed(SubmapNodeId(0, session.submaps.front().id), true);
  map->graph.SetUp(session.graph.up());  // the first session's frame is the map frame
  const Status graph = AddSessionGraph(session.graph, 0, &map->graph);
  if (!graph.ok()) return graph;
  map->trajectories[record.name] = session.trajectory;
  map->odom_trajectories[record.name] = session.odometry;
  map->files["loops/" + record.name + ".csv"] = LoopRecordsToCsv(session.loops);
  map->files["timing/" + record.name + ".yaml"] = files.timing_yaml;
  if (!files.place_recognition_csv.empty()) {
    map->files["place_recognition/" + record.name + ".csv"] = files.place_recognition_csv;
  }
  return Status::Ok();
}

std::vector<std::string> SessionRecordFiles(const std::string& session) {
  return {"dynamics/" + session + "_removed.pcd", "dynamics/" + session + "_mended.pcd",
          "dynamics/" + session + "_held.pcd", "place_recognition/" + session + ".csv"};
}

void RetireSessionRecords(int keep, MapContents* map) {
  if (keep <= 0 || map->sessions.size() <= static_cast<std::size_t>(keep)) return;
  const std::size_t retired = map->sessions.size() - static_cast<std::size_t>(keep);
  for (std::size_t i = 0; i < retired; ++i) {
    for (const std::string& rel : SessionRecordFiles(map->sessions[i].name)) {
      map->files.erase(rel);
      map->clouds.erase(rel);
      map->retired_files.insert(rel);
    }
  }
}

}  // namespace core
}  // namespace multisession_mapper
