#include "multisession_mapper/core/voxel_height_histogram.h"

#include <algorithm>
#include <limits>

namespace multisession_mapper {
namespace core {

void VoxelHeightHistogram::Add(double z_m, double voxel_m) {
  const double offset_m = z_m - floor_m_;  // small: the float sums keep 0.1 mm
  const double position = offset_m / voxel_m * kSlices;
  // Clamped before the cast (also NaN, to the lowest slice).
  const int slice =
      !(position > 0.0) ? 0 : static_cast<int>(std::min(position, kSlices - 1.0));
  if (count_[slice] == std::numeric_limits<std::uint16_t>::max()) {
    // Halve every slice: the proportions and the slices' mean heights stay.
    for (int s = 0; s < kSlices; ++s) {
      if (count_[s] == 0) continue;
      const float mean = sum_m_[s] / count_[s];
      count_[s] = static_cast<std::uint16_t>((count_[s] + 1) / 2);
      sum_m_[s] = mean * count_[s];
    }
  }
  ++count_[slice];
  sum_m_[slice] += static_cast<float>(offset_m);
}

std::uint32_t VoxelHeightHistogram::count() const {
  std::uint32_t total = 0;
  for (const std::uint16_t c : count_) total += c;
  return total;
}

double VoxelHeightHistogram::RobustHeight(double fallback_m) const {
  const std::uint32_t total = count();
  if (total == 0) return fallback_m;
  // The slice holding the median: the first whose cumulative count reaches half.
  int median = 0;
  std::uint32_t cumulative = 0;
  for (; median < kSlices; ++median) {
    cumulative += count_[median];
    if (2 * cumulative >= total) break;
  }
  double sum = 0.0;
  std::uint32_t n = 0;
  for (int s = std::max(0, median - 1); s <= std::min(kSlices - 1, median + 1); ++s) {
    sum += sum_m_[s];
    n += count_[s];
  }
  return floor_m_ + sum / n;
}

}  // namespace core
}  // namespace multisession_mapper
