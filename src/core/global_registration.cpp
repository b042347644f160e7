// Method choice (issue 6, item 4), by measurement on the simulator's `small` profile (map of
// s00 built by offline_mapper; Release; shared 2-core machine with a load average of 4-10, so
// wall times are 2-3x the CPU times):
//
// global_registration_benchmark --map <s00 map> --method both --max-pairs 8: 8 pairs of s00
// submaps with origins <= 15 m apart (consecutive submaps and the route's loop closure), the
// source moved by a random 90-180 deg yaw and 15-30 m, reference = the map's own submap poses;
// the same 8 pairs with a mirrored target as places that do not exist:
//   fpfh_ransac:    7/8 accepted, 0 wrong, error median 0.037 m / 0.196 deg; 0/8 mirrored
//                   accepted; CPU per pair (both submaps prepared) median 1.55 s, max 4.9 s.
//   yaw_search_icp: 1/8 accepted, 0 wrong (0.011 m / 0.085 deg); 0/8 mirrored accepted; CPU
//                   per pair median 4.1 s, max 9.9 s. 12 yaw starts from centroid alignment
//                   rarely reach the basin of partially overlapping submaps 15-30 m apart.
// inter_session_benchmark (s01 against the s00 map, both methods, before the prepared-submap
// cache): fpfh_ransac 5 submaps correctly matched, 0 wrong, 7 of 8 candidate pairs accepted,
// loop error median 0.083 m / 0.454 deg vs truth; yaw_search_icp 4 correct, 0 wrong, 4 of 8
// accepted, 2.0x the time per pair.
// => FPFH + RANSAC is the default. The synthetic and real pairs of global_registration_test
// (150 deg, 20+ m) are recovered within 0.1 cm / 0.01 deg and 3 cm / 0.37 deg (the real pair's
// relative.txt itself is 0.3-0.4 deg from every local optimum).
// Time: one pair costs ~0.5-0.7 s CPU of preparation (normals + FPFH of both coarse clouds, the
// fine kd-tree) plus ~0.5 s of RANSAC + fine ICP; InterSessionMatcher prepares each submap
// once (PreparedSubmap). With that cache, inter_session_benchmark (s01 vs s00 map): 8 pairs in
// 12.0 s CPU = 1.5 s CPU per pair (wall median 2.35 s under load): the 1 s target is NOT yet
// reached. Next steps: FPFH on fewer keypoints (coarse_voxel_m 1.5 / crop 40 m), OMP normals
// and features, ICP on a 1 m source for the first correspondence distance.
// Session 25, `campus` seed-1 s00 map (global_registration_benchmark, 20 overlapping pairs,
// both submaps prepared in every pair, quiet machine), median per pair: preparing the two
// submaps 0.41 s (FPFH 0.08-0.2 s per submap, the fine target's normals 0.06-0.17 s), mutual
// feature matching 0.14 s, RANSAC 0.004 s, fine stage 0.10 s; 0.825 s in all. Coarser
// features lose pairs (coarse_voxel_m 1.25: 17/20 accepted, 1.5: 15/20; feature_radius_m
// 3.5: 1 wrong; coarse_max_range_m 45: 2 mirrored pairs accepted), so the features stay. What
// changed: the matching uses its own nanoflann index, asks the reverse query only for targets
// that some source feature chose, and searches approximately (feature_match_epsilon), 0.14 ->
// 0.047 s; the fine target fits a normal when the ICP first matches its point (KdTreeTarget),
// preparation 0.41 -> 0.30 s for a fine stage 0.10 -> 0.16 s. 0.639 s per pair, the same 20/20
// accepted with the same errors, 0/20 mirrored accepted.
// Session 66: the FPFH features are our own (fpfh_features.h: PCL's histograms to the rounding
// of sums, each neighbour pair computed once instead of twice). global_registration_benchmark
// on the same map, 19 overlapping and 19 mirrored pairs, two runs alternating with the former
// build (PCL's FPFHEstimation): preparing both submaps 0.333 / 0.334 -> 0.153 / 0.152 s,
// 0.762 / 0.760 -> 0.458 / 0.451 s per pair; the same 19/19 accepted with the same errors,
// 0/19 mirrored accepted.
#include "multisession_mapper/core/global_registration.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <numeric>
#include <random>
#include <utility>
#include <vector>

#include <Eigen/Geometry>
#include <nanoflann.hpp>
#include <pcl/features/normal_3d.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/search/kdtree.h>

#include "multisession_mapper/core/fpfh_features.h"
#include "multisession_mapper/core/icp_registration.h"
#include "multisession_mapper/core/kdtree_target.h"
#include "multisession_mapper/core/se3.h"
#include "multisession_mapper/core/stopwatch.h"
#include "multisession_mapper/core/voxel_downsample.h"

namespace multisession_mapper {
namespace core {

namespace {

using Clock = std::chrono::steady_clock;

// FPFH histograms in one contiguous block with an exact L2 kd-tree over them (nanoflann).
// PCL's KdTreeFLANN did this before; per query it copied the histogram into a new vector and
// entered an OpenMP region, and the mutual matching took 0.14 s per pair on the `campus` s00
// map (global_registration_benchmark, 20 pairs). With feature_match_epsilon 0 the neighbours
// are the same (exact search); the default searches approximately (see the config).
class FeatureIndex {
 public:
  static constexpr int kDim = 33;

  explicit FeatureIndex(std::vector<float> rows)
      : rows_(std::move(rows)),
        tree_(kDim, *this, nanoflann::KDTreeSingleIndexAdaptorParams(10)) {
    tree_.buildIndex();
  }
  FeatureIndex(const FeatureIndex&) = delete;
  FeatureIndex& operator=(const FeatureIndex&) = delete;

  std::size_t size() const { return rows_.size() / kDim; }
  const float* row(std::size_t i) const { return rows_.data() + i * kDim; }
  /// The row nearest to `query` (kDim floats), or one within (1 + epsilon) times its distance;
  /// requires size() > 0.
  std::size_t Nearest(const float* query, float epsilon) const {
    std::size_t index = 0;
    float distance_sq = 0.0f;
    nanoflann::KNNResultSet<float, std::size_t, std::size_t> result(1);
    result.init(&index, &distance_sq);
    tree_.findNeighbors(result, query, nanoflann::SearchParams(32, epsilon, false));
    return index;
  }

  // nanoflann's dataset interface.
  std::size_t kdtree_get_point_count() const { return size(); }
  float kdtree_get_pt(std::size_t i, std::size_t d) const { return rows_[i * kDim + d]; }
  template <class BoundingBox>
  bool kdtree_get_bbox(BoundingBox& /*bb*/) const {
    return false;
  }

 private:
  using Tree = nanoflann::KDTreeSingleIndexAdaptor<
      nanoflann::L2_Simple_Adaptor<float, FeatureIndex, float>, FeatureIndex, kDim, std::size_t>;
  std::vector<float> rows_;
  Tree tree_;
};

static_assert(FeatureIndex::kDim == kFpfhBins, "feature rows are FPFH histograms");

// The coarse cloud of one submap (MakeCoarsePoints) with its FPFH features.
struct CoarseCloud : CoarsePoints {
  bool with_features = false;  // FPFH computed (valid / valid_features below)
  std::vector<int> valid;  // indices with a finite feature
  std::shared_ptr<const FeatureIndex> valid_features;  // their features; null when none
};

PointVector CropAndDownsample(const PointVector& points, double voxel_m, double max_range_m) {
  PointVector cropped;
  if (max_range_m > 0.0) {
    cropped.reserve(points.size());
    const double max_sq = max_range_m * max_range_m;
    for (const Eigen::Vector3d& p : points) {
      if (p.squaredNorm() <= max_sq) cropped.push_back(p);
    }
    return VoxelDownsampleCentred(cropped, voxel_m);
  }
  return VoxelDownsampleCentred(points, voxel_m);
}

}  // namespace

CoarsePoints MakeCoarsePoints(const PointVector& points, const GlobalRegistrationConfig& config) {
  CoarsePoints coarse;
  coarse.points = CropAndDownsample(points, config.coarse_voxel_m, config.coarse_max_range_m);
  pcl::PointCloud<pcl::PointXYZ>::Ptr xyz(new pcl::PointCloud<pcl::PointXYZ>);
  xyz->reserve(coarse.points.size());
  for (const Eigen::Vector3d& p : coarse.points) {
    xyz->push_back(pcl::PointXYZ(static_cast<float>(p.x()), static_cast<float>(p.y()),
                                 static_cast<float>(p.z())));
  }
  pcl::search::KdTree<pcl::PointXYZ>::Ptr tree(new pcl::search::KdTree<pcl::PointXYZ>);
  pcl::PointCloud<pcl::Normal>::Ptr normals(new pcl::PointCloud<pcl::Normal>);
  pcl::NormalEstimation<pcl::PointXYZ, pcl::Normal> normal_estimation;
  normal_estimation.setInputCloud(xyz);
  normal_estimation.setSearchMethod(tree);
  normal_estimation.setRadiusSearch(config.normal_radius_m);
  // Submap frames are sensor frames: orient normals towards the origin's upper side.
  normal_estimation.setViewPoint(0.0f, 0.0f, 2.0f);
  normal_estimation.compute(*normals);
  coarse.normals.resize(coarse.points.size(), Eigen::Vector3d::Zero());
  for (std::size_t i = 0; i < normals->size(); ++i) {
    const pcl::Normal& n = (*normals)[i];
    if (std::isfinite(n.normal_x) && std::isfinite(n.normal_y) && std::isfinite(n.normal_z)) {
      coarse.normals[i] = Eigen::Vector3d(n.normal_x, n.normal_y, n.normal_z);
    }
  }
  return coarse;
}

namespace {

CoarseCloud MakeCoarseCloud(const PointVector& points, const GlobalRegistrationConfig& config,
                            bool with_features) {
  CoarseCloud cloud;
  static_cast<CoarsePoints&>(cloud) = MakeCoarsePoints(points, config);
  if (!with_features) return cloud;
  cloud.with_features = true;
  std::vector<std::uint8_t> defined;
  StatusOr<std::vector<float>> features =
      ComputeFpfh(cloud.points, cloud.normals, config.feature_radius_m, &defined);
  // Fails only on a non-finite point (which the sampling leaves out; kept as a guard): the
  // submap then has no features (and no consistent feature matches).
  if (!features.ok()) return cloud;
  std::vector<float> rows;
  for (std::size_t i = 0; i < defined.size(); ++i) {
    if (!defined[i]) continue;
    cloud.valid.push_back(static_cast<int>(i));
    const float* h = features.value().data() + i * kFpfhBins;
    rows.insert(rows.end(), h, h + kFpfhBins);
  }
  if (!cloud.valid.empty()) {
    cloud.valid_features = std::make_shared<const FeatureIndex>(std::move(rows));
  }
  return cloud;
}

// Mutual nearest neighbours in FPFH space: (source index, target index). The nearest source
// feature is looked up only for the targets that are some source feature's nearest.
std::vector<std::pair<int, int>> MutualFeatureMatches(const CoarseCloud& source,
                                                      const CoarseCloud& target,
                                                      float epsilon) {
  std::vector<std::pair<int, int>> matches;
  if (!source.valid_features || !target.valid_features) return matches;
  const FeatureIndex& source_features = *source.valid_features;
  const FeatureIndex& target_features = *target.valid_features;
  constexpr std::size_t kUnknown = static_cast<std::size_t>(-1);
  std::vector<std::size_t> target_to_source(target_features.size(), kUnknown);
  for (std::size_t s = 0; s < source_features.size(); ++s) {
    const std::size_t t = target_features.Nearest(source_features.row(s), epsilon);
    if (target_to_source[t] == kUnknown) {
      target_to_source[t] = source_features.Nearest(target_features.row(t), epsilon);
    }
    if (target_to_source[t] != s) continue;
    matches.emplace_back(source.valid[s], target.valid[t]);
  }
  return matches;
}

double TiltRad(const Eigen::Matrix3d& rotation) {
  return std::acos(std::clamp(rotation(2, 2), -1.0, 1.0));
}

struct Hypothesis {
  Pose3 pose = Pose3::Identity();
  int score = 0;  // RANSAC inliers, or fitness x 1000
  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};
using Hypotheses = std::vector<Hypothesis, Eigen::aligned_allocator<Hypothesis>>;

bool SamePose(const Pose3& a, const Pose3& b, const GlobalRegistrationConfig& config) {
  const Pose3 d = se3::Between(a, b);
  return se3::TranslationNorm(d) < config.distinct_translation_m &&
         se3::RotationAngleRad(d) < config.distinct_rotation_rad;
}

// Keeps `best` sorted by score (descending), distinct, at most `capacity` long.
void Offer(const Hypothesis& h, int capacity, const GlobalRegistrationConfig& config,
           Hypotheses* best) {
  for (Hypothesis& b : *best) {
    if (SamePose(b.pose, h.pose, config)) {
      if (h.score > b.score) b = h;
      std::sort(best->begin(), best->end(),
                [](const Hypothesis& x, const Hypothesis& y) { return x.score > y.score; });
      return;
    }
  }
  if (static_cast<int>(best->size()) >= capacity && best->back().score >= h.score) return;
  best->push_back(h);
  std::sort(best->begin(), best->end(),
            [](const Hypothesis& x, const Hypothesis& y) { return x.score > y.score; });
  if (static_cast<int>(best->size()) > capacity) best->pop_back();
}

Pose3 FitRigid(const std::vector<Eigen::Vector3d>& from, const std::vector<Eigen::Vector3d>& to) {
  Eigen::Matrix3Xd a(3, from.size()), b(3, to.size());
  for (std::size_t i = 0; i < from.size(); ++i) {
    a.col(i) = from[i];
    b.col(i) = to[i];
  }
  Pose3 pose = Pose3::Identity();
  pose.matrix() = Eigen::umeyama(a, b, false);
  return pose;
}

// RANSAC over correspondence triples; returns the best distinct hypotheses (inliers refit).
Hypotheses RansacHypotheses(const CoarseCloud& source, const CoarseCloud& target,
                            const std::vector<std::pair<int, int>>& matches,
                            const GlobalRegistrationConfig& config) {
  Hypotheses best;
  const int n = static_cast<int>(matches.size());
  if (n < 3) return best;
  std::mt19937 rng(config.seed);
  std::uniform_int_distribution<int> pick(0, n - 1);
  const double inlier_sq = config.ransac_inlier_distance_m * config.ransac_inlier_distance_m;
  const double min_edge = config.ransac_min_edge_m;
  auto src = [&](int k) -> const Eigen::Vector3d& { return source.points[matches[k].first]; };
  auto tgt = [&](int k) -> const Eigen::Vector3d& { return target.points[matches[k].second]; };
  auto count_inliers = [&](const Pose3& pose, std::vector<int>* inliers) {
    int count = 0;
    for (int k = 0; k < n; ++k) {
      if ((pose * src(k) - tgt(k)).squaredNorm() <= inlier_sq) {
        ++count;
        if (inliers) inliers->push_back(k);
      }
    }
    return count;
  };
  const int capacity = std::max(1, config.num_hypotheses);
  for (int it = 0; it < config.ransac_iterations; ++it) {
    const int k[3] = {pick(rng), pick(rng), pick(rng)};
    if (k[0] == k[1] || k[1] == k[2] || k[0] == k[2]) continue;
    bool ok = true;
    for (int e = 0; e < 3 && ok; ++e) {
      const int i = k[e], j = k[(e + 1) % 3];
      const double ds = (src(i) - src(j)).norm();
      const double dt = (tgt(i) - tgt(j)).norm();
      ok = ds >= min_edge && dt >= min_edge &&
           std::min(ds, dt) >= config.ransac_edge_similarity * std::max(ds, dt);
    }
    if (!ok) continue;
    const Pose3 pose = FitRigid({src(k[0]), src(k[1]), src(k[2])}, {tgt(k[0]), tgt(k[1]), tgt(k[2])});
    if (!pose.matrix().allFinite() || TiltRad(pose.linear()) > config.max_tilt_rad) continue;
    Hypothesis h;
    h.pose = pose;
    h.score = count_inliers(pose, nullptr);
    if (h.score < 3) continue;
    Offer(h, capacity, config, &best);
  }
  // Refit each hypothesis on its inliers (twice: the refit can gather more).
  for (Hypothesis& h : best) {
    for (int round = 0; round < 2; ++round) {
      std::vector<int> inliers;
      count_inliers(h.pose, &inliers);
      if (inliers.size() < 3) break;
      std::vector<Eigen::Vector3d> a, b;
      for (int k : inliers) {
        a.push_back(src(k));
        b.push_back(tgt(k));
      }
      const Pose3 refit = FitRigid(a, b);
      if (!refit.matrix().allFinite() || TiltRad(refit.linear()) > config.max_tilt_rad) break;
      const int score = count_inliers(refit, nullptr);
      if (score < h.score) break;
      h.pose = refit;
      h.score = score;
    }
  }
  std::sort(best.begin(), best.end(),
            [](const Hypothesis& x, const Hypothesis& y) { return x.score > y.score; });
  return best;
}

Eigen::Vector3d Centroid(const PointVector& points) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& p : points) sum += p;
  return points.empty() ? sum : Eigen::Vector3d(sum / static_cast<double>(points.size()));
}

// Yaw starts with centroid alignment, each refined by coarse ICP; best by fitness.
Hypotheses YawSearchHypotheses(const CoarseCloud& source, const CoarseCloud& target,
                               const GlobalRegistrationConfig& config) {
  Hypotheses best;
  StatusOr<KdTreeTarget> tree = KdTreeTarget::Create(target.points, config.fine.target);
  StatusOr<IcpRegistration> icp = IcpRegistration::Create(config.fine.icp);
  if (!tree.ok() || !icp.ok()) return best;
  const Eigen::Vector3d cs = Centroid(source.points);
  const Eigen::Vector3d ct = Centroid(target.points);
  const int capacity = std::max(1, config.num_hypotheses);
  for (int b = 0; b < config.yaw_bins; ++b) {
    const double yaw = 2.0 * M_PI * b / config.yaw_bins;
    Pose3 pose = Pose3::Identity();
    pose.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    pose.translation() = ct - pose.linear() * cs;
    double fitness = 0.0;
    bool ok = true;
    for (double distance : config.yaw_search_schedule_m) {
      StatusOr<IcpResult> r =
          icp.value().Register(source.points, tree.value(), pose, distance, distance / 3.0);
      if (!r.ok()) {
        ok = false;
        break;
      }
      pose = r.value().pose;
      fitness = r.value().fitness;
    }
    if (!ok || TiltRad(pose.linear()) > config.max_tilt_rad) continue;
    Hypothesis h;
    h.pose = pose;
    h.score = static_cast<int>(std::lround(fitness * 1000.0));
    Offer(h, capacity, config, &best);
  }
  return best;
}

// Fraction of the source's structure points (coarse normals with |n_z| small) that lie within
// `structure_overlap_distance_m` of the target.
double StructureOverlap(const CoarseCloud& source, const SubmapTarget& target, const Pose3& pose,
                        const GlobalRegistrationConfig& config) {
  std::size_t structure = 0, overlapping = 0;
  for (std::size_t i = 0; i < source.points.size(); ++i) {
    const Eigen::Vector3d& n = source.normals[i];
    if (n.squaredNorm() < 0.5) continue;
    if (std::abs((pose.linear() * n).z()) >= config.structure_max_normal_z) continue;
    ++structure;
    std::size_t index;
    double distance_sq;
    overlapping += target.tree().NearestWithin(
        pose * source.points[i], config.structure_overlap_distance_m, &index, &distance_sq);
  }
  return structure == 0 ? 0.0 : static_cast<double>(overlapping) / structure;
}

}  // namespace

GlobalRegistrationConfig::GlobalRegistrationConfig() {
  // The fine stage starts from the coarse pose, which can be off by about a voxel and a few
  // degrees: its agreement bounds only catch an ICP that ran away.
  fine.max_correction_m = 3.0;
  fine.max_correction_rad = 0.2;
  fine.min_overlap_ratio = 0.3;
  // ICP schedule and convergence: the intra-session defaults. Measured on sim_small s00 pairs,
  // a faster two-distance schedule ({1.5, 0.5} m, 20 iterations, 1 mm convergence) left
  // low-overlap pairs 0.2-1.0 m / 2-3 deg off where these defaults reach 1-5 cm / 0.1-0.3 deg.
}

const char* GlobalRegistrationMethodName(GlobalRegistrationConfig::Method method) {
  switch (method) {
    case GlobalRegistrationConfig::Method::kFpfhRansac:
      return "fpfh_ransac";
    case GlobalRegistrationConfig::Method::kYawSearchIcp:
      return "yaw_search_icp";
  }
  return "unknown";
}

Status GlobalRegistrationConfig::Validate() const {
  if (!(coarse_voxel_m > 0.0)) return Status::Error("global_registration.coarse_voxel_m must be > 0");
  if (!std::isfinite(coarse_max_range_m)) {
    return Status::Error("global_registration.coarse_max_range_m must be finite");
  }
  if (!(normal_radius_m > 0.0) || !(feature_radius_m > 0.0)) {
    return Status::Error("global_registration normal/feature radii must be > 0");
  }
  if (!(feature_match_epsilon >= 0.0) || !std::isfinite(feature_match_epsilon)) {
    return Status::Error("global_registration.feature_match_epsilon must be >= 0");
  }
  if (ransac_iterations < 1) return Status::Error("global_registration.ransac_iterations must be >= 1");
  if (!(ransac_inlier_distance_m > 0.0)) {
    return Status::Error("global_registration.ransac_inlier_distance_m must be > 0");
  }
  if (!(ransac_edge_similarity > 0.0 && ransac_edge_similarity <= 1.0)) {
    return Status::Error("global_registration.ransac_edge_similarity must be in (0, 1]");
  }
  if (!(ransac_min_edge_m >= 0.0)) return Status::Error("global_registration.ransac_min_edge_m must be >= 0");
  if (!(max_tilt_rad > 0.0 && max_tilt_rad <= M_PI)) {
    return Status::Error("global_registration.max_tilt_rad must be in (0, pi]");
  }
  if (min_ransac_inliers < 3) return Status::Error("global_registration.min_ransac_inliers must be >= 3");
  if (yaw_bins < 1) return Status::Error("global_registration.yaw_bins must be >= 1");
  if (yaw_search_schedule_m.empty()) {
    return Status::Error("global_registration.yaw_search_schedule_m must not be empty");
  }
  for (double d : yaw_search_schedule_m) {
    if (!(d > 0.0)) return Status::Error("global_registration.yaw_search_schedule_m entries must be > 0");
  }
  if (num_hypotheses < 1) return Status::Error("global_registration.num_hypotheses must be >= 1");
  if (!(distinct_translation_m > 0.0) || !(distinct_rotation_rad > 0.0)) {
    return Status::Error("global_registration distinct thresholds must be > 0");
  }
  if (!(structure_max_normal_z > 0.0 && structure_max_normal_z <= 1.0)) {
    return Status::Error("global_registration.structure_max_normal_z must be in (0, 1]");
  }
  if (!(structure_overlap_distance_m > 0.0)) {
    return Status::Error("global_registration.structure_overlap_distance_m must be > 0");
  }
  if (!(min_structure_overlap_ratio >= 0.0 && min_structure_overlap_ratio <= 1.0)) {
    return Status::Error("global_registration.min_structure_overlap_ratio must be in [0, 1]");
  }
  return fine.Validate();
}

StatusOr<GlobalRegistration> GlobalRegistration::Create(const GlobalRegistrationConfig& config) {
  Status s = config.Validate();
  if (!s.ok()) return s;
  StatusOr<SubmapRegistration> fine = SubmapRegistration::Create(config.fine);
  if (!fine.ok()) return fine.status();
  return GlobalRegistration(config, std::move(fine.value()));
}

struct PreparedSubmap {
  CoarseCloud coarse;
  PointVector fine_source;                   // at the fine stage's source voxel
  std::shared_ptr<SubmapTarget> fine_target;  // null unless prepared as a target
  double prepare_s = 0.0;
};

StatusOr<std::shared_ptr<const PreparedSubmap>> GlobalRegistration::Prepare(
    const PointVector& points, bool as_target, bool with_features) const {
  const auto start = Clock::now();
  if (points.empty()) return Status::Error("global registration: empty submap");
  auto prepared = std::make_shared<PreparedSubmap>();
  prepared->coarse = MakeCoarseCloud(
      points, config_,
      with_features && config_.method == GlobalRegistrationConfig::Method::kFpfhRansac);
  // The fine stage (ICP and overlap) runs on the source at its ICP voxel: the overlap ratio of
  // the downsampled source is the same fraction, at a fraction of the cost.
  prepared->fine_source = VoxelDownsampleCentred(points, config_.fine.source_voxel_m);
  if (as_target) {
    StatusOr<SubmapTarget> target = SubmapTarget::Create(points, config_.fine);
    if (!target.ok()) return target.status();
    prepared->fine_target = std::make_shared<SubmapTarget>(std::move(target.value()));
  }
  prepared->prepare_s = SecondsSince(start);
  return std::shared_ptr<const PreparedSubmap>(std::move(prepared));
}

double GlobalRegistration::PrepareSeconds(const PreparedSubmap& submap) {
  return submap.prepare_s;
}

std::shared_ptr<const SubmapTarget> GlobalRegistration::FineTarget(const PreparedSubmap& submap) {
  return submap.fine_target;
}

GlobalRegistrationResult GlobalRegistration::Register(const PointVector& source,
                                                      const PointVector& target) const {
  const auto start = Clock::now();
  if (source.empty() || target.empty()) {
    GlobalRegistrationResult result;
    result.reason = "empty submap";
    return result;
  }
  StatusOr<std::shared_ptr<const PreparedSubmap>> s = Prepare(source, false);
  StatusOr<std::shared_ptr<const PreparedSubmap>> t = Prepare(target, true);
  if (!s.ok() || !t.ok()) {
    GlobalRegistrationResult result;
    result.reason = !s.ok() ? s.status().message() : t.status().message();
    return result;
  }
  const double prepare_s = SecondsSince(start);
  GlobalRegistrationResult result = Register(*s.value(), *t.value());
  result.coarse_time_s += prepare_s;
  result.prepare_s = prepare_s;
  result.time_s = SecondsSince(start);
  return result;
}

GlobalRegistrationResult GlobalRegistration::Register(const PreparedSubmap& source_submap,
                                                      const PreparedSubmap& target_submap) const {
  const auto start = Clock::now();
  GlobalRegistrationResult result;
  auto finish = [&](std::string reason) {
    result.reason = std::move(reason);
    result.time_s = SecondsSince(start);
    return result;
  };
  if (!target_submap.fine_target) return finish("target not prepared as a target");
  const bool features = config_.method == GlobalRegistrationConfig::Method::kFpfhRansac;
  if (features && (!source_submap.coarse.with_features || !target_submap.coarse.with_features)) {
    return finish("submap prepared without features");
  }
  const CoarseCloud& coarse_source = source_submap.coarse;
  const CoarseCloud& coarse_target = target_submap.coarse;
  Hypotheses hypotheses;
  if (features) {
    const std::vector<std::pair<int, int>> matches =
        MutualFeatureMatches(coarse_source, coarse_target,
                             static_cast<float>(config_.feature_match_epsilon));
    result.matching_s = SecondsSince(start);
    hypotheses = RansacHypotheses(coarse_source, coarse_target, matches, config_);
    result.hypotheses_s = SecondsSince(start) - result.matching_s;
    if (hypotheses.empty() || hypotheses.front().score < config_.min_ransac_inliers) {
      result.coarse_inliers = hypotheses.empty() ? 0 : hypotheses.front().score;
      result.coarse_time_s = SecondsSince(start);
      return finish("no consistent features (" + std::to_string(result.coarse_inliers) +
                    " RANSAC inliers of " + std::to_string(matches.size()) + " matches)");
    }
    // Hypotheses far weaker than the best are not worth a fine registration.
    const int floor = std::max(config_.min_ransac_inliers, hypotheses.front().score / 2);
    hypotheses.erase(std::remove_if(hypotheses.begin(), hypotheses.end(),
                                    [&](const Hypothesis& h) { return h.score < floor; }),
                     hypotheses.end());
  } else {
    hypotheses = YawSearchHypotheses(coarse_source, coarse_target, config_);
    result.hypotheses_s = SecondsSince(start);
    if (hypotheses.empty()) return finish("yaw search: no ICP start converged");
  }
  result.coarse_time_s = SecondsSince(start);

  bool have = false;
  std::string first_reason;
  for (const Hypothesis& h : hypotheses) {
    // Best first; the next hypotheses are only tried when the better ones were rejected.
    if (have) break;
    GlobalRegistrationResult attempt;
    const std::string reason = Refine(source_submap, target_submap, h.pose, &attempt);
    attempt.coarse_inliers = h.score;
    if (reason.empty() || first_reason.empty()) {
      result.T_target_source = attempt.T_target_source;
      result.overlap_ratio = attempt.overlap_ratio;
      result.information = attempt.information;
      result.coarse_inliers = attempt.coarse_inliers;
      result.structure_overlap_ratio = attempt.structure_overlap_ratio;
    }
    if (reason.empty()) {
      have = true;
      result.accepted = true;
    } else if (first_reason.empty()) {
      first_reason = reason;
    }
  }
  result.fine_s = SecondsSince(start) - result.coarse_time_s;
  if (!have) return finish(first_reason);
  return finish("");
}

GlobalRegistrationResult GlobalRegistration::RegisterFrom(const PreparedSubmap& source,
                                                          const PreparedSubmap& target,
                                                          const Pose3& prior) const {
  const auto start = Clock::now();
  GlobalRegistrationResult result;
  if (!target.fine_target) {
    result.reason = "target not prepared as a target";
  } else {
    result.reason = Refine(source, target, prior, &result);
    result.accepted = result.reason.empty();
  }
  result.time_s = SecondsSince(start);
  result.fine_s = result.time_s;
  return result;
}

std::string GlobalRegistration::Refine(const PreparedSubmap& source, const PreparedSubmap& target,
                                       const Pose3& start, GlobalRegistrationResult* out) const {
  const SubmapRegistrationResult fine =
      fine_.Register(source.fine_source, *target.fine_target, start);
  std::string reason = fine.reason;
  double structure = 0.0;
  if (fine.accepted) {
    structure = StructureOverlap(source.coarse, *target.fine_target, fine.T_target_source, config_);
    if (structure < config_.min_structure_overlap_ratio) {
      reason = "structure overlap " + std::to_string(structure) + " below " +
               std::to_string(config_.min_structure_overlap_ratio);
    }
  }
  out->T_target_source = fine.T_target_source;
  out->overlap_ratio = fine.overlap_ratio;
  out->information = fine.information;
  out->structure_overlap_ratio = structure;
  return reason;
}

}  // namespace core
}  // namespace multisession_mapper
