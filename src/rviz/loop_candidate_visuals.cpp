#include "loop_candidate_visuals.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace multisession_mapper {
namespace rviz_plugins {
namespace {

bool IsFinite(const geometry_msgs::Point& p) {
  return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z);
}

std::string Label(const LoopCandidate& c, bool has_segment) {
  char numbers[96];
  std::string label = c.current_session + ":" + std::to_string(c.current_submap);
  if (has_segment) {
    label += " -> " + c.history_session + ":" + std::to_string(c.history_submap);
    std::snprintf(numbers, sizeof(numbers), "\nvote %.2f  overlap %.2f",
                  static_cast<double>(c.vote_proportion), static_cast<double>(c.overlap_ratio));
  } else {
    std::snprintf(numbers, sizeof(numbers), " %s\nvote %.2f", LoopStatusName(c.status),
                  static_cast<double>(c.vote_proportion));
  }
  return label + numbers;
}

}  // namespace

const char* LoopStatusName(uint8_t status) {
  switch (status) {
    case LoopCandidate::CANDIDATE: return "candidate";
    case LoopCandidate::ACCEPTED: return "accepted";
    case LoopCandidate::REJECTED: return "rejected";
    case LoopCandidate::UNDEFINED: return "undefined";
    default: return "unknown";
  }
}

LoopVisualList BuildLoopVisuals(const LoopCandidateArray& msg,
                                const std::array<bool, kNumLoopStatuses>& show_status) {
  LoopVisualList out;
  for (size_t i = 0; i < msg.candidates.size(); ++i) {
    const LoopCandidate& c = msg.candidates[i];
    if (c.status >= kNumLoopStatuses || i >= msg.current_origins.size() ||
        !IsFinite(msg.current_origins[i])) {
      ++out.num_invalid;
      continue;
    }
    const bool has_segment =
        c.status != LoopCandidate::UNDEFINED && !c.history_session.empty();
    if (has_segment && (i >= msg.history_origins.size() || !IsFinite(msg.history_origins[i]))) {
      ++out.num_invalid;
      continue;
    }
    ++out.count_by_status[c.status];
    if (!show_status[c.status]) continue;
    LoopVisual v;
    v.status = c.status;
    v.current_origin = msg.current_origins[i];
    v.has_segment = has_segment;
    if (has_segment) v.history_origin = msg.history_origins[i];
    v.label = Label(c, has_segment);
    out.visuals.push_back(std::move(v));
  }
  // Drawn in this order, so that accepted loops stay visible over the (usually many) rejected.
  auto draw_rank = [](uint8_t status) {
    switch (status) {
      case LoopCandidate::REJECTED: return 0;
      case LoopCandidate::UNDEFINED: return 1;
      case LoopCandidate::CANDIDATE: return 2;
      default: return 3;  // ACCEPTED
    }
  };
  std::stable_sort(out.visuals.begin(), out.visuals.end(),
                   [&](const LoopVisual& a, const LoopVisual& b) {
                     return draw_rank(a.status) < draw_rank(b.status);
                   });
  return out;
}

}  // namespace rviz_plugins
}  // namespace multisession_mapper
