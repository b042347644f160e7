// The heights of the returns in one map voxel, so that the voxel's point can sit at the
// surface most of them measured. A ground voxel on which a pedestrian stood, or next to which
// a car passed, collects a minority of returns from the feet or the car's underside a few
// centimetres above the ground; their mean lifts the voxel's point off the ground, and the
// lifted point then lies nearer those objects than the ground (campus s00, seed 1: the map
// points nearest the moving-object points kept within 0.25 m of the ground were a median
// 0.034 m above it, clean ground points 0.001 m). The mean of the returns around their
// median height ignores such a minority.
#pragma once

#include <array>
#include <cstdint>

namespace multisession_mapper {
namespace core {

class VoxelHeightHistogram {
 public:
  /// Slices of the voxel's height.
  static constexpr int kSlices = 8;

  /// For the voxel whose floor (lowest z) is at `floor_m` [m].
  explicit VoxelHeightHistogram(double floor_m) : floor_m_(static_cast<float>(floor_m)) {}

  /// Adds a return at height `z_m` [m] (the voxel's edge is `voxel_m`; a height outside the
  /// voxel goes to the nearest slice).
  void Add(double z_m, double voxel_m);

  /// Mean height of the returns in the slice holding their median and in the slice on each
  /// side of it [m]; `fallback_m` when nothing was added.
  double RobustHeight(double fallback_m) const;

  /// Returns added (up to the halving that keeps the counts in 16 bits).
  std::uint32_t count() const;

 private:
  std::array<std::uint16_t, kSlices> count_{};
  std::array<float, kSlices> sum_m_{};  ///< of the heights above the floor
  float floor_m_;  ///< the voxel's lowest z [m]
};

}  // namespace core
}  // namespace multisession_mapper
