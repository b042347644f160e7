// Turns a mapped session into map contents (reference paper, section VI, map update). The first
// session defines the map frame; later sessions are merged by the multi-session stage.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "multisession_mapper/core/map_store.h"
#include "multisession_mapper/core/session_mapper.h"
#include "multisession_mapper/core/status.h"

namespace multisession_mapper {
namespace core {

/// Node id of a submap in the map's pose graph: session index * 1e6 + submap id.
NodeId SubmapNodeId(std::size_t session_index, std::uint32_t submap_id);

/// Copies a session's edges and vertical priors (node id = submap id) into the map graph,
/// renumbered with SubmapNodeId(session_index, .). The nodes must already be in `map_graph`.
Status AddSessionGraph(const PoseGraph& session_graph, std::size_t session_index,
                       PoseGraph* map_graph);

/// Files of a session that other modules produce (CSV and YAML text).
struct SessionFiles {
  std::string timing_yaml;
  std::string place_recognition_csv;  ///< empty when there was no database to query
};

/// Adds the first session of a map: its frame becomes the map frame, its submap graph the map
/// graph (submap 0 fixed). Fails when the map already has sessions.
Status AddFirstSession(const SessionResult& session, const SessionRecord& record,
                       const SessionFiles& files, MapContents* map);

/// Relative paths of a session's records that a retention policy may drop: its point records
/// (dynamics/<session>_removed.pcd, _mended.pcd) and its place-recognition log.
std::vector<std::string> SessionRecordFiles(const std::string& session);

/// Retention of the records (MapFusionConfig::record_sessions): the records of every session
/// but the last `keep` ones in `map->sessions` leave `map->files` / `map->clouds` and are
/// listed in `map->retired_files`, so that the next save does not carry them over. Change
/// logs, loops, trajectories and timing records stay. keep <= 0: nothing is retired.
void RetireSessionRecords(int keep, MapContents* map);

}  // namespace core
}  // namespace multisession_mapper
