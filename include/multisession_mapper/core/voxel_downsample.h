// Voxel-grid downsampling that keeps the FIRST point that falls in each voxel (as KISS-ICP,
// Vizzo et al. 2023, "KISS-ICP: In Defense of Point-to-Point ICP"): no averaging, so every
// kept point is a real measurement with its own attributes (ring, time for de-skewing).
//
// Own implementation vs pcl::VoxelGrid (centroid per voxel), measured with
// `odometry_benchmark` on the real VLP-16 scan vlp16_indoor/0.pcd (28,221 points, Release,
// median of 50, shared 2-core machine under load): voxel 0.1 m: own 0.26 ms vs PCL 1.19 ms;
// 0.5 m: 0.24 vs 0.59 ms; 1.5 m: 0.23 vs 0.48 ms (same point counts). The own one is kept:
// 2-5x faster, and it keeps real measurements with their ring/time attributes.
#pragma once

#include "multisession_mapper/core/types.h"

namespace multisession_mapper {
namespace core {

/// Points with one representative (the first in input order) per cubic voxel of edge
/// `voxel_size_m` [m]. Input order of the kept points is preserved. `voxel_size_m <= 0`
/// returns the input unchanged.
PointVector VoxelDownsample(const PointVector& points, double voxel_size_m);

/// The same on a scan: the kept points carry all their attributes; stamp and flags are kept.
LidarScan VoxelDownsample(const LidarScan& scan, double voxel_size_m);

/// Positions of a scan's points as double-precision vectors (same order).
PointVector ScanToPointVector(const LidarScan& scan);

}  // namespace core
}  // namespace multisession_mapper
