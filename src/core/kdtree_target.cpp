#include "multisession_mapper/core/kdtree_target.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "multisession_mapper/core/point_vector_adaptor.h"

namespace multisession_mapper {
namespace core {

Status KdTreeTargetConfig::Validate() const {
  if (normal_neighbors < 3) {
    return Status::Error("kdtree_target.normal_neighbors must be >= 3, got " +
                         std::to_string(normal_neighbors));
  }
  if (!std::isfinite(max_normal_radius_m) || max_normal_radius_m <= 0.0) {
    return Status::Error("kdtree_target.max_normal_radius_m must be > 0, got " +
                         std::to_string(max_normal_radius_m));
  }
  return plane.Validate();
}

using Tree = PointVectorKdTree<std::size_t>;

// A query without a match within the correspondence distance d is searched within
// (1 + this) * d, so that while it moves less than the margin it needs no search again (see
// FindMatches).
constexpr double kMissReachFraction = 0.25;

// Normals are computed on first use: an ICP matches a small part of a submap's points (a
// 1.5 m source against a 0.3 m target), and fitting all of them made the fine target of a
// `campus` submap cost 0.06-0.17 s, most of a history submap's preparation for the global
// registration. A normal is the same whenever it is computed (a fixed k-NN search), so a query
// that finds it being stored by another thread computes its own copy instead of waiting.
struct KdTreeTarget::Impl {
  enum : std::uint8_t { kUnknown = 0, kStoring = 1, kReady = 2 };

  Impl(PointVector pts, const KdTreeTargetConfig& cfg)
      : points(std::move(pts)),
        config(cfg),
        normals(points.size(), Eigen::Vector3d::Zero()),
        planar(points.size(), 0),
        state(new std::atomic<std::uint8_t>[points.size()]) {
    for (std::size_t i = 0; i < points.size(); ++i) {
      state[i].store(kUnknown, std::memory_order_relaxed);
    }
    adaptor.points = &points;
    tree = std::make_unique<Tree>(3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(10));
    tree->buildIndex();
  }

  // The PCA normal of points[i] from its k nearest neighbours within the radius; false when
  // the neighbourhood is not planar.
  bool FitNormal(std::size_t i, Eigen::Vector3d* normal) const {
    const std::size_t k =
        std::min<std::size_t>(static_cast<std::size_t>(config.normal_neighbors), points.size());
    // No allocation for the usual neighbour counts: this runs inside ICP iterations.
    constexpr std::size_t kOnStack = 64;
    std::array<std::size_t, kOnStack> stack_indices;
    std::array<double, kOnStack> stack_dists;
    std::vector<std::size_t> heap_indices(k > kOnStack ? k : 0);
    std::vector<double> heap_dists(k > kOnStack ? k : 0);
    std::size_t* indices = k > kOnStack ? heap_indices.data() : stack_indices.data();
    double* dists = k > kOnStack ? heap_dists.data() : stack_dists.data();
    const double radius_sq = config.max_normal_radius_m * config.max_normal_radius_m;
    const Eigen::Vector3d& p = points[i];
    const std::size_t found = tree->knnSearch(p.data(), k, indices, dists);
    CovarianceAccumulator acc;
    for (std::size_t j = 0; j < found; ++j) {
      if (dists[j] <= radius_sq) acc.Add(points[indices[j]] - p);
    }
    return acc.Normal(config.plane, normal);
  }

  // The normal of points[i] (zero when not planar); computed and stored on first use.
  bool NormalAt(std::size_t i, Eigen::Vector3d* normal) const {
    if (state[i].load(std::memory_order_acquire) == kReady) {
      *normal = normals[i];
      return planar[i] != 0;
    }
    Eigen::Vector3d fitted = Eigen::Vector3d::Zero();
    const bool is_planar = FitNormal(i, &fitted);
    if (!is_planar) fitted.setZero();
    std::uint8_t expected = kUnknown;
    if (state[i].compare_exchange_strong(expected, kStoring, std::memory_order_acq_rel)) {
      normals[i] = fitted;
      planar[i] = is_planar ? 1 : 0;
      state[i].store(kReady, std::memory_order_release);
    }
    *normal = fitted;
    return is_planar;
  }

  // The match of points[index] at `distance_sq` from the query, with its normal.
  void Match(std::size_t index, double distance_sq, TargetMatch* match) const {
    match->point = points[index];
    match->distance_sq = distance_sq;
    match->has_normal = NormalAt(index, &match->normal);
  }

  PointVector points;
  KdTreeTargetConfig config;
  PointVectorAdaptor adaptor;
  std::unique_ptr<Tree> tree;
  // Written once per point under `state` (kUnknown -> kStoring -> kReady).
  mutable PointVector normals;
  mutable std::vector<std::uint8_t> planar;
  std::unique_ptr<std::atomic<std::uint8_t>[]> state;
};

StatusOr<KdTreeTarget> KdTreeTarget::Create(PointVector points, const KdTreeTargetConfig& config) {
  const Status status = config.Validate();
  if (!status.ok()) return status;
  if (points.empty()) return Status::Error("kdtree_target: empty target point set");
  for (const Eigen::Vector3d& p : points) {
    if (!p.allFinite()) return Status::Error("kdtree_target: non-finite target point");
  }
  return KdTreeTarget(std::make_unique<Impl>(std::move(points), config));
}

KdTreeTarget::KdTreeTarget(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
KdTreeTarget::KdTreeTarget(KdTreeTarget&&) noexcept = default;
KdTreeTarget& KdTreeTarget::operator=(KdTreeTarget&&) noexcept = default;
KdTreeTarget::~KdTreeTarget() = default;

bool KdTreeTarget::empty() const { return impl_ == nullptr || impl_->points.empty(); }

const PointVector& KdTreeTarget::points() const { return impl_->points; }

bool KdTreeTarget::NearestWithin(const Eigen::Vector3d& query, double max_distance_m,
                                 std::size_t* index, double* distance_sq) const {
  return NearestWithinSq(query, max_distance_m * max_distance_m, index, distance_sq);
}

bool KdTreeTarget::NearestWithinSq(const Eigen::Vector3d& query, double bound_sq,
                                   std::size_t* index, double* distance_sq) const {
  if (empty()) return false;
  BoundedNearest<std::size_t> result(bound_sq);
  impl_->tree->findNeighbors(result, query.data(), nanoflann::SearchParams(32, 0.0f, false));
  if (!result.found()) return false;
  *index = result.index();
  *distance_sq = result.distance_sq();
  return true;
}

bool KdTreeTarget::FindMatch(const Eigen::Vector3d& query, double max_distance_m,
                             TargetMatch* match) const {
  return MatchWithin(query, max_distance_m * max_distance_m, match);
}

void KdTreeTarget::FindMatches(const PointVector& queries, double max_distance_m,
                               bool warm_start, WorkerPool* /*pool*/,
                               std::vector<std::uint8_t>* found,
                               std::vector<TargetMatch>* matches) const {
  const std::size_t n = queries.size();
  const bool hints = warm_start && found->size() == n && matches->size() == n;
  if (!hints) {
    found->assign(n, 0);
    matches->assign(n, TargetMatch());  // no memo of a miss either (distance_sq 0)
  }
  const double max_sq = max_distance_m * max_distance_m;
  const double reach = max_distance_m * (1.0 + kMissReachFraction);
  const double reach_sq = reach * reach;
  for (std::size_t i = 0; i < n; ++i) {
    TargetMatch& match = (*matches)[i];
    if ((*found)[i] != 0 && hints) {
      (*found)[i] = MatchWithin(queries[i], WarmStartBoundSq(&match, queries[i], max_sq), &match)
                        ? 1
                        : 0;
      if ((*found)[i] != 0) continue;
      match = TargetMatch();  // its match moved beyond max_distance_m: a miss now
    }
    // A miss remembers, in its unused match, where it was searched and how far the nearest
    // point was at least (the distance found within `reach`, or `reach`). Moved by less than
    // that bound minus max_distance_m, it still has no point within max_distance_m (triangle
    // inequality; 1e-9 m for rounding): no search. Otherwise it is searched within `reach`,
    // which finds its match, if any, as a search within max_distance_m does (the nearest
    // point is the nearest point), and the new bound.
    if (hints && match.distance_sq > 0.0) {
      const double bound = std::sqrt(match.distance_sq);
      if (bound - (queries[i] - match.point).norm() > max_distance_m + 1e-9) continue;
    }
    std::size_t index = 0;
    double dist_sq = 0.0;
    if (NearestWithinSq(queries[i], reach_sq, &index, &dist_sq) && dist_sq <= max_sq) {
      (*found)[i] = 1;
      impl_->Match(index, dist_sq, &match);
      continue;
    }
    (*found)[i] = 0;
    match = TargetMatch();
    match.point = queries[i];
    match.distance_sq = dist_sq > max_sq ? dist_sq : reach_sq;  // dist_sq 0: none in reach
  }
}

bool KdTreeTarget::MatchWithin(const Eigen::Vector3d& query, double bound_sq,
                               TargetMatch* match) const {
  std::size_t index = 0;
  double dist_sq = 0.0;
  if (!NearestWithinSq(query, bound_sq, &index, &dist_sq)) return false;
  impl_->Match(index, dist_sq, match);
  return true;
}

double KdTreeTarget::PlanarFraction() const {
  if (empty()) return 0.0;
  std::size_t n = 0;
  Eigen::Vector3d normal;
  for (std::size_t i = 0; i < impl_->points.size(); ++i) {
    n += impl_->NormalAt(i, &normal) ? 1 : 0;
  }
  return static_cast<double>(n) / static_cast<double>(impl_->points.size());
}

}  // namespace core
}  // namespace multisession_mapper
