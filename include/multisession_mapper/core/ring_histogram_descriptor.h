// LocNet-style handcrafted, rotation-invariant place descriptor (the default).
//
// LocNet (Yin et al., "Efficient 3D LiDAR based loop closing using deep neural network",
// ROBIO 2017), which the reference paper uses for inter-session place recognition (section V),
// feeds a siamese network with ring-wise histograms of range information. No trained weights
// exist here, so the descriptor is that handcrafted input itself, made compact and normalised
// so that a Euclidean kd-tree can index it.
//
// Construction, for each laser ring r in [0, num_rings):
//  1. Points of the ring with 3D range rho in [min_range_m, max_range_m] (and a defined azimuth)
//     are sorted by azimuth (a cheap monotone pseudo-angle, same order as atan2).
//  2. Range histogram H_r: `range_bins` bins spaced logarithmically over
//     [min_range_m, max_range_m] (near structure gets finer bins than far structure; a range
//     at exactly max_range_m falls in the last bin).
//  3. Range-difference histogram D_r: |rho_{k+1} - rho_k| over consecutive points of the ring
//     taken CYCLICALLY (the last point is followed by the first), `diff_bins` bins: bin 0 is
//     [0, diff_min_m), bins 1..diff_bins-2 are logarithmic over [diff_min_m, diff_max_m), the
//     last bin collects everything >= diff_max_m (edges of objects, gaps).
//  4. Each histogram is normalised to sum 1 (a probability), then square-rooted: the Euclidean
//     distance between square-rooted histograms is (sqrt 2 times) the Hellinger distance, which
//     suits histograms better than raw L2. A ring with fewer than `min_points_per_ring` points
//     contributes zeros.
//  5. The vector [w sqrt(H_0), sqrt(D_0), w sqrt(H_1), sqrt(D_1), ...], w = range_weight, is
//     scaled by 1 / sqrt(num_rings * (1 + w^2)), so its norm is <= 1 and descriptor distances
//     lie in [0, sqrt 2].
// Defaults were chosen on the simulator (`small` profile, 2 sessions, seeds 1 and 7, scan-level
// recall@1 and F1max within 5 m): range histograms are sensitive to the sensor's position, so
// coarse range bins at a low weight (6 bins, w = 0.15) beat fine or equally weighted ones
// (12 bins, w = 1: recall@1 0.67 vs 0.95 on seed 1), in line with LocNet's use of range
// differences.
// Dimension: num_rings * (range_bins + diff_bins) (default 16 * (6 + 12) = 288).
//
// Yaw invariance: ranges do not change under a rotation about the sensor's z axis and the
// cyclic azimuth order of a ring is preserved, so a scan rotated by any yaw (the same place
// driven in the opposite direction) gives the same vector up to float rounding at bin edges.
//
// Rings: the point's `ring` field when the scan has one (0 = lowest beam); otherwise the ring
// is derived from the elevation angle and the beam layout in the config (VLP-16 defaults:
// -15 deg to +15 deg every 2 deg); points farther than `beam_tolerance_rad` from every beam
// are ignored.
#pragma once

#include <cstddef>
#include <vector>

#include "multisession_mapper/core/place_descriptor.h"
#include "multisession_mapper/core/status.h"
#include "multisession_mapper/core/types.h"

namespace multisession_mapper {
namespace core {

struct RingHistogramDescriptorConfig {
  /// Number of laser rings (VLP-16: 16). Points with ring >= num_rings are ignored.
  int num_rings = 16;
  /// Beam layout used only when the scan has no ring field [rad]: elevation of ring 0, the
  /// spacing between consecutive rings and the largest accepted deviation from a beam.
  double beam_min_elevation_rad = -15.0 * 3.14159265358979323846 / 180.0;
  double beam_spacing_rad = 2.0 * 3.14159265358979323846 / 180.0;
  double beam_tolerance_rad = 0.8 * 3.14159265358979323846 / 180.0;
  /// Range window of the range histogram [m]; returns outside are ignored.
  double min_range_m = 1.0;
  double max_range_m = 100.0;
  /// Bins of the range histogram (logarithmic over [min_range_m, max_range_m]).
  int range_bins = 6;
  /// Bins of the range-difference histogram (see the header comment for the edges) and its
  /// logarithmic window [m].
  int diff_bins = 12;
  double diff_min_m = 0.03;
  double diff_max_m = 10.0;
  /// Weight of the range histogram relative to the range-difference histogram (weight 1).
  /// Ranges change quickly with the sensor's position, range differences much less (LocNet
  /// uses range differences only); tuned on the simulator (see the header comment).
  double range_weight = 0.15;
  /// Rings with fewer valid points contribute a zero block (too few for a histogram).
  int min_points_per_ring = 16;

  /// OK when every field is finite and consistent; otherwise names the bad field.
  Status Validate() const;
};

struct RingHistogramStats {
  std::size_t points_used = 0;  ///< points that entered a histogram
  int rings_used = 0;           ///< rings with at least min_points_per_ring points
};

class RingHistogramDescriptor {
 public:
  /// `config` must be valid (see RingHistogramDescriptorConfig::Validate); Create() checks it.
  static StatusOr<RingHistogramDescriptor> Create(const RingHistogramDescriptorConfig& config);

  /// Descriptor of one scan in the sensor frame (kind kRingHistogram, `key` = the vector).
  /// An empty scan gives the zero vector.
  PlaceDescriptor Compute(const LidarScan& scan, RingHistogramStats* stats = nullptr) const;

  /// Length of the vector: num_rings * (range_bins + diff_bins).
  int dimension() const { return config_.num_rings * (config_.range_bins + config_.diff_bins); }
  const RingHistogramDescriptorConfig& config() const { return config_; }

 private:
  explicit RingHistogramDescriptor(const RingHistogramDescriptorConfig& config)
      : config_(config) {}
  /// Ring of `p`, or -1 when the point belongs to no ring.
  int RingOf(const LidarPoint& p, bool has_ring) const;

  RingHistogramDescriptorConfig config_;
  std::vector<float> range_edges_m_;  // range_bins - 1 inner edges
  std::vector<float> diff_edges_m_;   // diff_bins - 1 edges, diff_min_m first
};

}  // namespace core
}  // namespace multisession_mapper
