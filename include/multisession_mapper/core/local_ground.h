// Height of points above their local ground, estimated from the same points: the lowest point
// per horizontal cell, then the minimum over the 3 x 3 cells around (a cell under a parked car
// has no ground return; its neighbours do). The map update uses it to tell the surfaces no
// movable object can be part of (terrain, canopies, roofs) from those a car could be.
#pragma once

#include <cstdint>
#include <vector>

#include "multisession_mapper/core/types.h"

namespace multisession_mapper {
namespace core {

/// Per point of `points` (one frame, z up): its height above the local ground [m], >= 0.
/// cell_m is the horizontal cell edge [m] and must be > 0; points must be finite.
std::vector<float> HeightsAboveLocalGround(const PointVector& points, double cell_m);

/// Per point: 1 when a point of `points` whose height (`heights`, as above) lies in
/// (low_m, high_m) is in its cell or one of the 8 around, i.e. something stands next to it
/// (a wall, a tyre, a hedge). heights has one entry per point; cell_m > 0.
std::vector<std::uint8_t> NearStandingPoints(const PointVector& points,
                                             const std::vector<float>& heights, double cell_m,
                                             double low_m, double high_m);

}  // namespace core
}  // namespace multisession_mapper
