// Reading and writing one LidarScan as a PCD file through PCL's generic PCLPointCloud2, so
// any field layout (padding fields "_", Velodyne x y z intensity ring time, Ouster t in ns,
// plain x y z) is accepted. Used by tests on the real data and by the tools.
#pragma once

#include <string>

#include "multisession_mapper/core/status.h"
#include "multisession_mapper/core/types.h"

namespace multisession_mapper {
namespace core {

/// Loads `path`. x, y, z are required (float32 or float64); intensity (any numeric type),
/// ring (integer) and time are optional; time is `time` [s, float] or `t` [ns, uint32],
/// relative to the scan start. has_ring / has_time say what was found. `stamp_s` is set by
/// the caller (PCD has no stamp). Fails, naming the problem, on a missing or unreadable file
/// or missing x/y/z.
StatusOr<LidarScan> LoadPcdScan(const std::string& path);

/// Writes `scan` as binary PCD with fields x y z intensity ring time (float32, float32,
/// float32, float32, uint16, float32).
Status SavePcdScan(const std::string& path, const LidarScan& scan);

}  // namespace core
}  // namespace multisession_mapper
