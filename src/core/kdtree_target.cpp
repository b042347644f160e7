#include "multisession_mapper/core/kdtree_target.h"

#include <cmath>
#include <string>
#include <utility>

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

struct KdTreeTarget::Impl {
  explicit Impl(PointVector pts) : points(std::move(pts)) {
    adaptor.points = &points;
    tree = std::make_unique<Tree>(3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(10));
    tree->buildIndex();
  }
  PointVector points;
  PointVectorAdaptor adaptor;
  std::unique_ptr<Tree> tree;
  PointVector normals;
  std::vector<bool> planar;
};

StatusOr<KdTreeTarget> KdTreeTarget::Create(PointVector points, const KdTreeTargetConfig& config) {
  const Status status = config.Validate();
  if (!status.ok()) return status;
  if (points.empty()) return Status::Error("kdtree_target: empty target point set");
  for (const Eigen::Vector3d& p : points) {
    if (!p.allFinite()) return Status::Error("kdtree_target: non-finite target point");
  }
  auto impl = std::make_unique<Impl>(std::move(points));
  const std::size_t n = impl->points.size();
  const std::size_t k = std::min<std::size_t>(static_cast<std::size_t>(config.normal_neighbors), n);
  impl->normals.assign(n, Eigen::Vector3d::Zero());
  impl->planar.assign(n, false);
  std::vector<std::size_t> indices(k);
  std::vector<double> dists(k);
  const double radius_sq = config.max_normal_radius_m * config.max_normal_radius_m;
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d& p = impl->points[i];
    const std::size_t found = impl->tree->knnSearch(p.data(), k, indices.data(), dists.data());
    CovarianceAccumulator acc;
    for (std::size_t j = 0; j < found; ++j) {
      if (dists[j] <= radius_sq) acc.Add(impl->points[indices[j]] - p);
    }
    Eigen::Vector3d normal;
    if (acc.Normal(config.plane, &normal)) {
      impl->normals[i] = normal;
      impl->planar[i] = true;
    }
  }
  return KdTreeTarget(std::move(impl));
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
  if (!hints) found->assign(n, 0);
  matches->resize(n);
  const double max_sq = max_distance_m * max_distance_m;
  for (std::size_t i = 0; i < n; ++i) {
    const bool previous = hints && (*found)[i] != 0;
    const double bound_sq =
        WarmStartBoundSq(previous ? &(*matches)[i] : nullptr, queries[i], max_sq);
    (*found)[i] = MatchWithin(queries[i], bound_sq, &(*matches)[i]) ? 1 : 0;
  }
}

bool KdTreeTarget::MatchWithin(const Eigen::Vector3d& query, double bound_sq,
                               TargetMatch* match) const {
  std::size_t index = 0;
  double dist_sq = 0.0;
  if (!NearestWithinSq(query, bound_sq, &index, &dist_sq)) return false;
  match->point = impl_->points[index];
  match->distance_sq = dist_sq;
  match->has_normal = impl_->planar[index];
  match->normal = impl_->normals[index];
  return true;
}

double KdTreeTarget::PlanarFraction() const {
  if (empty()) return 0.0;
  std::size_t n = 0;
  for (bool b : impl_->planar) n += b ? 1 : 0;
  return static_cast<double>(n) / static_cast<double>(impl_->planar.size());
}

}  // namespace core
}  // namespace multisession_mapper
