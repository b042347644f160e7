// What ICP registers against: anything that answers "nearest target point to q, with the
// local surface normal there if the neighbourhood is planar". Implemented by the local voxel
// map (odometry, VoxelHashMap) and by a kd-tree over a fixed point set (submap-to-submap
// registration, KdTreeTarget), so the same IcpRegistration serves both.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "multisession_mapper/core/types.h"

namespace multisession_mapper {
namespace core {

class WorkerPool;  // worker_pool.h; only implementations that split the search need it

/// One target point matched to a query.
struct TargetMatch {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();   ///< target point [m], target frame
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();  ///< unit normal when has_normal
  bool has_normal = false;  ///< false: neighbourhood not planar, use point-to-point
  double distance_sq = 0.0;  ///< squared distance query-point [m^2]
};

/// Squared search radius of a warm-started query (see RegistrationTarget::FindMatches): the
/// distance to its previous match, which is still in the unchanged target, so the nearest
/// point is at most that far; at most `max_sq`. A search that accepts only points closer than
/// this visits the candidates that can win in the same order as an unbounded one, so it picks
/// the same point. The margin keeps the previous match itself inside despite rounding.
/// `previous` null: the query had no match, the bound is `max_sq`.
inline double WarmStartBoundSq(const TargetMatch* previous, const Eigen::Vector3d& query,
                               double max_sq) {
  if (previous == nullptr) return max_sq;
  const double d_sq = (previous->point - query).squaredNorm();
  return std::min(max_sq, d_sq * (1.0 + 1e-9) + 1e-18);
}

class RegistrationTarget {
 public:
  virtual ~RegistrationTarget() = default;

  /// Nearest target point to `query` (target frame) closer than `max_distance_m`; false when
  /// there is none. Implementations may cache normals, so concurrent calls are not allowed
  /// unless the implementation says otherwise.
  virtual bool FindMatch(const Eigen::Vector3d& query, double max_distance_m,
                         TargetMatch* match) const = 0;

  /// FindMatch for every query: (*found)[i] is 1 when queries[i] has a match, which is then in
  /// (*matches)[i]. Results are those of one FindMatch per query in order. A `pool` (may be
  /// null) lets an implementation that allows it search on the pool's threads (VoxelHashMap
  /// without normals); this default runs FindMatch in order on the calling thread.
  /// `warm_start`: on entry, *found / *matches hold this target's answer for the same queries
  /// at nearby positions (the previous iteration of an ICP, or the last search with another
  /// max_distance_m, IcpSearchMemory; the target has not changed since). An implementation
  /// may bound the search by the distance to the previous match (VoxelHashMap and KdTreeTarget
  /// do) and keep its own memo in the entries of queries without a match (KdTreeTarget); the
  /// results are the same as without. This default ignores it.
  virtual void FindMatches(const PointVector& queries, double max_distance_m, bool warm_start,
                           WorkerPool* pool, std::vector<std::uint8_t>* found,
                           std::vector<TargetMatch>* matches) const {
    (void)pool;
    (void)warm_start;
    found->assign(queries.size(), 0);
    matches->resize(queries.size());
    for (std::size_t i = 0; i < queries.size(); ++i) {
      (*found)[i] = FindMatch(queries[i], max_distance_m, &(*matches)[i]) ? 1 : 0;
    }
  }

  /// True when the target holds no point.
  virtual bool empty() const = 0;
};

}  // namespace core
}  // namespace multisession_mapper
