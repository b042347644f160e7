// Nearest-neighbour and radius queries over a fixed point set (nanoflann kd-tree), for the
// algorithms that need plain neighbour lists (seed matching and region growing in the
// dynamic detection). KdTreeTarget serves registration (matches with normals) instead.
// Const queries are thread-safe.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "multisession_mapper/core/status.h"
#include "multisession_mapper/core/types.h"

namespace multisession_mapper {
namespace core {

class PointIndex {
 public:
  /// Builds the tree over `points` (copied). An empty set is allowed (every query finds
  /// nothing); a non-finite point is an error.
  static StatusOr<PointIndex> Create(PointVector points);
  PointIndex(PointIndex&&) noexcept;
  PointIndex& operator=(PointIndex&&) noexcept;
  ~PointIndex();

  /// Index and squared distance [m^2] of the nearest point; false when empty.
  bool Nearest(const Eigen::Vector3d& query, std::uint32_t* index, double* distance_sq) const;
  /// The nearest point if it lies within `max_radius_m` (a bounded search: much cheaper than
  /// Nearest() when most queries have no close point); false otherwise.
  bool NearestWithin(const Eigen::Vector3d& query, double max_radius_m, std::uint32_t* index,
                     double* distance_sq) const;
  /// Indices of every point within `radius_m` (inclusive), in no particular order; `out` is
  /// cleared first.
  void Radius(const Eigen::Vector3d& query, double radius_m,
              std::vector<std::uint32_t>* out) const;
  /// Number of points within `radius_m`, stopping once `cap` are found (cheap existence
  /// tests: cap = 1).
  std::size_t CountWithin(const Eigen::Vector3d& query, double radius_m, std::size_t cap) const;
  /// Up to k nearest points (nearest first) no farther than `max_radius_m`.
  void Nearest(const Eigen::Vector3d& query, std::size_t k, double max_radius_m,
               std::vector<std::uint32_t>* out) const;

  const PointVector& points() const;
  std::size_t size() const { return points().size(); }

 private:
  struct Impl;
  explicit PointIndex(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace core
}  // namespace multisession_mapper
