// Scan Context (Kim & Kim, "Scan Context: Egocentric Spatial Descriptor for Place Recognition
// within 3D Point Cloud Map", IROS 2018), the selectable alternative to the ring histograms.
//
// The horizontal plane around the sensor is cut into `num_rings` radial rings (equal width up
// to max_radius_m) x `num_sectors` azimuth sectors (sector 0 starts at azimuth -pi); each cell
// holds the largest point height z + sensor_height_m (clamped at 0; 0 = empty cell).
//  - Ring key (the kd-tree vector): the mean of each ring (row) over its sectors; invariant to
//    yaw.
//  - Sector key: the mean of each sector (column); used to find a coarse column shift fast.
//  - Distance: min over column shifts k of the mean over columns j of
//    1 - cos(query column (j + k) mod S, candidate column j), counting only columns non-empty in
//    both (1.0 when no column pair is comparable). Shifts searched: the sector-key alignment
//    +- shift_search_radius (the original's fast search), or all when the radius covers them.
//  - Yaw: the best shift k gives yaw = -k * 2 pi / S (wrapped to (-pi, pi]) with the convention
//    p_candidate ~= Rz(yaw) * p_query, i.e. the yaw of T_candidate_query.
#pragma once

#include "multisession_mapper/core/place_descriptor.h"
#include "multisession_mapper/core/status.h"
#include "multisession_mapper/core/types.h"

namespace multisession_mapper {
namespace core {

struct ScanContextConfig {
  int num_rings = 20;           ///< radial bins (the paper's N_r)
  int num_sectors = 60;         ///< azimuth bins (the paper's N_s), 6 deg each
  double max_radius_m = 80.0;   ///< horizontal range covered [m]; farther points are ignored
  double min_radius_m = 1.0;    ///< nearer points (robot body) are ignored [m]
  /// Added to z so that the ground is ~0 and cells stay >= 0 [m] (original: 2.0 m).
  double sensor_height_m = 2.0;
  /// Column shifts searched on each side of the sector-key alignment [sectors] (original:
  /// 10 % of num_sectors).
  int shift_search_radius = 6;

  /// OK when every field is finite and consistent; otherwise names the bad field.
  Status Validate() const;
};

/// Result of comparing two Scan Contexts.
struct ScanContextMatch {
  float distance = 1.0f;  ///< in [0, 1]; 0 = identical up to a column shift
  int shift = 0;          ///< best column shift k in [0, num_sectors)
  double yaw_rad = 0.0;   ///< yaw of T_candidate_query, (-pi, pi]
};

class ScanContextDescriptor {
 public:
  /// `config` must be valid (see ScanContextConfig::Validate); Create() checks it.
  static StatusOr<ScanContextDescriptor> Create(const ScanContextConfig& config);

  /// Descriptor of one scan in the sensor frame (kind kScanContext: key = ring key, matrix =
  /// num_rings x num_sectors row-major).
  PlaceDescriptor Compute(const LidarScan& scan) const;

  /// Column-shift distance and yaw between two Scan Contexts of this configuration's size.
  /// Returns distance 1 when either is not such a Scan Context.
  ScanContextMatch Distance(const PlaceDescriptor& query, const PlaceDescriptor& candidate) const;
  /// The same on raw row-major num_rings x num_sectors matrices (no size check; the database
  /// uses it to avoid copying stored matrices).
  ScanContextMatch DistanceRaw(const float* query, const float* candidate) const;

  const ScanContextConfig& config() const { return config_; }

 private:
  explicit ScanContextDescriptor(const ScanContextConfig& config) : config_(config) {}
  ScanContextConfig config_;
};

}  // namespace core
}  // namespace multisession_mapper
