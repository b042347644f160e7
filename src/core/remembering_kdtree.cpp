#include "multisession_mapper/core/remembering_kdtree.h"

namespace multisession_mapper {
namespace core {

RememberingKdTree::RememberingKdTree(double radius_m) : radius_m_(radius_m) {}

void RememberingKdTree::setInputCloud(const PointCloudConstPtr& cloud,
                                      const IndicesConstPtr& indices) {
  memory_.clear();
  Base::setInputCloud(cloud, indices);
}

int RememberingKdTree::radiusSearch(const pcl::PointCloud<pcl::PointXYZ>& cloud,
                                    pcl::index_t index, double radius, pcl::Indices& k_indices,
                                    std::vector<float>& k_sqr_distances,
                                    unsigned int max_nn) const {
  const bool remembered_kind = radius == radius_m_ && max_nn == 0 && &cloud == input_.get() &&
                               index >= 0 && static_cast<std::size_t>(index) < cloud.size();
  if (!remembered_kind) {
    return Base::radiusSearch(cloud, index, radius, k_indices, k_sqr_distances, max_nn);
  }
  if (memory_.size() != cloud.size()) memory_.assign(cloud.size(), Entry());
  Entry& entry = memory_[static_cast<std::size_t>(index)];
  if (entry.stored) {  // the second search: hand the result over and forget it
    k_indices.swap(entry.indices);
    k_sqr_distances.swap(entry.sqr_distances);
    entry = Entry();
    ++remembered_answers_;
    return static_cast<int>(k_indices.size());
  }
  const int found = Base::radiusSearch(cloud, index, radius, k_indices, k_sqr_distances, 0);
  entry.indices = k_indices;
  entry.sqr_distances = k_sqr_distances;
  entry.stored = true;
  return found;
}

}  // namespace core
}  // namespace multisession_mapper
