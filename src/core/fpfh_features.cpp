#include "multisession_mapper/core/fpfh_features.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "multisession_mapper/core/point_index.h"

namespace multisession_mapper {
namespace core {

namespace {

// Bin of an angle feature in [low, low + span] (PCL's arithmetic: the feature in float, the
// scaling in double), clamped to the histogram.
int Bin(double scaled) {
  const int b = static_cast<int>(std::floor(scaled));
  return std::min(std::max(b, 0), kFpfhBinsPerAngle - 1);
}

// The three bins of the pair (p1, n1) - (p2, n2) as pcl::computePairFeatures and PCL's
// SPFH binning give them for the SPFH of p1. The source of the Darboux frame is the end whose
// normal is closer to the line between them, decided as PCL does: swap when acos(|angle1|) >
// acos(|angle2|). Then the triple does not depend on the order of the pair, except on a tie
// of the two acos (equal normals, say), where PCL keeps the order it was given: `tie` tells
// the caller to compute the other end's bins with the ends exchanged. False where PCL's is:
// the points coincide, or the source normal is parallel to the line between them.
// The arithmetic is PCL's to the bit (4-float Eigen vectors with a zero fourth component, the
// same operations in the same order): on a plane the normals of neighbours are nearly equal,
// the two angles nearly tie, and which end becomes the source (and so the sign of f3) turns
// on the last bit of each.
bool PairBins(const Eigen::Vector4f& p1, const Eigen::Vector4f& n1, const Eigen::Vector4f& p2,
              const Eigen::Vector4f& n2, int bins[3], bool* tie) {
  Eigen::Vector4f dp = p2 - p1;
  dp[3] = 0.0f;
  const float distance = dp.norm();
  *tie = false;
  if (distance == 0.0f) return false;
  const float angle1 = n1.dot(dp) / distance;
  const float angle2 = n2.dot(dp) / distance;
  // acos falls with a slope of at least 1, so inputs 1e-5 apart never round to one output:
  // the two acos are needed only for close values.
  const float abs1 = std::fabs(angle1), abs2 = std::fabs(angle2);
  bool swap = abs1 < abs2;
  if (std::fabs(abs1 - abs2) <= 1e-5f) {
    const float acos1 = std::acos(abs1), acos2 = std::acos(abs2);
    swap = acos1 > acos2;
    *tie = acos1 == acos2;
  }
  const Eigen::Vector4f* u = &n1;
  const Eigen::Vector4f* other = &n2;
  float f3 = angle1;
  if (swap) {
    u = &n2;
    other = &n1;
    dp *= -1.0f;
    f3 = -angle2;
  }
  Eigen::Vector4f v = dp.cross3(*u);
  v[3] = 0.0f;
  const float v_norm = v.norm();
  if (v_norm == 0.0f) return false;
  v /= v_norm;
  Eigen::Vector4f w = u->cross3(v);
  w[3] = 0.0f;
  const float f2 = v.dot(*other);
  const float f1 = std::atan2(w.dot(*other), u->dot(*other));
  // As pcl::FPFHEstimation::computePointSPFHSignature bins them.
  const double inv_two_pi = static_cast<double>(1.0f / (2.0f * static_cast<float>(M_PI)));
  bins[0] = Bin(kFpfhBinsPerAngle * ((f1 + M_PI) * inv_two_pi));
  bins[1] = kFpfhBinsPerAngle + Bin(kFpfhBinsPerAngle * ((f2 + 1.0) * 0.5));
  bins[2] = 2 * kFpfhBinsPerAngle + Bin(kFpfhBinsPerAngle * ((f3 + 1.0) * 0.5));
  return true;
}

bool HasNormal(const Eigen::Vector3d& n) { return n.allFinite() && n.squaredNorm() > 0.5; }

}  // namespace

StatusOr<std::vector<float>> ComputeFpfh(const PointVector& points,
                                         const std::vector<Eigen::Vector3d>& normals,
                                         double radius_m, std::vector<std::uint8_t>* defined) {
  if (normals.size() != points.size()) {
    return Status::Error("fpfh: " + std::to_string(normals.size()) + " normals for " +
                         std::to_string(points.size()) + " points");
  }
  if (!(radius_m > 0.0) || !std::isfinite(radius_m)) {
    return Status::Error("fpfh: radius must be > 0");
  }
  if (defined == nullptr) return Status::Error("fpfh: no output for the defined flags");
  StatusOr<PointIndex> index = PointIndex::Create(points);
  if (!index.ok()) return Status::Error("fpfh: " + index.status().message());
  const std::size_t n = points.size();
  // Points and normals as PCL holds them (fourth component 1 and 0).
  std::vector<Eigen::Vector4f, Eigen::aligned_allocator<Eigen::Vector4f>> p(n), nrm(n);
  std::vector<std::uint8_t> has_normal(n);
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3f q = points[i].cast<float>();
    p[i] = Eigen::Vector4f(q.x(), q.y(), q.z(), 1.0f);
    has_normal[i] = HasNormal(normals[i]) ? 1 : 0;
    const Eigen::Vector3f m = has_normal[i] ? Eigen::Vector3f(normals[i].cast<float>())
                                            : Eigen::Vector3f::Zero();
    nrm[i] = Eigen::Vector4f(m.x(), m.y(), m.z(), 0.0f);
  }

  // Neighbour lists (CSR) of the points with a normal: the point itself and the points
  // without a normal left out. Squared distances in float, as PCL's search reports them.
  std::vector<std::size_t> first(n + 1, 0);
  std::vector<std::uint32_t> neighbour;
  std::vector<float> distance_sq;
  std::vector<std::uint32_t> found;
  for (std::size_t i = 0; i < n; ++i) {
    first[i + 1] = first[i];
    if (!has_normal[i]) continue;
    index.value().Radius(points[i], radius_m, &found);  // in the same order on every run
    for (const std::uint32_t j : found) {
      if (j == i || !has_normal[j]) continue;
      neighbour.push_back(j);
      distance_sq.push_back((p[j] - p[i]).head<3>().squaredNorm());
    }
    first[i + 1] = neighbour.size();
  }

  // SPFH: each pair once (twice on a tie), its bins counted for both ends. PCL's increment is
  // 100 over the number of neighbours, whether or not their pair features exist.
  // Counts per bin first (exact in float up to 2^24), scaled into the SPFH below.
  std::vector<float> spfh(n * kFpfhBins, 0.0f);
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t k = first[i]; k < first[i + 1]; ++k) {
      const std::uint32_t j = neighbour[k];
      if (j < i) continue;
      int bins[3];
      bool tie = false;
      const bool paired = PairBins(p[i], nrm[i], p[j], nrm[j], bins, &tie);
      if (paired) {
        for (const int b : bins) spfh[i * kFpfhBins + b] += 1.0f;
      }
      if (tie) {  // j's own view of the pair
        bool again = false;
        if (!PairBins(p[j], nrm[j], p[i], nrm[i], bins, &again)) continue;
      } else if (!paired) {
        continue;
      }
      for (const int b : bins) spfh[static_cast<std::size_t>(j) * kFpfhBins + b] += 1.0f;
    }
  }
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t neighbours = first[i + 1] - first[i];
    if (neighbours == 0) continue;
    const float increment = 100.0f / static_cast<float>(neighbours);
    for (int b = 0; b < kFpfhBins; ++b) spfh[i * kFpfhBins + b] *= increment;
  }

  // FPFH: the neighbours' SPFHs weighted by 1 / squared distance (the point's own is not part
  // of PCL's sum), each angle's block normalised to 100.
  std::vector<float> features(n * kFpfhBins, 0.0f);
  defined->assign(n, 0);
  for (std::size_t i = 0; i < n; ++i) {
    if (!has_normal[i]) continue;
    float* out = features.data() + i * kFpfhBins;
    for (std::size_t k = first[i]; k < first[i + 1]; ++k) {
      if (distance_sq[k] == 0.0f) continue;
      const float weight = 1.0f / distance_sq[k];
      const float* row = spfh.data() + static_cast<std::size_t>(neighbour[k]) * kFpfhBins;
      for (int b = 0; b < kFpfhBins; ++b) out[b] += row[b] * weight;
    }
    bool all_blocks = true;
    for (int block = 0; block < 3; ++block) {
      float* h = out + block * kFpfhBinsPerAngle;
      float sum = 0.0f;
      for (int b = 0; b < kFpfhBinsPerAngle; ++b) sum += h[b];
      if (sum > 0.0f) {
        const float scale = 100.0f / sum;
        for (int b = 0; b < kFpfhBinsPerAngle; ++b) h[b] *= scale;
      } else {
        all_blocks = false;
      }
    }
    if (all_blocks) {
      (*defined)[i] = 1;
    } else {
      std::fill(out, out + kFpfhBins, 0.0f);
    }
  }
  return features;
}

}  // namespace core
}  // namespace multisession_mapper
