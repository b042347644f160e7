#include "multisession_mapper/core/submap_loop_agreement.h"

#include <algorithm>
#include <map>

#include "multisession_mapper/core/se3.h"

namespace multisession_mapper {
namespace core {

std::vector<std::size_t> OddPlacementsOfOneSubmap(const SubmapPlacements& placements,
                                                  double max_translation_m,
                                                  double max_rotation_rad) {
  std::map<std::uint32_t, std::vector<std::size_t>> by_submap;
  for (std::size_t i = 0; i < placements.size(); ++i) {
    by_submap[placements[i].current_submap].push_back(i);
  }
  const auto agree = [&](std::size_t a, std::size_t b) {
    const Pose3 difference =
        se3::Between(placements[a].T_map_current, placements[b].T_map_current);
    return se3::TranslationNorm(difference) <= max_translation_m &&
           se3::RotationAngleRad(difference) <= max_rotation_rad;
  };
  std::vector<std::size_t> odd;
  for (const auto& entry : by_submap) {
    const std::vector<std::size_t>& members = entry.second;
    if (members.size() < 3) continue;
    std::vector<std::size_t> lonely;
    for (std::size_t a : members) {
      const bool partnered =
          std::any_of(members.begin(), members.end(), [&](std::size_t b) {
            return a != b && agree(a, b);
          });
      if (!partnered) lonely.push_back(a);
    }
    // Every placement alone: no majority to tell the odd ones by.
    if (lonely.size() == members.size()) continue;
    odd.insert(odd.end(), lonely.begin(), lonely.end());
  }
  std::sort(odd.begin(), odd.end());
  return odd;
}

}  // namespace core
}  // namespace multisession_mapper
