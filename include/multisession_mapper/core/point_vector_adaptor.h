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

/// A 3D L2 kd-tree over a PointVector; IndexType is the type of the returned point indices.
template <typename IndexType>
using PointVectorKdTree =
    nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, PointVectorAdaptor>,
                                        PointVectorAdaptor, 3, IndexType>;

}  // namespace core
}  // namespace multisession_mapper
