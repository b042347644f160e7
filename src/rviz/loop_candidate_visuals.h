// What LoopCandidatesDisplay draws for one LoopCandidateArray, computed without Ogre so that it
// can be unit-tested: one segment per loop (current submap origin -> history submap origin), or
// one marker at the current origin for an UNDEFINED submap (no history submap won the vote,
// Ding et al., Sec. III-B), each with a label carrying the vote proportion and overlap ratio.
#pragma once

#include <array>
#include <string>
#include <vector>

#include <geometry_msgs/Point.h>
#include <multisession_mapper/LoopCandidate.h>
#include <multisession_mapper/LoopCandidateArray.h>

namespace multisession_mapper {
namespace rviz_plugins {

// Number of LoopCandidate::status values (CANDIDATE, ACCEPTED, REJECTED, UNDEFINED).
constexpr int kNumLoopStatuses = 4;

struct LoopVisual {
  uint8_t status = LoopCandidate::UNDEFINED;
  geometry_msgs::Point current_origin;   // map frame [m]
  geometry_msgs::Point history_origin;   // map frame [m]; unused when !has_segment
  bool has_segment = false;              // false: draw a marker at current_origin only
  std::string label;                     // e.g. "s01:4 -> s00:7\nvote 0.62  overlap 0.48"
};

struct LoopVisualList {
  std::vector<LoopVisual> visuals;
  // Candidates left out because an origin was missing (arrays shorter than `candidates`),
  // not finite, or the status is unknown. Shown to the user as a display warning.
  int num_invalid = 0;
  // Per status (index = LoopCandidate::status) the number of candidates in the message.
  std::array<int, kNumLoopStatuses> count_by_status{};
};

// Builds the visuals of `msg`, keeping only statuses with show_status[status] true, in drawing
// order: rejected, undefined, candidate, accepted (message order within a status). A candidate
// whose status is not UNDEFINED but whose history_session is empty is drawn as a marker too.
LoopVisualList BuildLoopVisuals(const LoopCandidateArray& msg,
                                const std::array<bool, kNumLoopStatuses>& show_status);

// Human-readable status name ("candidate", "accepted", "rejected", "undefined", "unknown").
const char* LoopStatusName(uint8_t status);

}  // namespace rviz_plugins
}  // namespace multisession_mapper
