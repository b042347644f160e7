// Test helper: the integer cell of a point in a grid of cubic cells (floor, so negative
// coordinates work), as a comparable tuple; the references of the voxel and Z-order tests.
#pragma once

#include <cmath>
#include <tuple>

#include <Eigen/Core>

namespace multisession_mapper {
namespace test {

inline std::tuple<long, long, long> CellOf(const Eigen::Vector3d& p, double edge_m) {
  const auto cell = [&](double v) { return static_cast<long>(std::floor(v / edge_m)); };
  return {cell(p.x()), cell(p.y()), cell(p.z())};
}

}  // namespace test
}  // namespace multisession_mapper
