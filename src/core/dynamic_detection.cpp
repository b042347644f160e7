#include "multisession_mapper/core/dynamic_detection.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <deque>
#include <initializer_list>
#include <iterator>
#include <limits>
#include <memory>
#include <string>
#include <unordered_map>
#include <utility>

#include <Eigen/Eigenvalues>

#include "multisession_mapper/core/local_plane.h"
#include "multisession_mapper/core/point_index.h"
#include "multisession_mapper/core/ray_voxel_grid.h"
#include "multisession_mapper/core/stopwatch.h"
#include "multisession_mapper/core/voxel_key.h"

namespace multisession_mapper {
namespace core {

namespace {

constexpr int kHistory = 0;
constexpr int kCurrent = 1;
// Voxel flags: occupied by a session's points; queried for the other session's passing rays.
constexpr std::uint8_t kOccupied[2] = {1, 2};
constexpr std::uint8_t kQueried[2] = {4, 8};
// ... queried by a point of the far band (beyond max_range_m of the other session).
constexpr std::uint8_t kQueriedFar[2] = {16, 32};

Status CheckPositive(const std::string& name, double value) {
  if (!std::isfinite(value) || value <= 0.0) {
    return Status::Error("dynamic_detection." + name + " must be > 0, got " +
                         std::to_string(value));
  }
  return Status::Ok();
}

// One submap of the pair in the current frame with everything derived from it.
struct Side {
  PointVector points;
  PointVector origins;  // thinned sensor origins
  PointVector scan_origins;  // every scan's origin, by scan index (with views only)
  const std::vector<PointViews>* views = nullptr;  // the submap's, or null: nearest origins
  std::vector<std::uint8_t> common;
  std::vector<std::uint8_t> far;  // beyond max_range_m of the other session (the far band)
  std::vector<float> nearest_other_m;  // distance to the nearest point of the other submap
  // No seed of the common parts can lie within grow_radius_m (see FindCommonParts): the
  // growth need not search around the point for one.
  std::vector<std::uint8_t> no_seed_near;
  std::vector<float> height_m;         // above the local ground
  // Lazily computed normals: 0 unknown, 1 planar, 2 none.
  std::vector<std::uint8_t> normal_state;
  std::vector<Eigen::Vector3f> normals;
};

PointVector ThinOrigins(const Submap& submap, const Pose3& T, double spacing_m) {
  PointVector kept;
  for (const SubmapScanRecord& scan : submap.scans) {
    const Eigen::Vector3d o = T * scan.T_submap_sensor.translation();
    bool close = false;
    for (const Eigen::Vector3d& k : kept) {
      if ((k - o).squaredNorm() < spacing_m * spacing_m) {
        close = true;
        break;
      }
    }
    if (!close) kept.push_back(o);
  }
  return kept;
}

// Lowest point per 2D cell of the given submaps, then the minimum over the 3x3 neighbourhood.
class GroundGrid {
 public:
  GroundGrid(std::initializer_list<const Side*> sides, double cell_m) : cell_m_(cell_m) {
    Eigen::Vector2d lo(std::numeric_limits<double>::max(), std::numeric_limits<double>::max());
    Eigen::Vector2d hi = -lo;
    for (const Side* s : sides) {
      for (const Eigen::Vector3d& p : s->points) {
        lo = lo.cwiseMin(p.head<2>());
        hi = hi.cwiseMax(p.head<2>());
      }
    }
    origin_ = lo;
    nx_ = static_cast<int>(std::floor((hi.x() - lo.x()) / cell_m)) + 1;
    ny_ = static_cast<int>(std::floor((hi.y() - lo.y()) / cell_m)) + 1;
    std::vector<float> lowest(static_cast<std::size_t>(nx_) * ny_,
                              std::numeric_limits<float>::infinity());
    for (const Side* s : sides) {
      for (const Eigen::Vector3d& p : s->points) {
        float& z = lowest[Cell(p)];
        z = std::min(z, static_cast<float>(p.z()));
      }
    }
    ground_.assign(lowest.size(), std::numeric_limits<float>::infinity());
    for (int y = 0; y < ny_; ++y) {
      for (int x = 0; x < nx_; ++x) {
        float g = std::numeric_limits<float>::infinity();
        for (int dy = -1; dy <= 1; ++dy) {
          for (int dx = -1; dx <= 1; ++dx) {
            const int cx = x + dx, cy = y + dy;
            if (cx < 0 || cy < 0 || cx >= nx_ || cy >= ny_) continue;
            g = std::min(g, lowest[static_cast<std::size_t>(cy) * nx_ + cx]);
          }
        }
        ground_[static_cast<std::size_t>(y) * nx_ + x] = g;
      }
    }
  }
  float HeightAbove(const Eigen::Vector3d& p) const {
    return static_cast<float>(p.z()) - ground_[Cell(p)];
  }

 private:
  std::size_t Cell(const Eigen::Vector3d& p) const {
    const int x = std::min(std::max(static_cast<int>((p.x() - origin_.x()) / cell_m_), 0), nx_ - 1);
    const int y = std::min(std::max(static_cast<int>((p.y() - origin_.y()) / cell_m_), 0), ny_ - 1);
    return static_cast<std::size_t>(y) * nx_ + x;
  }
  double cell_m_;
  Eigen::Vector2d origin_;
  int nx_ = 1, ny_ = 1;
  std::vector<float> ground_;
};

// A side's neighbour index, built over its submap's points in the submap's own frame, so that
// every pair of the submap can share it. Queries come in the frame of the detection (the
// current submap's) and are moved into the index's frame first; distances do not change under
// the rigid motion, so the answers are those of an index over the moved points (up to rounding
// at the radius). With the identity (the current side) the moved query is the query, exactly.
class FrameIndex {
 public:
  FrameIndex(const PointIndex& index, const Pose3& T_index_detection)
      : index_(index),
        rotation_(T_index_detection.linear()),
        translation_(T_index_detection.translation()) {}
  bool NearestWithin(const Eigen::Vector3d& query, double max_radius_m, std::uint32_t* index,
                     double* distance_sq) const {
    return index_.NearestWithin(Move(query), max_radius_m, index, distance_sq);
  }
  void Radius(const Eigen::Vector3d& query, double radius_m,
              std::vector<std::uint32_t>* out) const {
    index_.Radius(Move(query), radius_m, out);
  }
  void Nearest(const Eigen::Vector3d& query, std::size_t k, double max_radius_m,
               std::vector<std::uint32_t>* out) const {
    index_.Nearest(Move(query), k, max_radius_m, out);
  }

 private:
  Eigen::Vector3d Move(const Eigen::Vector3d& query) const {
    return rotation_ * query + translation_;
  }
  const PointIndex& index_;
  Eigen::Matrix3d rotation_;
  Eigen::Vector3d translation_;
};

class PairDetection {
 public:
  PairDetection(const DynamicDetectionConfig& config, Side* sides, const FrameIndex& history,
                const FrameIndex& current)
      : config_(config),
        sides_(sides),
        indices_{&history, &current},
        min_pass_sin_(static_cast<float>(std::sin(config.min_pass_incidence_rad))) {}

  // Steps 1-2: seeds and region growing of the common parts.
  void FindCommonParts() {
    for (int s = 0; s < 2; ++s) {
      Side& side = sides_[s];
      const FrameIndex& other = *indices_[1 - s];
      const std::size_t n = side.points.size();
      side.common.assign(n, 0);
      side.far.assign(n, 0);
      side.nearest_other_m.assign(n, std::numeric_limits<float>::infinity());
      side.normal_state.assign(n, 0);
      side.normals.assign(n, Eigen::Vector3f::Zero());
      side.no_seed_near.assign(n, 0);
      // A seed within grow_radius_m of a point has a point of the other submap within
      // seed_distance_m, so the point has one within their sum (the triangle inequality):
      // searched that far, a point without one has no seed near it, unless it lies within
      // grow_radius_m of the out-of-range points (seeds without the other's point), which
      // `inner` rules out. Distances beyond the reach are only compared against smaller
      // thresholds: they stay "far".
      const double seed_reach = config_.seed_distance_m + config_.grow_radius_m + 1e-6;  // + rounding
      const double reach =
          std::max({config_.seed_distance_m, config_.mending_distance_m, seed_reach});
      const double inner = config_.max_range_m - config_.grow_radius_m;
      // Points out of the other session's range are not examined: marked common (never
      // dynamic, no queries) and close to the other (never mended). Points of the far band
      // are examined, under the conditions of DetectDynamic and Mending.
      const double range_sq = config_.max_range_m * config_.max_range_m;
      const double outer = ExaminedRange();
      for (std::size_t i = 0; i < n; ++i) {
        if (!NearAny(sides_[1 - s].origins, side.points[i], range_sq)) {
          // In the far band, points that can never be dynamic (above the objects the height
          // guard lets grow) stay common as out-of-range points: seeds of the common parts.
          if (outer > config_.max_range_m && !NeverDynamic(side.height_m[i]) &&
              NearAny(sides_[1 - s].origins, side.points[i], outer * outer)) {
            side.far[i] = 1;
          } else {
            side.common[i] = 1;
            side.nearest_other_m[i] = 0.0f;
            continue;
          }
        }
        std::uint32_t j = 0;
        double d2 = 0.0;
        const bool found = other.NearestWithin(side.points[i], reach, &j, &d2);
        if (found) {
          side.nearest_other_m[i] = static_cast<float>(std::sqrt(d2));
          side.common[i] = d2 <= config_.seed_distance_m * config_.seed_distance_m ? 1 : 0;
        }
        if ((!found || d2 > seed_reach * seed_reach) && inner > 0.0 &&
            NearAny(sides_[1 - s].origins, side.points[i], inner * inner)) {
          side.no_seed_near[i] = 1;
        }
      }
      GrowCommon(s);
    }
  }

  // Heights above the submap's own ground: the two sessions' grounds differ by the vertical
  // alignment error and the odometry's height drift inside the submaps (0.1-0.3 m), and above
  // the lower of the two a session's own ground rose out of ground_tolerance_m and was then
  // seen through by the other session's grazing rays. Where the own ground is far above the
  // joint one, the own view of the ground was blocked (under a parked car): the joint one.
  void EstimateGround() {
    const GroundGrid joint({&sides_[0], &sides_[1]}, config_.ground_cell_m);
    const float max_gap = static_cast<float>(config_.own_ground_max_gap_m);
    for (int s = 0; s < 2; ++s) {
      Side& side = sides_[s];
      const GroundGrid own({&side}, config_.ground_cell_m);
      side.height_m.resize(side.points.size());
      for (std::size_t i = 0; i < side.points.size(); ++i) {
        const float above_joint = joint.HeightAbove(side.points[i]);
        const float above_own = own.HeightAbove(side.points[i]);
        side.height_m[i] = above_joint - above_own <= max_gap ? above_own : above_joint;
      }
    }
  }

  // Step 3: voxel maps and free-space ray casting of both sessions.
  Status CastRays() {
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::max());
    Eigen::Vector3d hi = -lo;
    for (int s = 0; s < 2; ++s) {
      for (const PointVector* v : {&sides_[s].points, &sides_[s].origins}) {
        for (const Eigen::Vector3d& p : *v) {
          lo = lo.cwiseMin(p);
          hi = hi.cwiseMax(p);
        }
      }
    }
    const Eigen::Vector3d pad = Eigen::Vector3d::Constant(config_.voxel_size_m);
    StatusOr<RayVoxelGrid> grid = RayVoxelGrid::Create(config_.voxel_size_m, lo - pad, hi + pad);
    if (!grid.ok()) return grid.status();
    grid_ = std::make_unique<RayVoxelGrid>(std::move(grid.value()));
    // Coarse mask (one cell per 8^3 voxels) of where queried voxels are: a ray that crosses
    // none of them cannot add evidence and is not traversed voxel by voxel.
    StatusOr<RayVoxelGrid> coarse =
        RayVoxelGrid::Create(8.0 * config_.voxel_size_m, lo - pad, hi + pad);
    if (!coarse.ok()) return coarse.status();
    coarse_ = std::make_unique<RayVoxelGrid>(std::move(coarse.value()));
    for (int s = 0; s < 2; ++s) {
      for (const Eigen::Vector3d& p : sides_[s].points) {
        grid_->Touch(grid_->KeyOf(p))->flags |= kOccupied[s];
      }
    }
    for (int s = 0; s < 2; ++s) {
      const Side& side = sides_[s];
      for (std::size_t i = 0; i < side.points.size(); ++i) {
        // Passing rays are counted where the other session may have something the voxel's
        // own session did not see: the difference set and points without a close partner,
        // above the ground (rays cannot see through the ground; mending needs no count there).
        if (side.height_m[i] < config_.ground_tolerance_m ||
            (side.common[i] && side.nearest_other_m[i] <= config_.mending_distance_m)) {
          continue;
        }
        // A point of the far band above the height guard is never a seed, never mended and
        // never compared (changed_compare_range_m): its passes are not needed.
        if (side.far[i] && config_.height_guard_enabled &&
            side.height_m[i] > config_.height_guard_m) {
          continue;
        }
        auto query = [&](const Eigen::Vector3i& key, RayVoxelGrid::Cell* cell) {
          const std::uint8_t flags = kQueried[s] | (side.far[i] ? kQueriedFar[s] : 0);
          cell->flags |= flags;
          coarse_->Touch(coarse_->KeyOf(grid_->CentreOf(key)))->flags |= flags;
        };
        const Eigen::Vector3i point_key = grid_->KeyOf(side.points[i]);
        RayVoxelGrid::Cell* point_cell = grid_->Find(point_key);
        query(point_key, point_cell);
        Eigen::Vector3f normal;
        if (config_.min_pass_incidence_rad > 0.0 &&
            Normal(s, static_cast<std::uint32_t>(i), &normal)) {
          pass_normals_[s].emplace(point_cell, normal);  // the voxel's first planar point
        }
        // The free column below (only for points that can become dynamic).
        if (side.common[i]) continue;
        ForFreeColumn(s, i, [&](const Eigen::Vector3i& key) {
          RayVoxelGrid::Cell* cell = grid_->Touch(key);
          if (cell == nullptr || (cell->flags & kOccupied[s])) return false;
          query(key, cell);
          return true;
        });
      }
    }
    for (int s = 0; s < 2; ++s) CastSide(s);
    return Status::Ok();
  }

  // Step 4: coarse dynamic points of side `s` (seen through by the other), grown into objects.
  std::vector<std::uint32_t> DetectDynamic(int s) {
    const Side& side = sides_[s];
    const int other = 1 - s;
    const std::size_t n = side.points.size();
    // 0: not eligible, 1: eligible, 2: coarse dynamic.
    std::vector<std::uint8_t> state(n, 0);
    std::vector<std::uint32_t> neighbours;
    for (std::size_t i = 0; i < n; ++i) {
      if (side.common[i] || side.height_m[i] < config_.ground_tolerance_m) continue;
      // Above the height guard a point is never a seed, but it may belong to an object grown
      // from below it, up to guard_object_height_m (set below height_guard_m: the plain guard).
      const bool above_guard =
          config_.height_guard_enabled && side.height_m[i] > config_.height_guard_m;
      if (NeverDynamic(side.height_m[i])) continue;
      // Consistency: the other session has nothing above the ground around the point.
      indices_[other]->Radius(side.points[i], config_.support_radius_m, &neighbours);
      int support = 0;
      for (std::uint32_t j : neighbours) {
        if (sides_[other].height_m[j] >= config_.ground_tolerance_m) ++support;
      }
      if (support > config_.max_support_points) continue;
      state[i] = 1;
      if (above_guard) continue;
      const RayVoxelGrid::Cell* cell = grid_->Find(grid_->KeyOf(side.points[i]));
      int passing = cell != nullptr ? cell->count[other] : 0;
      ForFreeColumn(s, i, [&](const Eigen::Vector3i& key) {
        const RayVoxelGrid::Cell* below = grid_->Find(key);
        if (below == nullptr || (below->flags & kOccupied[s])) return false;
        passing += below->count[other];
        return passing < config_.min_passing_rays;
      });
      if (passing >= config_.min_passing_rays) state[i] = 2;
    }
    // Grow clusters from the coarse points over eligible points.
    std::vector<std::uint8_t> visited(n, 0);
    std::vector<std::uint32_t> dynamic, cluster;
    for (std::size_t seed = 0; seed < n; ++seed) {
      if (state[seed] != 2 || visited[seed]) continue;
      visited[seed] = 1;
      Grow(s, static_cast<std::uint32_t>(seed), config_.dynamic_grow_radius_m,
           [&](std::uint32_t j) {
             if (state[j] == 0 || visited[j]) return false;
             visited[j] = 1;
             return true;
           },
           &cluster);
      int coarse = 0;
      float bottom_m = std::numeric_limits<float>::max();
      for (std::uint32_t i : cluster) {
        coarse += state[i] == 2;
        bottom_m = std::min(bottom_m, side.height_m[i]);
      }
      const bool grounded =
          config_.max_object_bottom_m == 0.0 || bottom_m <= config_.max_object_bottom_m;
      if (static_cast<int>(cluster.size()) >= config_.min_cluster_points &&
          coarse >= config_.min_cluster_coarse_points &&
          coarse >= config_.min_cluster_coarse_fraction * static_cast<double>(cluster.size()) &&
          grounded &&
          (!TouchesFarBand(side, cluster) ||
           (StandsOnWideGround(s, cluster) && WholeObjectIsMovable(s, cluster)))) {
        dynamic.insert(dynamic.end(), cluster.begin(), cluster.end());
        if (config_.bottom_extension_radius_m > 0.0) ExtendDown(s, cluster, &visited, &dynamic);
      }
    }
    std::sort(dynamic.begin(), dynamic.end());
    return dynamic;
  }

  // Step 5: objects of side s that are not the same object in the other session (another car
  // in the same slot). Every object of side s it examines goes to `examined`, with `changed`
  // decided by its own comparison; PartnersOfChanged then adds the other side's partners.
  void ExamineObjects(int s, std::vector<DynamicDetectionResult::ExaminedObject>* examined) {
    const Side& side = sides_[s];
    const int other = 1 - s;
    const std::size_t n = side.points.size();
    const double range_sq = config_.changed_compare_range_m * config_.changed_compare_range_m;
    std::vector<std::uint8_t> eligible(n, 0);
    for (std::size_t i = 0; i < n; ++i) {
      eligible[i] = side.height_m[i] >= config_.ground_tolerance_m &&
                    NearAny(side.origins, side.points[i], range_sq) &&
                    NearAny(sides_[other].origins, side.points[i], range_sq);
    }
    std::vector<std::uint32_t> cluster;
    for (std::size_t seed = 0; seed < n; ++seed) {
      if (!eligible[seed]) continue;
      // Euclidean clustering; eligible[] doubles as the visited mark (cleared when taken).
      eligible[seed] = 0;
      Grow(s, static_cast<std::uint32_t>(seed), config_.changed_grow_radius_m,
           [&](std::uint32_t j) {
             if (!eligible[j]) return false;
             eligible[j] = 0;
             return true;
           },
           &cluster);
      if (static_cast<int>(cluster.size()) < config_.changed_min_points) continue;
      // The shape of the whole object, not of its cut by the compare range: a wall or hedge
      // that leaves the range would pass for a car-sized object.
      if (!MovableShape(s, cluster) ||
          (TouchesFarBand(side, cluster) && !StandsOnWideGround(s, cluster)) ||
          !WholeObjectIsMovable(s, cluster)) {
        continue;
      }
      DynamicDetectionResult::ExaminedObject object;
      object.side = s;
      object.points = cluster;
      CompareSurfaces(s, cluster, &object);
      object.changed = object.compared >= config_.changed_min_compared &&
                       object.off_surface >= config_.changed_min_fraction * object.compared;
      for (int end = 0; end < 2 && config_.changed_end_min_compared > 0; ++end) {
        object.changed = object.changed ||
                         (object.end_compared[end] >= config_.changed_end_min_compared &&
                          object.end_off[end] >=
                              config_.changed_end_min_fraction * object.end_compared[end]);
      }
      examined->push_back(std::move(object));
    }
  }

  // Step 5, partners: two different objects in one place are both changed (the other car in
  // the slot is in neither session's place of the first). An examined object that is not
  // changed by its own comparison becomes changed when one of its points has a point of an
  // object changed on the other side among its 4 nearest other-side points within
  // changed_neighbour_radius_m, and at least changed_partner_min_fraction of its compared
  // points contradict (it must disagree a little itself: a car that stayed, flagged wrongly on
  // one side, keeps its other copy).
  void PartnersOfChanged(std::vector<DynamicDetectionResult::ExaminedObject>* examined) {
    if (config_.changed_partner_min_fraction >= config_.changed_min_fraction) return;
    std::vector<std::uint8_t> changed_point[2];
    for (int s : {kHistory, kCurrent}) changed_point[s].assign(sides_[s].points.size(), 0);
    for (const auto& object : *examined) {
      if (!object.changed) continue;
      for (std::uint32_t i : object.points) changed_point[object.side][i] = 1;
    }
    std::vector<std::uint32_t> neighbours;
    for (auto& object : *examined) {
      if (object.changed || object.compared < config_.changed_min_compared ||
          object.off_surface < config_.changed_partner_min_fraction * object.compared) {
        continue;
      }
      const int other = 1 - object.side;
      for (std::uint32_t i : object.points) {
        indices_[other]->Nearest(sides_[object.side].points[i], 4,
                                 config_.changed_neighbour_radius_m, &neighbours);
        if (std::any_of(neighbours.begin(), neighbours.end(),
                        [&](std::uint32_t j) { return changed_point[other][j] != 0; })) {
          object.changed = object.by_partner = true;
          break;
        }
      }
    }
  }

  // Step 5's outcome for side s: `dynamic` (sorted) loses the points of the objects found the
  // same in both sessions (changed_same_max_fraction) and gains those of the changed objects.
  // The objects of one side are disjoint: ExamineObjects takes every point into one cluster at
  // most.
  void ApplyExamined(int s, const std::vector<DynamicDetectionResult::ExaminedObject>& examined,
                     std::vector<std::uint32_t>* dynamic) const {
    std::vector<std::uint32_t> changed, same;
    for (const auto& object : examined) {
      if (object.side != s) continue;
      std::vector<std::uint32_t>* into =
          object.changed ? &changed : IsSame(object) ? &same : nullptr;
      if (into != nullptr) into->insert(into->end(), object.points.begin(), object.points.end());
    }
    std::sort(changed.begin(), changed.end());
    std::sort(same.begin(), same.end());
    std::vector<std::uint32_t> kept;
    kept.reserve(dynamic->size());
    std::set_difference(dynamic->begin(), dynamic->end(), same.begin(), same.end(),
                        std::back_inserter(kept));
    dynamic->clear();
    std::set_union(kept.begin(), kept.end(), changed.begin(), changed.end(),
                   std::back_inserter(*dynamic));
  }

  // Step 6: the low residue of side s (DynamicDetectionConfig::low_residue_min_ground_points),
  // merged into its sorted `dynamic` points.
  void AddLowResidue(int s, std::vector<std::uint32_t>* dynamic) const {
    const Side& side = sides_[s];
    const int other = 1 - s;
    const Side& theirs = sides_[other];
    const float low = static_cast<float>(config_.bottom_min_height_m);
    const double range_sq = config_.low_residue_range_m * config_.low_residue_range_m;
    const double radius_sq = config_.low_residue_radius_m * config_.low_residue_radius_m;
    const double partner_sq =
        config_.low_residue_partner_distance_m * config_.low_residue_partner_distance_m;
    // A partner is above the ground or at the point's level, horizontally within the partner
    // distance and at most kPartnerRise above the point (the rest of a trunk, a post or a
    // wall whose foot the two sessions sampled at different places). The search reaches
    // kPartnerRise up and down: the other session's ground lies about the point's height
    // above its own ground below it, more where the two grounds differ (0.1-0.3 m).
    constexpr double kPartnerRise = 0.5;
    // Their points at most this far below the point are at its level (partners); ground is
    // lower (range noise of a ground voxel's returns is a few centimetres).
    constexpr double kLevel = 0.05;
    const double search = std::hypot(std::max(config_.low_residue_radius_m,
                                              config_.low_residue_partner_distance_m),
                                     std::max(config_.ground_tolerance_m, kPartnerRise));
    std::vector<std::uint32_t> residue, neighbours;
    for (std::uint32_t i = 0; i < side.points.size(); ++i) {
      if (!InBottomLayer(s, i)) continue;
      if (std::binary_search(dynamic->begin(), dynamic->end(), i)) continue;
      const Eigen::Vector3d& p = side.points[i];
      if (!NearAny(theirs.origins, p, range_sq)) continue;
      indices_[other]->Radius(p, search, &neighbours);
      int ground = 0;
      bool partner = false;
      for (const std::uint32_t j : neighbours) {
        const Eigen::Vector3d d = theirs.points[j] - p;
        const double horizontal_sq = d.head<2>().squaredNorm();
        // Above their ground, or at the point's own level (the sessions' ground estimates
        // differ at a curb or a step: each session's ground cell may take the other level).
        const bool level = d.z() >= -kLevel;
        if (level || theirs.height_m[j] >= low) {
          if (horizontal_sq <= partner_sq && d.z() <= kPartnerRise) {
            partner = true;
            break;
          }
        } else if (horizontal_sq <= radius_sq) {
          ++ground;
        }
      }
      if (partner || ground < config_.low_residue_min_ground_points) continue;
      if (config_.low_residue_max_own_neighbours > 0) {
        // A small blob (a foot, the bottom of a wheel), not a long low object (a curb).
        indices_[s]->Radius(p, config_.low_residue_blob_radius_m, &neighbours);
        int own = 0;
        for (const std::uint32_t j : neighbours) own += InBottomLayer(s, j);
        if (own > config_.low_residue_max_own_neighbours) continue;
      }
      residue.push_back(i);
    }
    std::vector<std::uint32_t> merged;
    merged.reserve(dynamic->size() + residue.size());
    std::merge(dynamic->begin(), dynamic->end(), residue.begin(), residue.end(),
               std::back_inserter(merged));
    dynamic->swap(merged);
  }

  // An examined object that is not changed and agrees with the other session on all but
  // changed_same_max_fraction of at least changed_min_compared compared points (rule on).
  bool IsSame(const DynamicDetectionResult::ExaminedObject& object) const {
    return config_.changed_same_max_fraction > 0.0 && !object.changed &&
           object.compared >= config_.changed_min_compared &&
           object.off_surface <= config_.changed_same_max_fraction * object.compared;
  }

  // Step 7: current points missing from the history and not seen through by it.
  std::vector<std::uint32_t> Mending(const std::vector<std::uint32_t>& current_dynamic) const {
    const Side& side = sides_[kCurrent];
    std::vector<std::uint8_t> dynamic(side.points.size(), 0);
    for (std::uint32_t i : current_dynamic) dynamic[i] = 1;
    std::vector<std::uint32_t> mending;
    for (std::size_t i = 0; i < side.points.size(); ++i) {
      if (dynamic[i] || side.far[i] || side.nearest_other_m[i] <= config_.mending_distance_m) {
        continue;
      }
      const RayVoxelGrid::Cell* cell = grid_->Find(grid_->KeyOf(side.points[i]));
      if (cell != nullptr && cell->count[kHistory] >= config_.min_passing_rays) continue;
      mending.push_back(static_cast<std::uint32_t>(i));
    }
    return mending;
  }

 private:
  // Adds the points below an accepted object down to bottom_min_height_m above the ground
  // (marked in `taken`): within bottom_extension_radius_m horizontally of an object point and
  // at most bottom_max_drop_m below it, repeated from each added point, and not common with
  // the other session (the ground beside the object, seen by both, stays).
  void ExtendDown(int s, const std::vector<std::uint32_t>& object, std::vector<std::uint8_t>* taken,
                  std::vector<std::uint32_t>* dynamic) const {
    const Side& side = sides_[s];
    const double r = config_.bottom_extension_radius_m;
    const double search = std::hypot(r, config_.bottom_max_drop_m);
    Spread(s, std::deque<std::uint32_t>(object.begin(), object.end()), search,
           [&](std::uint32_t i, std::uint32_t j) {
             if ((*taken)[j] || !InBottomLayer(s, j)) return false;
             // The other session has it too: ground beside the object.
             if (side.common[j]) return false;
             const Eigen::Vector3d d = side.points[i] - side.points[j];
             if (d.z() <= 0.0 || d.z() > config_.bottom_max_drop_m || d.head<2>().norm() > r) {
               return false;
             }
             (*taken)[j] = 1;
             dynamic->push_back(j);
             return true;
           },
           nullptr);
  }

  // Whether point i of side s lies in the layer right above the ground that rays cannot
  // judge: from bottom_min_height_m up to ground_tolerance_m (wheels, feet; steps 4 and 6).
  bool InBottomLayer(int s, std::uint32_t i) const {
    const float h = sides_[s].height_m[i];
    return h >= static_cast<float>(config_.bottom_min_height_m) &&
           h < static_cast<float>(config_.ground_tolerance_m);
  }

  // Breadth-first spread over side s from the points in `queue` (already taken): each point
  // taken from the queue goes to `reached` (when given), and its neighbour j within radius_m
  // joins the queue when take(i, j) says so (take marks it). The region growings of all steps.
  // With `stop`, the spread ends as soon as stop() says so (points still queued are left).
  template <typename Take, typename Stop = bool (*)()>
  void Spread(int s, std::deque<std::uint32_t> queue, double radius_m, Take take,
              std::vector<std::uint32_t>* reached, Stop stop = [] { return false; }) const {
    std::vector<std::uint32_t> neighbours;
    while (!queue.empty() && !stop()) {
      const std::uint32_t i = queue.front();
      queue.pop_front();
      if (reached != nullptr) reached->push_back(i);
      indices_[s]->Radius(sides_[s].points[i], radius_m, &neighbours);
      for (std::uint32_t j : neighbours) {
        if (take(i, j)) queue.push_back(j);
      }
    }
  }

  // Euclidean growth from one `seed` (already taken): neighbour j joins when take(j) says so.
  // `cluster` gets the seed and every point that joined.
  template <typename Take>
  void Grow(int s, std::uint32_t seed, double radius_m, Take take,
            std::vector<std::uint32_t>* cluster) const {
    cluster->clear();
    Spread(s, {seed}, radius_m, [&](std::uint32_t, std::uint32_t j) { return take(j); }, cluster);
  }

  // Above the height guard and the object height it lets grow nothing is dynamic.
  bool NeverDynamic(float height_m) const {
    return config_.height_guard_enabled &&
           height_m > std::max(config_.height_guard_m, config_.guard_object_height_m);
  }

  // How far from the other session's origins points are examined [m].
  double ExaminedRange() const { return std::max(config_.max_range_m, config_.far_range_m); }

  static bool TouchesFarBand(const Side& side, const std::vector<std::uint32_t>& cluster) {
    return std::any_of(cluster.begin(), cluster.end(),
                       [&](std::uint32_t i) { return side.far[i] != 0; });
  }

  // The far band's shape test: the detection grown over every above-ground point of its
  // submap (also the common ones and those above the guard, as the changed-object step's
  // objects) must have a movable object's shape. A detection in the lower part of a tree
  // crown whose ground nobody measured (its own lowest points pass for the ground) is part of
  // a taller or wider object. Growth stops once the object is too wide or too tall.
  bool WholeObjectIsMovable(int s, const std::vector<std::uint32_t>& detection) {
    const Side& side = sides_[s];
    std::vector<std::uint8_t>& taken = object_mark_[s];
    taken.resize(side.points.size(), 0);
    std::vector<std::uint32_t> object(detection.begin(), detection.end());
    for (std::uint32_t i : object) taken[i] = 1;
    Eigen::Vector2d lo = side.points[object.front()].head<2>(), hi = lo;
    for (std::uint32_t i : object) {
      lo = lo.cwiseMin(side.points[i].head<2>());
      hi = hi.cwiseMax(side.points[i].head<2>());
    }
    const double max_extent_sq = config_.changed_max_extent_m * config_.changed_max_extent_m;
    bool too_large = false;
    Spread(s, std::deque<std::uint32_t>(detection.begin(), detection.end()),
           config_.changed_grow_radius_m,
           [&](std::uint32_t, std::uint32_t j) {
             if (too_large || taken[j] || side.height_m[j] < config_.ground_tolerance_m) {
               return false;
             }
             taken[j] = 1;
             object.push_back(j);
             lo = lo.cwiseMin(side.points[j].head<2>());
             hi = hi.cwiseMax(side.points[j].head<2>());
             too_large = (hi - lo).squaredNorm() > max_extent_sq ||
                         side.height_m[j] > config_.guard_object_height_m;
             return !too_large;
           },
           nullptr, [&] { return too_large; });
    for (std::uint32_t i : object) taken[i] = 0;
    return !too_large && MovableShape(s, object);
  }

  // The far band's ground around an object: its lowest point is at most far_max_bottom_m
  // above the lowest point of both submaps around it (far_ground_cell_m; always true when
  // that is 0).
  bool StandsOnWideGround(int s, const std::vector<std::uint32_t>& cluster) {
    if (config_.far_ground_cell_m <= 0.0) return true;
    if (!wide_ground_) {
      wide_ground_ = std::make_unique<GroundGrid>(
          std::initializer_list<const Side*>{&sides_[0], &sides_[1]},
          config_.far_ground_cell_m);
    }
    const Side& side = sides_[s];
    std::uint32_t lowest = cluster.front();
    for (std::uint32_t i : cluster) {
      if (side.points[i].z() < side.points[lowest].z()) lowest = i;
    }
    return wide_ground_->HeightAbove(side.points[lowest]) <= config_.far_max_bottom_m;
  }

  // An object of movable size standing on the ground with mostly planar surfaces.
  bool MovableShape(int s, const std::vector<std::uint32_t>& cluster) {
    const Side& side = sides_[s];
    Eigen::Vector2d lo = side.points[cluster.front()].head<2>(), hi = lo;
    float bottom = std::numeric_limits<float>::infinity(), top = -bottom;
    int planar = 0;
    Eigen::Vector3f normal;
    for (std::uint32_t i : cluster) {
      lo = lo.cwiseMin(side.points[i].head<2>());
      hi = hi.cwiseMax(side.points[i].head<2>());
      bottom = std::min(bottom, side.height_m[i]);
      top = std::max(top, side.height_m[i]);
      planar += Normal(s, i, &normal);
    }
    return (hi - lo).norm() <= config_.changed_max_extent_m &&
           top <= config_.guard_object_height_m && bottom <= config_.changed_max_bottom_m &&
           planar >= config_.changed_min_planar_fraction * static_cast<double>(cluster.size());
  }

  // Counts the object's points where the other session says something (compared): it has an
  // above-ground point within changed_neighbour_radius_m, one of them with a normal unless one
  // is close enough, or else its rays passed through the point's voxel (at least
  // min_passing_rays). Of those, the points that contradict the other session (off): farther
  // than changed_surface_distance_m from every such neighbour's surface, or seen through.
  void CompareSurfaces(int s, const std::vector<std::uint32_t>& cluster,
                       DynamicDetectionResult::ExaminedObject* object) {
    const int other = 1 - s;
    const Side& theirs = sides_[other];
    std::vector<std::uint32_t> neighbours;
    Eigen::Vector3f normal;
    // The object's longest horizontal axis and centroid, for its ends (when the rule is on).
    const bool ends = config_.changed_end_min_compared > 0;
    Eigen::Vector2d centroid = Eigen::Vector2d::Zero();
    Eigen::Vector2d axis = Eigen::Vector2d::UnitX();
    if (ends) {
      for (std::uint32_t i : cluster) centroid += sides_[s].points[i].head<2>();
      centroid /= static_cast<double>(cluster.size());
      Eigen::Matrix2d scatter = Eigen::Matrix2d::Zero();
      for (std::uint32_t i : cluster) {
        const Eigen::Vector2d d = sides_[s].points[i].head<2>() - centroid;
        scatter += d * d.transpose();
      }
      // Eigenvalues ascend: the last eigenvector is the longest axis.
      axis = Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(scatter).eigenvectors().col(1);
    }
    for (std::uint32_t i : cluster) {
      const Eigen::Vector3d& p = sides_[s].points[i];
      // Which end the point is on, if its own surface faces along the axis (-1: none).
      int end = -1;
      Eigen::Vector3f own;
      if (ends && Normal(s, i, &own)) {
        const Eigen::Vector2d horizontal = own.head<2>().cast<double>();
        if (std::abs(horizontal.dot(axis)) >= config_.changed_end_min_cos * own.norm()) {
          end = (p.head<2>() - centroid).dot(axis) >= 0.0 ? 0 : 1;
        }
      }
      indices_[other]->Nearest(p, 8, config_.changed_neighbour_radius_m, &neighbours);
      bool any = false, planar = false, on_surface = false;
      for (std::uint32_t j : neighbours) {
        if (theirs.height_m[j] < config_.ground_tolerance_m) continue;
        any = true;
        const Eigen::Vector3d d = p - theirs.points[j];
        const bool has_normal = Normal(other, j, &normal);
        planar = planar || has_normal;
        const double distance = has_normal ? std::abs(normal.cast<double>().dot(d)) : d.norm();
        if (distance <= config_.changed_surface_distance_m) {
          on_surface = true;
          break;
        }
      }
      // Off a surface only where the other session has one (a planar neighbour): the gaps
      // between sparse samples of an edge or a blurred surface say nothing.
      if (any && !on_surface && !planar) continue;
      if (!any) {
        const RayVoxelGrid::Cell* cell = grid_->Find(grid_->KeyOf(p));
        if (cell != nullptr && cell->count[other] >= config_.min_passing_rays) {
          ++object->compared;
          ++object->off_surface;
          ++object->seen_through;
        }
        continue;
      }
      ++object->compared;
      object->off_surface += !on_surface;
      if (end >= 0) CompareEnd(other, p, own, neighbours, &object->end_compared[end],
                               &object->end_off[end]);
    }
  }

  // An end point is judged only by the other session's surfaces that face the same way (its
  // neighbours with a normal within acos(changed_end_min_cos) of the point's own): the other
  // car's end. Beside a corner the other session's side of the same car is near too, off the
  // end's plane; and an end the other session saw through says nothing about which car it
  // was (cars that stayed had such ends at times).
  void CompareEnd(int other, const Eigen::Vector3d& p, const Eigen::Vector3f& own,
                  const std::vector<std::uint32_t>& neighbours, int* compared, int* off) {
    const Side& theirs = sides_[other];
    Eigen::Vector3f normal;
    bool facing = false;
    for (std::uint32_t j : neighbours) {
      if (theirs.height_m[j] < config_.ground_tolerance_m || !Normal(other, j, &normal) ||
          std::abs(normal.dot(own)) < config_.changed_end_min_cos) {
        continue;
      }
      facing = true;
      if (std::abs(normal.cast<double>().dot(p - theirs.points[j])) <=
          config_.changed_surface_distance_m) {
        ++*compared;
        return;
      }
    }
    *compared += facing ? 1 : 0;
    *off += facing ? 1 : 0;
  }

  // Calls visit(key) for the voxels below the voxel of point i of side s, one after the other
  // down to column_clearance_m above its local ground and at most free_column_depth_m deep,
  // while visit returns true.
  template <typename Visit>
  void ForFreeColumn(int s, std::size_t i, Visit visit) const {
    const Side& side = sides_[s];
    const double depth_m = std::min(config_.free_column_depth_m,
                                    side.height_m[i] - config_.column_clearance_m);
    const int voxels = static_cast<int>(std::floor(depth_m / config_.voxel_size_m));
    Eigen::Vector3i key = grid_->KeyOf(side.points[i]);
    for (int k = 0; k < voxels; ++k) {
      --key.z();
      if (!visit(key)) return;
    }
  }

  // Normal of the point's voxel (edge normal_voxel_m) from all points of its submap in it:
  // one covariance per voxel instead of a neighbour search per point. A voxel that holds
  // foliage is not planar; a point farther than grow_radius_m / 3 from its voxel's plane
  // (a car's side in a voxel dominated by the ground below it) gets no normal. Both stop the
  // growth.
  bool Normal(int s, std::uint32_t i, Eigen::Vector3f* normal) {
    Side& side = sides_[s];
    if (side.normal_state[i] == 0) {
      VoxelMap<VoxelPlane>& planes = voxel_planes_[s];
      if (planes.empty()) {
        for (const Eigen::Vector3d& p : side.points) {
          VoxelPlane& plane = planes[ToVoxelKey(p, config_.normal_voxel_m)];
          plane.covariance.Add(p);
          plane.sum += p;
        }
        for (auto& [key, plane] : planes) {
          plane.planar = plane.covariance.Normal(plane_, &plane.normal);
          plane.sum /= plane.covariance.count();
        }
      }
      const VoxelPlane& plane = planes.at(ToVoxelKey(side.points[i], config_.normal_voxel_m));
      if (plane.planar && std::abs(plane.normal.dot(side.points[i] - plane.sum)) <=
                              config_.grow_radius_m / 3.0) {
        side.normals[i] = plane.normal.cast<float>();
        side.normal_state[i] = 1;
      } else {
        side.normal_state[i] = 2;
      }
    }
    *normal = side.normals[i];
    return side.normal_state[i] == 1;
  }

  bool Compatible(int s, std::uint32_t a, std::uint32_t b) {
    Eigen::Vector3f na, nb;
    // Never across the ground's rim: objects standing on the ground stay apart from it.
    const float tol = static_cast<float>(config_.ground_tolerance_m);
    if ((sides_[s].height_m[a] < tol) != (sides_[s].height_m[b] < tol)) return false;
    if (!Normal(s, a, &na) || !Normal(s, b, &nb)) return false;
    // Similar normals and the neighbour on the tangent plane (not a step up from the ground).
    const Eigen::Vector3f d = (sides_[s].points[b] - sides_[s].points[a]).cast<float>();
    const float off_plane = static_cast<float>(config_.grow_radius_m / 3.0);
    return std::abs(na.dot(nb)) >= cos_max_angle_ && std::abs(na.dot(d)) <= off_plane &&
           std::abs(nb.dot(d)) <= off_plane;
  }

  // Region growing from the seeds over points with compatible normals. Only points that are
  // not seeds are searched from: their common neighbours start the growth. The grown set is
  // every non-seed point joined to a seed by a chain of compatible neighbours, whatever the
  // order; so a point that joins spreads at once, with the neighbours of its own search, and
  // the points it reaches skip theirs (each grown point is searched once, not twice).
  void GrowCommon(int s) {
    Side& side = sides_[s];
    cos_max_angle_ = static_cast<float>(std::cos(config_.grow_max_normal_angle_rad));
    const auto take = [&](std::uint32_t i, std::uint32_t j) {
      if (side.common[j] || !Compatible(s, i, j)) return false;
      side.common[j] = 2;  // grown (2) rather than seed (1): no effect beyond bookkeeping
      return true;
    };
    std::vector<std::uint32_t> neighbours;
    std::deque<std::uint32_t> queue;
    for (std::size_t n = 0; n < side.points.size(); ++n) {
      const auto i = static_cast<std::uint32_t>(n);
      if (side.common[i] || side.no_seed_near[i]) continue;
      indices_[s]->Radius(side.points[i], config_.grow_radius_m, &neighbours);
      if (std::none_of(neighbours.begin(), neighbours.end(), [&](std::uint32_t j) {
            return side.common[j] == 1 && Compatible(s, i, j);
          })) {
        continue;
      }
      side.common[i] = 2;
      queue.clear();
      for (std::uint32_t j : neighbours) {
        if (take(i, j)) queue.push_back(j);
      }
      Spread(s, std::move(queue), config_.grow_radius_m, take, nullptr);
    }
  }

  // Whether a ray of side s (unit direction) meets the plane of the other side's point that
  // queried `cell` at less than min_pass_incidence_rad (see the config).
  bool Grazing(int s, const RayVoxelGrid::Cell* cell, const Eigen::Vector3f& direction) const {
    const auto& normals = pass_normals_[1 - s];
    if (normals.empty()) return false;
    const auto it = normals.find(cell);
    return it != normals.end() && std::abs(it->second.dot(direction)) < min_pass_sin_;
  }

  // Rays from the thinned origins of side s to its points; counts the passes through voxels
  // queried by the other side. A ray blocked by its own session's occupied voxel is dropped.
  void CastSide(int s) {
    const Side& side = sides_[s];
    const std::uint8_t own = kOccupied[s];
    const std::uint8_t query = kQueried[1 - s];
    const std::uint8_t query_far = kQueriedFar[1 - s];
    const std::size_t k = std::min<std::size_t>(static_cast<std::size_t>(config_.rays_per_point),
                                                side.origins.size());
    const double max_len_sq = config_.max_ray_length_m * config_.max_ray_length_m;
    const double origin_clearance_m = config_.voxel_size_m;
    // Candidate ray origins of a point by squared distance.
    std::vector<std::pair<double, const Eigen::Vector3d*>> nearest;
    std::vector<RayVoxelGrid::Cell*> passed;
    const auto add_origin = [&](const Eigen::Vector3d& o, const Eigen::Vector3d& p) {
      const double d2 = (o - p).squaredNorm();
      if (d2 <= max_len_sq) nearest.emplace_back(d2, &o);
    };
    for (std::size_t i = 0; i < side.points.size(); ++i) {
      const Eigen::Vector3d& p = side.points[i];
      nearest.clear();
      const PointViews* views = side.views != nullptr ? &(*side.views)[i] : nullptr;
      if (views != nullptr && views->nearest_scan < side.scan_origins.size() &&
          views->last_scan < side.scan_origins.size()) {
        // Rays to the scans that measured the point.
        add_origin(side.scan_origins[views->nearest_scan], p);
        if (views->last_scan != views->nearest_scan) {
          add_origin(side.scan_origins[views->last_scan], p);
        }
      } else {
        for (const Eigen::Vector3d& o : side.origins) add_origin(o, p);
      }
      const std::size_t rays = std::min(k, nearest.size());
      std::partial_sort(nearest.begin(), nearest.begin() + rays, nearest.end());
      for (std::size_t r = 0; r < rays; ++r) {
        const Eigen::Vector3d& o = *nearest[r].second;
        const double length = std::sqrt(nearest[r].first);
        double margin = config_.end_margin_m;
        if (side.height_m[i] < config_.ground_tolerance_m && length > 0.0) {
          const double sin_elevation = std::abs(o.z() - p.z()) / length;
          margin = std::min(config_.max_end_margin_m,
                            config_.end_margin_m / std::max(sin_elevation, 1e-3));
        }
        // Beyond the examined range from the origin no voxel is examined.
        const double free_until = std::min(length - margin, ExaminedRange());
        if (free_until <= origin_clearance_m) continue;
        bool relevant = false;
        coarse_->Traverse(o, p, [&](RayVoxelGrid::Cell* cell, double entry_m) {
          if (entry_m >= free_until) return false;
          // (a coarse cell is 8 voxels wide: it may reach back below max_range_m)
          const bool beyond = entry_m > config_.max_range_m;
          relevant = cell != nullptr && (cell->flags & (beyond ? query_far : query));
          return !relevant;
        });
        if (!relevant) continue;
        passed.clear();
        bool blocked = false;
        // The walk goes backwards, from where the examined stretch ends to the origin: half of
        // these rays are blocked by their own session, two thirds of those within the last
        // fifth of the ray (grazing their own surface near the point), and stop early. An own
        // voxel blocks when the ray enters it (coming from the origin) beyond the clearance,
        // that is where the backward walk leaves it; the voxel of the origin never blocks.
        const Eigen::Vector3d end = o + (p - o) * (free_until / length);
        const Eigen::Vector3f direction = ((p - o) / length).cast<float>();
        bool previous_own = false;
        grid_->Traverse(end, o, [&](RayVoxelGrid::Cell* cell, double back_m) {
          if (previous_own && free_until - back_m > origin_clearance_m) {
            blocked = true;
            return false;
          }
          previous_own = cell != nullptr && (cell->flags & own);
          // Beyond max_range_m along the ray a pass counts only for the far band, so that
          // the points within max_range_m get the evidence they got without it.
          const std::uint8_t wanted =
              free_until - back_m > config_.max_range_m ? query_far : query;
          if (cell != nullptr && (cell->flags & wanted) && !Grazing(s, cell, direction)) {
            passed.push_back(cell);
          }
          return true;
        });
        if (blocked) continue;
        for (RayVoxelGrid::Cell* cell : passed) {
          if (cell->count[s] < 255) ++cell->count[s];
        }
      }
    }
  }

  const DynamicDetectionConfig& config_;
  Side* sides_;
  const FrameIndex* indices_[2];  // kHistory, kCurrent
  std::unique_ptr<RayVoxelGrid> grid_;
  std::unique_ptr<RayVoxelGrid> coarse_;
  LocalPlaneCriteria plane_;
  float cos_max_angle_ = 1.0f;
  struct VoxelPlane {
    CovarianceAccumulator covariance;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();  // the centroid once finished
    Eigen::Vector3d normal = Eigen::Vector3d::Zero();
    bool planar = false;
  };
  VoxelMap<VoxelPlane> voxel_planes_[2];
  std::vector<std::uint8_t> object_mark_[2];  // scratch marks of WholeObjectIsMovable
  std::unique_ptr<GroundGrid> wide_ground_;  // StandsOnWideGround's, built on first use
  // Per side: normal of the planar point that queried a voxel (min_pass_incidence_rad).
  std::unordered_map<const RayVoxelGrid::Cell*, Eigen::Vector3f> pass_normals_[2];
  float min_pass_sin_ = 0.0f;
};

}  // namespace

bool NearAny(const PointVector& origins, const Eigen::Vector3d& p, double range_sq) {
  for (const Eigen::Vector3d& o : origins) {
    if ((o - p).squaredNorm() <= range_sq) return true;
  }
  return false;
}

void DynamicDetectionResult::StageTimes::Add(const StageTimes& other) {
  index_s += other.index_s;
  ground_s += other.ground_s;
  common_s += other.common_s;
  rays_s += other.rays_s;
  dynamic_s += other.dynamic_s;
  changed_s += other.changed_s;
  mending_s += other.mending_s;
}

bool DynamicDetectionResult::MarksMoreThan(double fraction, std::size_t history_points,
                                           std::size_t current_points) const {
  return history_dynamic.size() > fraction * std::max<std::size_t>(1, history_points) ||
         current_dynamic.size() > fraction * std::max<std::size_t>(1, current_points);
}

Status DynamicDetectionConfig::Validate() const {
  for (const auto& [name, value] :
       {std::pair<const char*, double>{"seed_distance_m", seed_distance_m},
        {"grow_radius_m", grow_radius_m},
        {"normal_voxel_m", normal_voxel_m},
        {"voxel_size_m", voxel_size_m},
        {"origin_spacing_m", origin_spacing_m},
        {"max_ray_length_m", max_ray_length_m},
        {"max_range_m", max_range_m},
        {"end_margin_m", end_margin_m},
        {"max_end_margin_m", max_end_margin_m},
        {"support_radius_m", support_radius_m},
        {"dynamic_grow_radius_m", dynamic_grow_radius_m},
        {"ground_cell_m", ground_cell_m},
        {"height_guard_m", height_guard_m},
        {"guard_object_height_m", guard_object_height_m},
        {"mending_distance_m", mending_distance_m},
        {"changed_compare_range_m", changed_compare_range_m},
        {"changed_grow_radius_m", changed_grow_radius_m},
        {"changed_max_extent_m", changed_max_extent_m},
        {"changed_max_bottom_m", changed_max_bottom_m},
        {"far_max_bottom_m", far_max_bottom_m},
        {"changed_neighbour_radius_m", changed_neighbour_radius_m},
        {"changed_surface_distance_m", changed_surface_distance_m}}) {
    const Status status = CheckPositive(name, value);
    if (!status.ok()) return status;
  }
  // A cell below the local ground's would not be a wider ground (and a tiny one a huge grid).
  if (!std::isfinite(far_ground_cell_m) ||
      !(far_ground_cell_m == 0.0 || far_ground_cell_m >= ground_cell_m)) {
    return Status::Error(
        "dynamic_detection.far_ground_cell_m must be 0 (off) or at least ground_cell_m");
  }
  if (!(min_cluster_coarse_fraction >= 0.0 && min_cluster_coarse_fraction <= 1.0)) {
    return Status::Error("dynamic_detection.min_cluster_coarse_fraction must be in [0, 1]");
  }
  if (!std::isfinite(min_pass_incidence_rad) || min_pass_incidence_rad < 0.0 ||
      min_pass_incidence_rad > M_PI / 2) {
    return Status::Error("dynamic_detection.min_pass_incidence_rad must be in [0, pi/2]");
  }
  if (!std::isfinite(grow_max_normal_angle_rad) || grow_max_normal_angle_rad < 0.0 ||
      grow_max_normal_angle_rad > M_PI / 2) {
    return Status::Error("dynamic_detection.grow_max_normal_angle_rad must be in [0, pi/2]");
  }
  if (!std::isfinite(free_column_depth_m) || free_column_depth_m < 0.0 ||
      !std::isfinite(column_clearance_m) || column_clearance_m < 0.0) {
    return Status::Error(
        "dynamic_detection.free_column_depth_m and column_clearance_m must be >= 0");
  }
  if (!std::isfinite(own_ground_max_gap_m) || own_ground_max_gap_m < 0.0) {
    return Status::Error("dynamic_detection.own_ground_max_gap_m must be >= 0");
  }
  if (!std::isfinite(ground_tolerance_m) || ground_tolerance_m < 0.0) {
    return Status::Error("dynamic_detection.ground_tolerance_m must be >= 0");
  }
  if (!std::isfinite(far_range_m) || far_range_m < 0.0) {
    return Status::Error("dynamic_detection.far_range_m must be >= 0 (0: off)");
  }
  if (!std::isfinite(max_object_bottom_m) || max_object_bottom_m < 0.0) {
    return Status::Error("dynamic_detection.max_object_bottom_m must be >= 0 (0: off)");
  }
  if (!std::isfinite(bottom_extension_radius_m) || bottom_extension_radius_m < 0.0 ||
      !std::isfinite(bottom_min_height_m) || bottom_min_height_m < 0.0 ||
      !std::isfinite(bottom_max_drop_m) || bottom_max_drop_m <= 0.0) {
    return Status::Error(
        "dynamic_detection: bottom_extension_radius_m and bottom_min_height_m must be >= 0 "
        "(radius 0: off), bottom_max_drop_m > 0");
  }
  if (voxel_size_m < 0.01) {
    return Status::Error("dynamic_detection.voxel_size_m must be >= 0.01 (memory), got " +
                         std::to_string(voxel_size_m));
  }
  if (max_end_margin_m < end_margin_m) {
    return Status::Error("dynamic_detection.max_end_margin_m must be >= end_margin_m");
  }
  if (rays_per_point < 1) return Status::Error("dynamic_detection.rays_per_point must be >= 1");
  if (min_passing_rays < 1 || min_passing_rays > 255) {
    return Status::Error("dynamic_detection.min_passing_rays must be in [1, 255]");
  }
  if (max_support_points < 0) {
    return Status::Error("dynamic_detection.max_support_points must be >= 0");
  }
  if (min_cluster_points < 1 || min_cluster_coarse_points < 1 ||
      min_cluster_coarse_points > min_cluster_points) {
    return Status::Error(
        "dynamic_detection: need 1 <= min_cluster_coarse_points <= min_cluster_points");
  }
  if (changed_min_points < 1 || changed_min_compared < 1) {
    return Status::Error(
        "dynamic_detection.changed_min_points and changed_min_compared must be >= 1");
  }
  if (!std::isfinite(changed_min_planar_fraction) || changed_min_planar_fraction < 0.0 ||
      changed_min_planar_fraction > 1.0 || !std::isfinite(changed_min_fraction) ||
      changed_min_fraction <= 0.0 || changed_min_fraction > 1.0 ||
      !std::isfinite(changed_partner_min_fraction) || changed_partner_min_fraction < 0.0 ||
      changed_partner_min_fraction > 1.0) {
    return Status::Error(
        "dynamic_detection.changed_min_planar_fraction and changed_partner_min_fraction must "
        "be in [0, 1] and changed_min_fraction in (0, 1]");
  }
  if (!(changed_same_max_fraction >= 0.0) ||
      (changed_same_max_fraction > 0.0 && !(changed_same_max_fraction < changed_min_fraction))) {
    return Status::Error(
        "dynamic_detection.changed_same_max_fraction must be >= 0 (0: off) and below "
        "changed_min_fraction");
  }
  if (low_residue_min_ground_points < 0 || low_residue_max_own_neighbours < 0 ||
      !(low_residue_radius_m > 0.0) || !std::isfinite(low_residue_radius_m) ||
      !(low_residue_partner_distance_m >= 0.0) || !std::isfinite(low_residue_partner_distance_m) ||
      !(low_residue_range_m > 0.0) || !(low_residue_range_m <= max_range_m) ||
      !(low_residue_blob_radius_m > 0.0) || !std::isfinite(low_residue_blob_radius_m)) {
    return Status::Error(
        "dynamic_detection: low_residue_min_ground_points and low_residue_max_own_neighbours "
        "must be >= 0 (0: off / no limit), low_residue_partner_distance_m >= 0, "
        "low_residue_radius_m and low_residue_blob_radius_m > 0, low_residue_range_m in "
        "(0, max_range_m]");
  }
  if (changed_end_min_compared < 0 || !(changed_end_min_fraction > 0.0) ||
      !(changed_end_min_fraction <= 1.0) || !(changed_end_min_cos >= 0.0) ||
      !(changed_end_min_cos <= 1.0)) {
    return Status::Error(
        "dynamic_detection.changed_end_min_compared must be >= 0 (0: off), "
        "changed_end_min_fraction in (0, 1] and changed_end_min_cos in [0, 1]");
  }
  return Status::Ok();
}

StatusOr<DynamicDetector> DynamicDetector::Create(const DynamicDetectionConfig& config) {
  const Status status = config.Validate();
  if (!status.ok()) return status;
  return DynamicDetector(config);
}

StatusOr<DynamicDetectionResult> DynamicDetector::Detect(const Submap& history,
                                                         const Submap& current,
                                                         const Pose3& T_current_history,
                                                         PointIndexPool* history_indices,
                                                         std::size_t h,
                                                         PointIndexPool* current_indices,
                                                         std::size_t k) const {
  StatusOr<PointIndexPool::Lease> history_index = history_indices->Acquire(h);
  StatusOr<PointIndexPool::Lease> current_index = current_indices->Acquire(k);
  if (!history_index.ok()) return history_index.status();
  if (!current_index.ok()) return current_index.status();
  StatusOr<DynamicDetectionResult> result =
      Detect(history, current, T_current_history, *history_index.value().index,
             *current_index.value().index);
  if (result.ok()) {
    const double share_s =
        history_index.value().build_share_s + current_index.value().build_share_s;
    result.value().time_s += share_s;
    result.value().stage.index_s += share_s;
  }
  return result;
}

namespace {

// An error unless `index` was built over the points of `submap`.
Status CheckIndexSize(const Submap& submap, const PointIndex& index) {
  if (index.size() == submap.points.size()) return Status::Ok();
  return Status::Error("dynamic_detection: the index of submap " + submap.session + "/" +
                       std::to_string(submap.id) + " holds " + std::to_string(index.size()) +
                       " points, the submap " + std::to_string(submap.points.size()));
}

// Builds an index over `points` and runs `detect` with it; the index's construction counts in
// the result's time_s and stage.index_s.
template <typename DetectWith>
StatusOr<DynamicDetectionResult> WithBuiltIndex(const PointVector& points, DetectWith detect) {
  const auto start = std::chrono::steady_clock::now();
  StatusOr<PointIndex> index = PointIndex::Create(points);
  if (!index.ok()) return index.status();
  const double index_s = SecondsSince(start);
  StatusOr<DynamicDetectionResult> result = detect(index.value());
  if (result.ok()) {
    result.value().time_s = SecondsSince(start);
    result.value().stage.index_s += index_s;
  }
  return result;
}

}  // namespace

StatusOr<DynamicDetectionResult> DynamicDetector::Detect(const Submap& history,
                                                         const Submap& current,
                                                         const Pose3& T_current_history) const {
  return WithBuiltIndex(current.points, [&](const PointIndex& current_index) {
    return Detect(history, current, T_current_history, current_index);
  });
}

StatusOr<DynamicDetectionResult> DynamicDetector::Detect(const Submap& history,
                                                         const Submap& current,
                                                         const Pose3& T_current_history,
                                                         const PointIndex& current_index) const {
  return WithBuiltIndex(history.points, [&](const PointIndex& history_index) {
    return Detect(history, current, T_current_history, history_index, current_index);
  });
}

StatusOr<DynamicDetectionResult> DynamicDetector::Detect(const Submap& history,
                                                         const Submap& current,
                                                         const Pose3& T_current_history,
                                                         const PointIndex& history_index,
                                                         const PointIndex& current_index) const {
  const auto start = std::chrono::steady_clock::now();
  DynamicDetectionResult result;
  for (const Status& status :
       {CheckIndexSize(history, history_index), CheckIndexSize(current, current_index)}) {
    if (!status.ok()) return status;
  }
  if (history.points.empty() || current.points.empty()) return result;
  if (history.scans.empty() || current.scans.empty()) {
    return Status::Error("dynamic_detection: submap " +
                         (history.scans.empty() ? history.session + "/" + std::to_string(history.id)
                                                : current.session + "/" + std::to_string(current.id)) +
                         " has no scan origins to ray-cast from");
  }
  Side sides[2];
  sides[kHistory].points.reserve(history.points.size());
  for (const Eigen::Vector3d& p : history.points) {
    sides[kHistory].points.push_back(T_current_history * p);
  }
  sides[kCurrent].points = current.points;
  sides[kHistory].origins = ThinOrigins(history, T_current_history, config_.origin_spacing_m);
  sides[kCurrent].origins = ThinOrigins(current, Pose3::Identity(), config_.origin_spacing_m);
  if (config_.rays_from_viewing_scans) {
    for (int s : {kHistory, kCurrent}) {
      const Submap& submap = s == kHistory ? history : current;
      if (submap.views.size() != submap.points.size()) continue;
      const Pose3 T = s == kHistory ? T_current_history : Pose3::Identity();
      sides[s].views = &submap.views;
      for (const SubmapScanRecord& scan : submap.scans) {
        sides[s].scan_origins.push_back(T * scan.T_submap_sensor.translation());
      }
    }
  }

  DynamicDetectionResult::StageTimes& stage = result.stage;
  auto lap = std::chrono::steady_clock::now();
  // Adds the time since the last lap to `slot`.
  auto clock = [&lap](double* slot) {
    const auto now = std::chrono::steady_clock::now();
    *slot += std::chrono::duration<double>(now - lap).count();
    lap = now;
  };
  const FrameIndex history_in_detection(history_index, T_current_history.inverse());
  const FrameIndex current_in_detection(current_index, Pose3::Identity());
  PairDetection pair(config_, sides, history_in_detection, current_in_detection);
  pair.EstimateGround();
  clock(&stage.ground_s);
  pair.FindCommonParts();
  for (int s : {kHistory, kCurrent}) {
    result.common_grown[s] = static_cast<std::size_t>(
        std::count(sides[s].common.begin(), sides[s].common.end(), std::uint8_t{2}));
  }
  clock(&stage.common_s);
  const Status cast = pair.CastRays();
  if (!cast.ok()) return cast;
  clock(&stage.rays_s);
  result.history_dynamic = pair.DetectDynamic(kHistory);
  result.current_dynamic = pair.DetectDynamic(kCurrent);
  clock(&stage.dynamic_s);
  if (config_.changed_objects_enabled) {
    for (int s : {kHistory, kCurrent}) pair.ExamineObjects(s, &result.examined_objects);
    pair.PartnersOfChanged(&result.examined_objects);
    pair.ApplyExamined(kHistory, result.examined_objects, &result.history_dynamic);
    pair.ApplyExamined(kCurrent, result.examined_objects, &result.current_dynamic);
  }
  clock(&stage.changed_s);
  if (config_.low_residue_min_ground_points > 0) {
    pair.AddLowResidue(kHistory, &result.history_dynamic);
    pair.AddLowResidue(kCurrent, &result.current_dynamic);
  }
  clock(&stage.dynamic_s);
  result.current_mending = pair.Mending(result.current_dynamic);
  clock(&stage.mending_s);
  result.time_s = SecondsSince(start);
  return result;
}

}  // namespace core
}  // namespace multisession_mapper
