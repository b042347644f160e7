#include "multisession_mapper/core/point_index.h"

#include <algorithm>
#include <utility>

#include "multisession_mapper/core/point_vector_adaptor.h"

namespace multisession_mapper {
namespace core {

namespace {

using Tree = PointVectorKdTree<std::uint32_t>;

// Collects indices within a squared radius; stops after `cap` (0: no cap).
class IndexCollector {
 public:
  IndexCollector(double radius_sq, std::size_t cap, std::vector<std::uint32_t>* out)
      : radius_sq_(radius_sq), cap_(cap), out_(out) {}
  std::size_t size() const { return out_->size(); }
  bool full() const { return true; }
  double worstDist() const { return radius_sq_; }
  bool addPoint(double dist, std::uint32_t index) {
    if (dist <= radius_sq_) out_->push_back(index);
    return cap_ == 0 || out_->size() < cap_;
  }

 private:
  double radius_sq_;
  std::size_t cap_;
  std::vector<std::uint32_t>* out_;
};

// The k nearest points within a squared radius, nearest first. The radius bounds the search
// from the start (an unbounded k-nearest search then filtered by the radius explores far
// branches wherever fewer than k points are near: half of a merge's dynamic-detection time).
class BoundedKNearest {
 public:
  BoundedKNearest(std::size_t k, double radius_sq) : k_(k), radius_sq_(radius_sq) {
    best_.reserve(k + 1);
  }
  std::size_t size() const { return best_.size(); }
  bool full() const { return true; }
  double worstDist() const { return best_.size() < k_ ? radius_sq_ : best_.back().first; }
  bool addPoint(double dist, std::uint32_t index) {
    if (dist > worstDist()) return true;
    // After the entries of equal distance, as nanoflann's KNNResultSet keeps them.
    const auto at = std::upper_bound(
        best_.begin(), best_.end(), dist,
        [](double d, const std::pair<double, std::uint32_t>& e) { return d < e.first; });
    best_.insert(at, {dist, index});
    if (best_.size() > k_) best_.pop_back();
    return true;
  }
  const std::vector<std::pair<double, std::uint32_t>>& best() const { return best_; }

 private:
  std::size_t k_;
  double radius_sq_;
  std::vector<std::pair<double, std::uint32_t>> best_;
};

}  // namespace

struct PointIndex::Impl {
  explicit Impl(PointVector pts) : points(std::move(pts)) {
    adaptor.points = &points;
    tree = std::make_unique<Tree>(3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(10));
    if (!points.empty()) tree->buildIndex();
  }
  PointVector points;
  PointVectorAdaptor adaptor;
  std::unique_ptr<Tree> tree;
};

StatusOr<PointIndex> PointIndex::Create(PointVector points) {
  for (const Eigen::Vector3d& p : points) {
    if (!p.allFinite()) return Status::Error("point_index: non-finite point");
  }
  return PointIndex(std::make_unique<Impl>(std::move(points)));
}

PointIndex::PointIndex(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
PointIndex::PointIndex(PointIndex&&) noexcept = default;
PointIndex& PointIndex::operator=(PointIndex&&) noexcept = default;
PointIndex::~PointIndex() = default;

const PointVector& PointIndex::points() const { return impl_->points; }

bool PointIndex::Nearest(const Eigen::Vector3d& query, std::uint32_t* index,
                         double* distance_sq) const {
  if (impl_->points.empty()) return false;
  std::uint32_t i = 0;
  double d = 0.0;
  if (impl_->tree->knnSearch(query.data(), 1, &i, &d) == 0) return false;
  *index = i;
  *distance_sq = d;
  return true;
}

bool PointIndex::NearestWithin(const Eigen::Vector3d& query, double max_radius_m,
                               std::uint32_t* index, double* distance_sq) const {
  if (impl_->points.empty()) return false;
  BoundedNearest<std::uint32_t> result(max_radius_m * max_radius_m);
  impl_->tree->findNeighbors(result, query.data(), nanoflann::SearchParams(32, 0.0f, false));
  if (!result.found()) return false;
  *index = result.index();
  *distance_sq = result.distance_sq();
  return true;
}

void PointIndex::Radius(const Eigen::Vector3d& query, double radius_m,
                        std::vector<std::uint32_t>* out) const {
  out->clear();
  if (impl_->points.empty()) return;
  IndexCollector collector(radius_m * radius_m, 0, out);
  impl_->tree->findNeighbors(collector, query.data(), nanoflann::SearchParams(32, 0.0f, false));
}

std::size_t PointIndex::CountWithin(const Eigen::Vector3d& query, double radius_m,
                                    std::size_t cap) const {
  if (impl_->points.empty()) return 0;
  std::vector<std::uint32_t> found;
  IndexCollector collector(radius_m * radius_m, cap, &found);
  impl_->tree->findNeighbors(collector, query.data(), nanoflann::SearchParams(32, 0.0f, false));
  return found.size();
}

void PointIndex::Nearest(const Eigen::Vector3d& query, std::size_t k, double max_radius_m,
                         std::vector<std::uint32_t>* out) const {
  out->clear();
  if (impl_->points.empty() || k == 0) return;
  BoundedKNearest result(k, max_radius_m * max_radius_m);
  impl_->tree->findNeighbors(result, query.data(), nanoflann::SearchParams(32, 0.0f, false));
  for (const auto& [distance_sq, index] : result.best()) out->push_back(index);
}

}  // namespace core
}  // namespace multisession_mapper
