// Labelled ground-truth cloud of a session (truth/<session>_labels.pcd, docs/simulator.md):
// exact hit positions in the world frame with their class and object id, one point per voxel
// (the first hit, in scan order, so the output does not depend on threads), and the smallest
// range from which any return of that voxel was measured (so an evaluation can leave out
// what a pipeline with a shorter range limit could never have mapped).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "multisession_mapper/core/status.h"
#include "multisession_mapper/core/voxel_index_table.h"
#include "multisession_mapper/core/voxel_key.h"
#include "multisession_mapper/sim/vlp16.h"

namespace multisession_mapper {
namespace sim {

class LabelCloud {
 public:
  /// `voxel_m` > 0: keep the first point per cubic voxel of that size (with the smallest
  /// range_m of the voxel's points); 0: keep every point.
  explicit LabelCloud(double voxel_m);

  void Add(const TruthPoint& point);
  void Add(const std::vector<TruthPoint>& points);
  std::size_t size() const { return points_.size(); }
  const std::vector<TruthPoint>& points() const { return points_; }

  /// Binary PCD v0.7 with packed fields x y z (F4) label (U1) object_id (U4) range (F4),
  /// 21 bytes/point.
  core::Status WritePcd(const std::string& path) const;
  /// Reads a file written by WritePcd (binary or ascii), or by earlier versions without the
  /// range field (range_m = 0).
  static core::StatusOr<std::vector<TruthPoint>> ReadPcd(const std::string& path);

 private:
  double voxel_m_;
  core::VoxelIndexTable voxels_;  ///< voxel -> index of its point in points_
  std::vector<TruthPoint> points_;
};

}  // namespace sim
}  // namespace multisession_mapper
