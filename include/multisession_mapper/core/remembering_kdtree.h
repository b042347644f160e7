// PCL's kd-tree search that remembers its radius searches of one radius around the points of
// its own cloud until each has been asked for a second time.
//
// Why: PCL's FPFHEstimation searches the neighbourhood of every point twice, once for the
// point's SPFH and once to weight the SPFHs of its neighbours. With this search the second one
// is served from memory, with the same neighbours in the same order, so the features are bit
// for bit PCL's (remembering_kdtree_test). Measured with global_registration_benchmark on the
// `campus` seed 1 s00 map (20 overlapping and 20 mirrored pairs, same run): the same 40
// results, 0.87 -> 0.81 s per pair; merging s01 into the s00 map: matching 1-2 s faster.
//
// Searches with another radius, a neighbour limit or another cloud go to the kd-tree as
// usual. Not thread-safe (a const search writes the memory): one instance per thread.
#pragma once

#include <vector>

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/search/kdtree.h>

namespace multisession_mapper {
namespace core {

class RememberingKdTree : public pcl::search::KdTree<pcl::PointXYZ> {
 public:
  using Base = pcl::search::KdTree<pcl::PointXYZ>;
  using Base::radiusSearch;

  /// Remembers the searches of this radius [m].
  explicit RememberingKdTree(double radius_m);

  /// A new cloud forgets everything remembered.
  void setInputCloud(const PointCloudConstPtr& cloud,
                     const IndicesConstPtr& indices = IndicesConstPtr()) override;

  int radiusSearch(const pcl::PointCloud<pcl::PointXYZ>& cloud, pcl::index_t index,
                   double radius, pcl::Indices& k_indices, std::vector<float>& k_sqr_distances,
                   unsigned int max_nn = 0) const override;

  /// Searches answered from memory so far.
  std::size_t remembered_answers() const { return remembered_answers_; }

 private:
  struct Entry {
    pcl::Indices indices;
    std::vector<float> sqr_distances;
    bool stored = false;
  };
  double radius_m_;
  mutable std::vector<Entry> memory_;
  mutable std::size_t remembered_answers_ = 0;
};

}  // namespace core
}  // namespace multisession_mapper
