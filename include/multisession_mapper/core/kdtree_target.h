// Registration target over a fixed point set (a submap, a reference scan): a nanoflann kd-tree
// for nearest neighbours plus normals from the k nearest neighbours (PCA, see local_plane.h),
// fitted when a point is first matched and kept. Used by IcpRegistration for submap-to-submap
// and scan-to-submap alignment, where the target does not change between queries. Const
// queries are thread-safe.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "multisession_mapper/core/local_plane.h"
#include "multisession_mapper/core/registration_target.h"
#include "multisession_mapper/core/status.h"
#include "multisession_mapper/core/types.h"

namespace multisession_mapper {
namespace core {

struct KdTreeTargetConfig {
  /// Neighbours used for each point's normal (the point itself included). On dense scans the
  /// neighbours of a point lie on its own ring (no normal, point-to-point is used): downsample
  /// the target (0.1-0.3 m) first so that neighbourhoods span several rings.
  int normal_neighbors = 20;
  /// Neighbours farther than this are left out of the normal fit [m]; keeps normals local on
  /// sparse far-range points.
  double max_normal_radius_m = 1.5;
  LocalPlaneCriteria plane;

  Status Validate() const;
};

class KdTreeTarget : public RegistrationTarget {
 public:
  /// Builds the tree over `points` (copied); normals are fitted when first matched. Fails on
  /// a bad config or when `points` is empty.
  static StatusOr<KdTreeTarget> Create(PointVector points,
                                       const KdTreeTargetConfig& config = KdTreeTargetConfig());
  KdTreeTarget(KdTreeTarget&&) noexcept;
  KdTreeTarget& operator=(KdTreeTarget&&) noexcept;
  ~KdTreeTarget() override;

  bool FindMatch(const Eigen::Vector3d& query, double max_distance_m,
                 TargetMatch* match) const override;
  /// FindMatch per query; with `warm_start` each query's search is bounded by the distance to
  /// its previous match (WarmStartBoundSq), and a query without a match is not searched again
  /// while it has moved too little to reach a point within `max_distance_m` (its unused entry
  /// of `matches` keeps where it was searched and how far its nearest point was at least; it
  /// is searched a quarter farther for that). Same results, fewer tree branches: submap ICP's
  /// fine stage 0.146 -> 0.141 s per pair median and the slowest pair 1.15 -> 1.03 s
  /// (global_registration_benchmark, campus seed-1 s00 map, alternating runs). `pool` unused.
  void FindMatches(const PointVector& queries, double max_distance_m, bool warm_start,
                   WorkerPool* pool, std::vector<std::uint8_t>* found,
                   std::vector<TargetMatch>* matches) const override;
  bool empty() const override;

  /// Index of the nearest point within `max_distance_m` and its squared distance [m^2];
  /// false when there is none. The search is pruned by that radius from the start (a k = 1
  /// search begins with an infinite radius and descends into far branches for a query with
  /// no point nearby).
  bool NearestWithin(const Eigen::Vector3d& query, double max_distance_m, std::size_t* index,
                     double* distance_sq) const;
  const PointVector& points() const;
  /// Fraction of points with a planar normal (diagnostics).
  double PlanarFraction() const;

 private:
  struct Impl;
  /// Nearest point closer than sqrt(bound_sq) with its normal; false when there is none.
  bool MatchWithin(const Eigen::Vector3d& query, double bound_sq, TargetMatch* match) const;
  bool NearestWithinSq(const Eigen::Vector3d& query, double bound_sq, std::size_t* index,
                       double* distance_sq) const;
  explicit KdTreeTarget(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace core
}  // namespace multisession_mapper
