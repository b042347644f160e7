#include "multisession_mapper/core/ring_histogram_descriptor.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

namespace multisession_mapper {
namespace core {
namespace {

// Monotone in atan2(y, x) mapped to [0, 4): same ordering, no trigonometry (the descriptor
// budget is ~1 ms per scan). Caller guarantees (x, y) != (0, 0).
float PseudoAngle(float x, float y) {
  const float p = x / (std::fabs(x) + std::fabs(y));
  return y < 0.0f ? 3.0f + p : 1.0f - p;
}

struct Return {
  float angle;  // PseudoAngle
  float range;  // [m]
};

// Sorts one ring by angle in linear time: counting sort into buckets ~0.1 deg wide (finer than
// a beam's azimuth step, so they hold 0-2 returns), then insertion sort inside buckets.
void SortByAngle(std::vector<Return>* ring, std::vector<std::uint32_t>* start,
                 std::vector<Return>* scratch) {
  constexpr int kBuckets = 4096;
  constexpr float kBucketScale = kBuckets / 4.0f;
  const auto bucket = [](float angle) {
    return std::min(static_cast<int>(angle * kBucketScale), kBuckets - 1);
  };
  start->assign(kBuckets + 1, 0);
  for (const Return& r : *ring) ++(*start)[static_cast<std::size_t>(bucket(r.angle)) + 1];
  for (int b = 0; b < kBuckets; ++b) (*start)[b + 1] += (*start)[b];
  scratch->resize(ring->size());
  for (const Return& r : *ring) {
    (*scratch)[(*start)[static_cast<std::size_t>(bucket(r.angle))]++] = r;
  }
  for (std::size_t i = 1; i < scratch->size(); ++i) {
    const Return v = (*scratch)[i];
    std::size_t j = i;
    while (j > 0 && (*scratch)[j - 1].angle > v.angle) {
      (*scratch)[j] = (*scratch)[j - 1];
      --j;
    }
    (*scratch)[j] = v;
  }
  ring->swap(*scratch);
}

}  // namespace

Status RingHistogramDescriptorConfig::Validate() const {
  const std::string p = "ring_histogram_descriptor.";
  if (num_rings < 1 || num_rings > 1024) {
    return Status::Error(p + "num_rings must be in [1, 1024], got " + std::to_string(num_rings));
  }
  if (!std::isfinite(beam_min_elevation_rad) || std::fabs(beam_min_elevation_rad) > M_PI / 2) {
    return Status::Error(p + "beam_min_elevation_rad must be finite and in [-pi/2, pi/2]");
  }
  if (!std::isfinite(beam_spacing_rad) || beam_spacing_rad <= 0.0) {
    return Status::Error(p + "beam_spacing_rad must be finite and > 0");
  }
  if (!std::isfinite(beam_tolerance_rad) || beam_tolerance_rad <= 0.0) {
    return Status::Error(p + "beam_tolerance_rad must be finite and > 0");
  }
  if (!std::isfinite(min_range_m) || min_range_m <= 0.0) {
    return Status::Error(p + "min_range_m must be finite and > 0 (log bins), got " +
                         std::to_string(min_range_m));
  }
  if (!std::isfinite(max_range_m) || max_range_m <= min_range_m) {
    return Status::Error(p + "max_range_m must be finite and > min_range_m, got " +
                         std::to_string(max_range_m));
  }
  if (range_bins < 1 || range_bins > 1000) {
    return Status::Error(p + "range_bins must be in [1, 1000], got " + std::to_string(range_bins));
  }
  if (diff_bins < 3 || diff_bins > 1000) {
    return Status::Error(p + "diff_bins must be in [3, 1000], got " + std::to_string(diff_bins));
  }
  if (!std::isfinite(diff_min_m) || diff_min_m <= 0.0) {
    return Status::Error(p + "diff_min_m must be finite and > 0");
  }
  if (!std::isfinite(diff_max_m) || diff_max_m <= diff_min_m) {
    return Status::Error(p + "diff_max_m must be finite and > diff_min_m");
  }
  if (!std::isfinite(range_weight) || range_weight < 0.0 || range_weight > 100.0) {
    return Status::Error(p + "range_weight must be in [0, 100], got " +
                         std::to_string(range_weight));
  }
  if (min_points_per_ring < 2) {
    return Status::Error(p + "min_points_per_ring must be >= 2, got " +
                         std::to_string(min_points_per_ring));
  }
  return Status::Ok();
}

StatusOr<RingHistogramDescriptor> RingHistogramDescriptor::Create(
    const RingHistogramDescriptorConfig& config) {
  Status status = config.Validate();
  if (!status.ok()) return status;
  RingHistogramDescriptor descriptor(config);
  // Inner bin edges (see the header): logarithmic over [min_range_m, max_range_m] for ranges;
  // diff_min_m, logarithmic steps, diff_max_m for range differences.
  const double range_ratio = config.max_range_m / config.min_range_m;
  for (int i = 1; i < config.range_bins; ++i) {
    descriptor.range_edges_m_.push_back(static_cast<float>(
        config.min_range_m * std::pow(range_ratio, double(i) / config.range_bins)));
  }
  const double diff_ratio = config.diff_max_m / config.diff_min_m;
  for (int i = 0; i <= config.diff_bins - 2; ++i) {
    descriptor.diff_edges_m_.push_back(static_cast<float>(
        config.diff_min_m * std::pow(diff_ratio, double(i) / (config.diff_bins - 2))));
  }
  return descriptor;
}

int RingHistogramDescriptor::RingOf(const LidarPoint& p, bool has_ring) const {
  if (has_ring) return p.ring < config_.num_rings ? static_cast<int>(p.ring) : -1;
  const double horizontal = std::hypot(p.position_m.x(), p.position_m.y());
  const double elevation = std::atan2(p.position_m.z(), horizontal);
  const double index = (elevation - config_.beam_min_elevation_rad) / config_.beam_spacing_rad;
  const long ring = std::lround(index);
  if (ring < 0 || ring >= config_.num_rings) return -1;
  const double off_rad = std::fabs(index - static_cast<double>(ring)) * config_.beam_spacing_rad;
  return off_rad <= config_.beam_tolerance_rad ? static_cast<int>(ring) : -1;
}

PlaceDescriptor RingHistogramDescriptor::Compute(const LidarScan& scan,
                                                 RingHistogramStats* stats) const {
  const RingHistogramDescriptorConfig& c = config_;
  const int block = c.range_bins + c.diff_bins;
  PlaceDescriptor out;
  out.kind = DescriptorKind::kRingHistogram;
  out.key.assign(static_cast<std::size_t>(dimension()), 0.0f);

  // Returns of each ring in input order. Drivers deliver a ring in firing (azimuth) order, so
  // the sequence is usually already in cyclic azimuth order (one wrap of the azimuth origin),
  // which is all the cyclic differences need; otherwise the ring is sorted by pseudo-angle.
  std::vector<std::vector<Return>> rings(static_cast<std::size_t>(c.num_rings));
  const std::size_t expected = scan.points.size() / static_cast<std::size_t>(c.num_rings) + 16;
  for (auto& ring : rings) ring.reserve(expected);
  const float min_sq = static_cast<float>(c.min_range_m * c.min_range_m);
  const float max_sq = static_cast<float>(c.max_range_m * c.max_range_m);
  for (const LidarPoint& p : scan.points) {
    const float x = p.position_m.x();
    const float y = p.position_m.y();
    const float range_sq = p.position_m.squaredNorm();
    // The negated comparisons also drop NaN.
    if (!(range_sq >= min_sq && range_sq <= max_sq)) continue;
    if (x == 0.0f && y == 0.0f) continue;  // azimuth undefined
    const int ring = scan.has_ring ? (p.ring < c.num_rings ? static_cast<int>(p.ring) : -1)
                                   : RingOf(p, false);
    if (ring < 0) continue;
    rings[static_cast<std::size_t>(ring)].push_back({PseudoAngle(x, y), std::sqrt(range_sq)});
  }

  const float scale =
      static_cast<float>(1.0 / std::sqrt(c.num_rings * (1.0 + c.range_weight * c.range_weight)));
  const float range_scale = static_cast<float>(c.range_weight) * scale;
  RingHistogramStats local;
  std::vector<float> hist(static_cast<std::size_t>(block));
  std::vector<std::uint32_t> sort_start;
  std::vector<Return> sort_scratch;
  for (int r = 0; r < c.num_rings; ++r) {
    std::vector<Return>& ring = rings[static_cast<std::size_t>(r)];
    const int n = static_cast<int>(ring.size());
    if (n < c.min_points_per_ring) continue;
    // Cyclically sorted in either direction (Velodynes spin clockwise: azimuth decreases)?
    // |differences| are the same both ways round.
    const float wrap = ring[static_cast<std::size_t>(n - 1)].angle - ring[0].angle;
    int descents = wrap > 0.0f ? 1 : 0;
    int ascents = wrap < 0.0f ? 1 : 0;
    for (std::size_t i = 1; i < ring.size() && (descents <= 1 || ascents <= 1); ++i) {
      descents += ring[i - 1].angle > ring[i].angle;
      ascents += ring[i - 1].angle < ring[i].angle;
    }
    if (descents > 1 && ascents > 1) SortByAngle(&ring, &sort_start, &sort_scratch);
    const Return* pts = ring.data();
    std::fill(hist.begin(), hist.end(), 0.0f);
    float* range_hist = hist.data();
    float* diff_hist = hist.data() + c.range_bins;
    for (int k = 0; k < n; ++k) {
      const float rho = pts[k].range;
      range_hist[std::upper_bound(range_edges_m_.begin(), range_edges_m_.end(), rho) -
                 range_edges_m_.begin()] += 1.0f;
      const float diff = std::fabs(pts[k + 1 < n ? k + 1 : 0].range - rho);
      diff_hist[std::upper_bound(diff_edges_m_.begin(), diff_edges_m_.end(), diff) -
                diff_edges_m_.begin()] += 1.0f;
    }
    // Both histograms hold n counts: normalise to a probability, then square-root (Hellinger).
    const float inv_n = 1.0f / static_cast<float>(n);
    float* dst = out.key.data() + static_cast<std::ptrdiff_t>(r) * block;
    for (int b = 0; b < block; ++b) {
      dst[b] = std::sqrt(hist[static_cast<std::size_t>(b)] * inv_n) *
               (b < c.range_bins ? range_scale : scale);
    }
    local.points_used += static_cast<std::size_t>(n);
    ++local.rings_used;
  }
  if (stats != nullptr) *stats = local;
  return out;
}

}  // namespace core
}  // namespace multisession_mapper
