// nanoflann's dataset interface over a PointVector, and the 3D kd-tree type built on it. Shared
// by KdTreeTarget (registration) and PointIndex (neighbour queries); an implementation header of
// the core library (it includes nanoflann).
#pragma once

#include <cstddef>

#include <nanoflann.hpp>

#include "multisession_mapper/core/types.h"

namespace multisession_mapper {
namespace core {

struct PointVectorAdaptor {
  const PointVector* points = nullptr;
  std::size_t kdtree_get_point_count() const { return points->size(); }
  double kdtree_get_pt(std::size_t i, std::size_t dim) const { return (*points)[i](dim); }
  template <class Bbox>
  bool kdtree_get_bbox(Bbox& /*bb*/) const {
    return false;  // let nanoflann compute the bounding box
  }
};

/// nanoflann result set: the nearest index within an initial squared radius. It prunes the search
/// from the start, unlike a k = 1 search that begins with an infinite radius and descends into
/// far branches for a query with no point nearby.
template <typename IndexType>
class BoundedNearest {
 public:
  explicit BoundedNearest(double radius_sq) : best_sq_(radius_sq) {}
  std::size_t size() const { return found_ ? 1 : 0; }
  bool full() const { return true; }
  double worstDist() const { return best_sq_; }
  bool addPoint(double dist, IndexType index) {
    if (dist <= best_sq_) {
      best_sq_ = dist;
      index_ = index;
      found_ = true;
    }
    return true;
  }
  bool found() const { return found_; }
  IndexType index() const { return index_; }
  double distance_sq() const { return best_sq_; }

 private:
  double best_sq_;
  IndexType index_ = 0;
  bool found_ = false;
};

/// A 3D L2 kd-tree over a PointVector; IndexType is the type of the returned point indices.
template <typename IndexType>
using PointVectorKdTree =
    nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, PointVectorAdaptor>,
                                        PointVectorAdaptor, 3, IndexType>;

}  // namespace core
}  // namespace multisession_mapper
