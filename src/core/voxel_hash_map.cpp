#include "multisession_mapper/core/voxel_hash_map.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>

#include "multisession_mapper/core/worker_pool.h"

namespace multisession_mapper {
namespace core {
namespace {

// The 3x3x3 neighbourhood, nearest first: centre, faces, edges, corners. Searching in this
// order shrinks the best distance early, so more of the farther voxels are skipped.
struct Offset {
  int dx, dy, dz;
};
constexpr int kNeighbourhood = 27;
constexpr Offset kNeighbourOrder[kNeighbourhood] = {
    {0, 0, 0},                                                                    // centre
    {-1, 0, 0}, {1, 0, 0}, {0, -1, 0}, {0, 1, 0}, {0, 0, -1}, {0, 0, 1},          // faces
    {-1, -1, 0}, {-1, 1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 0, -1}, {-1, 0, 1},      // edges
    {1, 0, -1}, {1, 0, 1}, {0, -1, -1}, {0, -1, 1}, {0, 1, -1}, {0, 1, 1},
    {-1, -1, -1}, {-1, -1, 1}, {-1, 1, -1}, {-1, 1, 1},                           // corners
    {1, -1, -1}, {1, -1, 1}, {1, 1, -1}, {1, 1, 1}};

// kNeighbourOrder's index of the offset (dx, dy, dz) that a loop over dx, then dy, then dz
// (each -1..1) visits at position 9 (dx + 1) + 3 (dy + 1) + (dz + 1).
constexpr std::array<int, kNeighbourhood> LoopToNeighbour() {
  std::array<int, kNeighbourhood> out{};
  for (int k = 0; k < kNeighbourhood; ++k) {
    const Offset& o = kNeighbourOrder[k];
    out[9 * (o.dx + 1) + 3 * (o.dy + 1) + (o.dz + 1)] = k;
  }
  return out;
}
constexpr std::array<int, kNeighbourhood> kLoopToNeighbour = LoopToNeighbour();
// Each offset once: the table is a permutation (a repeated offset would leave an entry 0).
constexpr bool IsPermutation(const std::array<int, kNeighbourhood>& table) {
  for (int a = 0; a < kNeighbourhood; ++a) {
    for (int b = a + 1; b < kNeighbourhood; ++b) {
      if (table[a] == table[b]) return false;
    }
  }
  return true;
}
static_assert(IsPermutation(kLoopToNeighbour), "kNeighbourOrder must list 27 distinct offsets");

// One expression for the search and the recall of a match, so both give the same bits.
inline double SquaredDistance(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return (a - b).squaredNorm();
}

// Squared distance from `p` to the box [low, high] (0 inside): no point of the box is closer.
inline double SquaredDistanceToBox(const Eigen::Vector3d& low, const Eigen::Vector3d& high,
                                   const Eigen::Vector3d& p) {
  return (low - p).cwiseMax(p - high).cwiseMax(0.0).squaredNorm();
}

}  // namespace

Status VoxelHashMapConfig::Validate() const {
  if (!std::isfinite(voxel_size_m) || voxel_size_m <= 0.0) {
    return Status::Error("voxel_hash_map.voxel_size_m must be > 0, got " +
                         std::to_string(voxel_size_m));
  }
  if (max_points_per_voxel < 1) {
    return Status::Error("voxel_hash_map.max_points_per_voxel must be >= 1, got " +
                         std::to_string(max_points_per_voxel));
  }
  if (!std::isfinite(min_point_spacing_m) || min_point_spacing_m < 0.0 ||
      min_point_spacing_m >= voxel_size_m) {
    return Status::Error("voxel_hash_map.min_point_spacing_m must be in [0, voxel_size_m), got " +
                         std::to_string(min_point_spacing_m));
  }
  if (!std::isfinite(max_distance_m) || max_distance_m <= 0.0) {
    return Status::Error("voxel_hash_map.max_distance_m must be > 0, got " +
                         std::to_string(max_distance_m));
  }
  if (!std::isfinite(removal_step_m) || removal_step_m < 0.0) {
    return Status::Error("voxel_hash_map.removal_step_m must be >= 0, got " +
                         std::to_string(removal_step_m));
  }
  if (!std::isfinite(normal_radius_m) || normal_radius_m <= 0.0 ||
      normal_radius_m > 3.0 * voxel_size_m) {
    return Status::Error("voxel_hash_map.normal_radius_m must be in (0, 3 * voxel_size_m], got " +
                         std::to_string(normal_radius_m));
  }
  return plane.Validate();
}

StatusOr<VoxelHashMap> VoxelHashMap::Create(const VoxelHashMapConfig& config) {
  const Status status = config.Validate();
  if (!status.ok()) return status;
  return VoxelHashMap(config);
}

VoxelHashMap::VoxelHashMap(const VoxelHashMapConfig& config)
    : config_(config),
      inv_voxel_size_(1.0 / config.voxel_size_m),
      stride_(static_cast<std::size_t>(config.max_points_per_voxel)) {}

void VoxelHashMap::ClearNeighbourCache() {
  memory_.clear();
  if (neighbour_cache_.empty()) return;
  neighbour_cache_.Release();
  neighbour_ids_.clear();
}

void VoxelHashMap::AddToCachedNeighbourhoods(const VoxelIndex& index, std::uint32_t id) {
  if (neighbour_cache_.empty()) return;
  // The new voxel is neighbour k of the center index - offset k.
  for (int k = 0; k < kNeighbourhood; ++k) {
    const Offset& o = kNeighbourOrder[k];
    const std::uint32_t cached = neighbour_cache_.Find(index - VoxelIndex(o.dx, o.dy, o.dz));
    if (cached != VoxelIndexTable::kEmpty) {
      neighbour_ids_[cached + k] = static_cast<std::int32_t>(id);
    }
  }
}

std::uint32_t VoxelHashMap::NeighbourOffset(const VoxelIndex& center) const {
  const std::uint32_t offset = static_cast<std::uint32_t>(neighbour_ids_.size());
  const auto found = neighbour_cache_.FindOrInsert(center, offset);
  if (!found.second) return found.first;
  neighbour_ids_.resize(neighbour_ids_.size() + kNeighbourhood);
  for (int k = 0; k < kNeighbourhood; ++k) {
    const Offset& o = kNeighbourOrder[k];
    neighbour_ids_[offset + k] = Find(center + VoxelIndex(o.dx, o.dy, o.dz));
  }
  return offset;
}

std::uint32_t VoxelHashMap::QueryNeighbourOffset(std::size_t i, const VoxelIndex& center) const {
  QueryMemory& memory = memory_[i];
  if (memory.offset != VoxelIndexTable::kEmpty && memory.center == center) return memory.offset;
  memory.offset = NeighbourOffset(center);
  memory.center = center;
  memory.has_match = false;  // remembered for another neighbourhood
  return memory.offset;
}

bool VoxelHashMap::SearchOrRecall(std::size_t i, const Eigen::Vector3d& query,
                                  const VoxelIndex& center, const std::int32_t* ids,
                                  double bound_sq, bool recall, TargetMatch* match,
                                  bool* recalled) const {
  QueryMemory& memory = memory_[i];
  if (recall && memory.has_match) {
    // Every other point is at least clear - moved from the query now, the remembered one at
    // distance: it is the only nearest while distance < clear - moved. The margin is far
    // above the rounding of these sums and of the voxel-face tests (~1e-13 m at 1 km).
    const double moved = (query - memory.query).norm();
    const double distance_sq = SquaredDistance(memory.match, query);
    const double margin = 1e-9 + 1e-14 * query.cwiseAbs().maxCoeff();
    if (std::sqrt(distance_sq) + moved + margin < std::sqrt(memory.clear_sq)) {
      *recalled = true;
      if (!(distance_sq < bound_sq)) return false;  // as MatchAround: only below the bound
      match->point = memory.match;
      match->distance_sq = distance_sq;
      match->has_normal = false;
      return true;
    }
  }
  double clear_sq = 0.0;
  const bool found = MatchAround(query, center, ids, bound_sq, match, &clear_sq);
  memory.query = query;
  memory.has_match = found;
  if (found) {
    memory.match = match->point;
    memory.clear_sq = clear_sq;
  }
  return found;
}

void VoxelHashMap::Clear() {
  ++content_version_;
  ClearNeighbourCache();
  voxels_.clear();
  boxes_.clear();
  points_.clear();
  normals_cached_ = false;
  removed_once_ = false;
  table_.Release();
}

int VoxelHashMap::Find(const VoxelIndex& index) const {
  const std::uint32_t id = table_.Find(index);
  return id == VoxelIndexTable::kEmpty ? -1 : static_cast<int>(id);
}

int VoxelHashMap::FindOrInsert(const VoxelIndex& index) {
  const auto found = table_.FindOrInsert(index, static_cast<std::uint32_t>(voxels_.size()));
  if (!found.second) return static_cast<int>(found.first);
  AddToCachedNeighbourhoods(index, found.first);
  voxels_.emplace_back();
  voxels_.back().index = index;
  boxes_.emplace_back();
  points_.resize(voxels_.size() * stride_);
  return static_cast<int>(found.first);
}

void VoxelHashMap::RebuildTable() {
  table_.Release();
  table_.Reserve(voxels_.size());
  for (std::size_t id = 0; id < voxels_.size(); ++id) {
    table_.FindOrInsert(voxels_[id].index, static_cast<std::uint32_t>(id));
  }
}

VoxelHashMap::VoxelIndex VoxelHashMap::IndexOf(const Eigen::Vector3d& p) const {
  return VoxelIndex(static_cast<int>(std::floor(p.x() * inv_voxel_size_)),
                    static_cast<int>(std::floor(p.y() * inv_voxel_size_)),
                    static_cast<int>(std::floor(p.z() * inv_voxel_size_)));
}

void VoxelHashMap::Update(const PointVector& points_in_map,
                          const Eigen::Vector3d& robot_position_m) {
  AddPoints(points_in_map);
  if (!removed_once_ ||
      (robot_position_m - last_removal_position_m_).norm() >= config_.removal_step_m) {
    RemoveFarVoxels(robot_position_m);
    removed_once_ = true;
    last_removal_position_m_ = robot_position_m;
  }
}

void VoxelHashMap::AddPoints(const PointVector& points_in_map) {
  ++epoch_;
  const double spacing_sq = config_.min_point_spacing_m * config_.min_point_spacing_m;
  const std::size_t max_points = static_cast<std::size_t>(config_.max_points_per_voxel);
  std::vector<VoxelIndex> changed;
  // Successive points of a scan often share a voxel: look the index up only when it changes.
  VoxelIndex last_index(std::numeric_limits<int>::min(), 0, 0);
  int id = -1;
  for (const Eigen::Vector3d& p : points_in_map) {
    if (!p.allFinite()) continue;
    const VoxelIndex index = IndexOf(p);
    if (id < 0 || index != last_index) {
      id = FindOrInsert(index);
      last_index = index;
    }
    Voxel& voxel = voxels_[id];
    SearchBox& box = boxes_[id];
    if (box.count >= max_points) continue;
    Eigen::Vector3d* points = PointsOf(id);
    if (spacing_sq > 0.0 &&
        std::any_of(points, points + box.count,
                    [&](const Eigen::Vector3d& q) { return (q - p).squaredNorm() < spacing_sq; })) {
      continue;
    }
    if (box.count == 0) {
      box.low = box.high = p;
    } else {
      box.low = box.low.cwiseMin(p);
      box.high = box.high.cwiseMax(p);
    }
    points[box.count++] = p;
    ++content_version_;
    if (voxel.last_insert_epoch != epoch_) {
      voxel.last_insert_epoch = epoch_;
      changed.push_back(index);
    }
  }
  if (!normals_cached_) return;
  for (const VoxelIndex& index : changed) InvalidateNormalsAround(index);
}

void VoxelHashMap::InvalidateNormalsAround(const VoxelIndex& index) {
  const int reach = static_cast<int>(std::ceil(config_.normal_radius_m * inv_voxel_size_));
  for (int dx = -reach; dx <= reach; ++dx) {
    for (int dy = -reach; dy <= reach; ++dy) {
      for (int dz = -reach; dz <= reach; ++dz) {
        const int id = Find(index + VoxelIndex(dx, dy, dz));
        if (id < 0) continue;
        const Voxel& voxel = voxels_[id];
        voxel.normal_states.assign(boxes_[id].count, NormalState::kUnknown);
        voxel.normals.resize(boxes_[id].count);
      }
    }
  }
}

void VoxelHashMap::RemoveFarVoxels(const Eigen::Vector3d& position_m) {
  const double max_sq = config_.max_distance_m * config_.max_distance_m;
  // Stable compaction of voxels_ and their point blocks.
  std::size_t kept = 0;
  for (std::size_t id = 0; id < voxels_.size(); ++id) {
    const std::uint32_t count = boxes_[id].count;
    if (count == 0 || (PointsOf(id)[0] - position_m).squaredNorm() > max_sq) continue;
    if (kept != id) {
      std::copy_n(PointsOf(id), count, PointsOf(kept));
      voxels_[kept] = std::move(voxels_[id]);
      boxes_[kept] = boxes_[id];
    }
    ++kept;
  }
  if (kept == voxels_.size()) return;
  ++content_version_;
  ClearNeighbourCache();  // ids moved
  voxels_.resize(kept);
  boxes_.resize(kept);
  points_.resize(kept * stride_);
  RebuildTable();
}

bool VoxelHashMap::FindMatch(const Eigen::Vector3d& query, double max_distance_m,
                             TargetMatch* match) const {
  if (voxels_.empty() || !(max_distance_m > 0.0)) return false;
  const VoxelIndex center = IndexOf(query);
  return MatchAround(query, center, NeighbourIds(center), max_distance_m * max_distance_m, match);
}

void VoxelHashMap::FindMatches(const PointVector& queries, double max_distance_m,
                               bool warm_start, WorkerPool* pool,
                               std::vector<std::uint8_t>* found,
                               std::vector<TargetMatch>* matches) const {
  // Below this many queries a second thread costs more than it saves.
  constexpr std::size_t kMinParallelQueries = 256;
  constexpr std::size_t kBlock = 128;  // queries per work item
  const std::size_t n = queries.size();
  if (voxels_.empty() || !(max_distance_m > 0.0)) {
    found->assign(n, 0);
    matches->resize(n);
    return;
  }
  const double max_sq = max_distance_m * max_distance_m;
  const bool hints = warm_start && found->size() == n && matches->size() == n;
  // Squared bound of query i's search (the neighbour voxels are visited in a fixed order).
  auto bound_sq = [&](std::size_t i) {
    const bool previous = hints && (*found)[i] != 0;
    return WarmStartBoundSq(previous ? &(*matches)[i] : nullptr, queries[i], max_sq);
  };
  if (memory_.size() != n) memory_.assign(n, QueryMemory());  // another query set
  // Recall needs the map unchanged since the matches were remembered, and no normals (a
  // match with normals is computed by MatchAround only).
  const bool recall = memory_version_ == content_version_ && !normals_enabled_;
  memory_version_ = content_version_;
  // The neighbour cache's only writer is this loop (it may grow neighbour_ids_); the search
  // below only reads it, each task writing only its own queries' memory, found and matches.
  std::vector<VoxelIndex> centers(n);
  std::vector<std::uint32_t> offsets(n);
  std::vector<double> bounds(n);
  for (std::size_t i = 0; i < n; ++i) {
    centers[i] = IndexOf(queries[i]);
    offsets[i] = QueryNeighbourOffset(i, centers[i]);
    bounds[i] = bound_sq(i);  // reads the previous found / matches: before they are reset
  }
  found->assign(n, 0);
  matches->resize(n);
  const std::int32_t* ids = neighbour_ids_.data();
  const std::size_t blocks = (n + kBlock - 1) / kBlock;
  std::vector<std::uint32_t> block_recalls(blocks, 0);  // one writer each
  const auto search_block = [&](std::size_t block) {
    const std::size_t end = std::min(n, (block + 1) * kBlock);
    for (std::size_t i = block * kBlock; i < end; ++i) {
      bool recalled = false;
      (*found)[i] =
          SearchOrRecall(i, queries[i], centers[i], ids + offsets[i], bounds[i], recall,
                         &(*matches)[i], &recalled)
              ? 1
              : 0;
      block_recalls[block] += recalled ? 1 : 0;
    }
  };
  // Normals are computed and cached by the search itself: those searches stay on this thread.
  if (pool == nullptr || pool->threads() <= 1 || normals_enabled_ || n < kMinParallelQueries) {
    for (std::size_t block = 0; block < blocks; ++block) search_block(block);
  } else {
    pool->Run(blocks, search_block);
  }
  for (const std::uint32_t count : block_recalls) recalled_ += count;
}

bool VoxelHashMap::MatchAround(const Eigen::Vector3d& query, const VoxelIndex& center,
                               const std::int32_t* ids, double bound_sq, TargetMatch* match,
                               double* clear_sq) const {
  const double size = config_.voxel_size_m;
  // Distance from the query to the low / high face of its own voxel, per axis.
  const Eigen::Vector3d low = query - center.cast<double>() * size;
  const Eigen::Vector3d high = Eigen::Vector3d::Constant(size) - low;

  double best_sq = bound_sq;
  int best_id = -1;
  std::size_t best_index = 0;
  // Lower bound on the squared distance to every point but the best (for clear_sq): what a
  // skipped voxel or box could hold at least, and the points examined and not kept.
  double clear = std::numeric_limits<double>::infinity();
  for (int k = 0; k < kNeighbourhood; ++k) {
    const int id = ids[k];
    if (id < 0) continue;
    if (k > 0) {
      // Skip a neighbour voxel that cannot hold anything closer than the best so far.
      const Offset& o = kNeighbourOrder[k];
      const double gx = o.dx < 0 ? low.x() : (o.dx > 0 ? high.x() : 0.0);
      const double gy = o.dy < 0 ? low.y() : (o.dy > 0 ? high.y() : 0.0);
      const double gz = o.dz < 0 ? low.z() : (o.dz > 0 ? high.z() : 0.0);
      const double face_sq = gx * gx + gy * gy + gz * gz;
      if (face_sq >= best_sq) {
        clear = std::min(clear, face_sq);
        continue;
      }
    }
    // Same test against the box of the voxel's points, tighter (surfaces are thin).
    const SearchBox& box = boxes_[id];
    const double gap_sq = SquaredDistanceToBox(box.low, box.high, query);
    if (gap_sq >= best_sq) {
      clear = std::min(clear, gap_sq);
      continue;
    }
    const Eigen::Vector3d* pts = PointsOf(static_cast<std::size_t>(id));
    const std::size_t n = box.count;
    for (std::size_t i = 0; i < n; ++i) {
      const double d = SquaredDistance(pts[i], query);
      if (d < best_sq) {
        if (best_id >= 0) clear = std::min(clear, best_sq);  // the best so far is an other
        best_sq = d;
        best_id = id;
        best_index = i;
      } else {
        clear = std::min(clear, d);
      }
    }
  }
  if (clear_sq != nullptr) *clear_sq = clear;
  if (best_id < 0) return false;

  const Voxel* best_voxel = &voxels_[best_id];
  const Eigen::Vector3d& point = PointsOf(static_cast<std::size_t>(best_id))[best_index];
  match->point = point;
  match->distance_sq = best_sq;
  if (!normals_enabled_) {
    match->has_normal = false;
    return true;
  }
  const std::uint32_t best_count = boxes_[best_id].count;
  if (best_voxel->normal_states.size() != best_count) {
    best_voxel->normal_states.resize(best_count, NormalState::kUnknown);
    best_voxel->normals.resize(best_count);
  }
  NormalState& state = best_voxel->normal_states[best_index];
  if (state == NormalState::kUnknown) {
    normals_cached_ = true;
    state = ComputeNormal(point, IndexOf(point), &best_voxel->normals[best_index]);
  }
  match->has_normal = state == NormalState::kPlanar;
  if (match->has_normal) match->normal = best_voxel->normals[best_index];
  return true;
}

VoxelHashMap::NormalState VoxelHashMap::ComputeNormal(const Eigen::Vector3d& p,
                                                      const VoxelIndex& index,
                                                      Eigen::Vector3d* normal) const {
  const double radius_sq = config_.normal_radius_m * config_.normal_radius_m;
  const int reach = static_cast<int>(std::ceil(config_.normal_radius_m * inv_voxel_size_));
  // Within one voxel (the defaults) the neighbourhood's ids come from the search's cache when
  // it holds them (read only: no look-up grows it here), otherwise from the table.
  const std::uint32_t cached =
      reach == 1 ? neighbour_cache_.Find(index) : VoxelIndexTable::kEmpty;
  CovarianceAccumulator acc;
  int loop_position = 0;  // (dx, dy, dz) in loop order: kLoopToNeighbour's index
  for (int dx = -reach; dx <= reach; ++dx) {
    for (int dy = -reach; dy <= reach; ++dy) {
      for (int dz = -reach; dz <= reach; ++dz, ++loop_position) {
        const int id = cached != VoxelIndexTable::kEmpty
                           ? neighbour_ids_[cached + kLoopToNeighbour[loop_position]]
                           : Find(index + VoxelIndex(dx, dy, dz));
        if (id < 0) continue;
        // A voxel whose points' box lies beyond the radius adds nothing: skipped unread (the
        // sums, and so the normal, are bit for bit those of reading every voxel).
        const SearchBox& box = boxes_[id];
        if (SquaredDistanceToBox(box.low, box.high, p) > radius_sq) continue;
        const Eigen::Vector3d* points = PointsOf(static_cast<std::size_t>(id));
        for (std::size_t i = 0; i < box.count; ++i) {
          const Eigen::Vector3d& q = points[i];
          if ((q - p).squaredNorm() <= radius_sq) acc.Add(q - p);  // centred: better conditioned
        }
      }
    }
  }
  return acc.Normal(config_.plane, normal) ? NormalState::kPlanar : NormalState::kNotPlanar;
}

bool VoxelHashMap::PlaneNormalAt(const Eigen::Vector3d& p, Eigen::Vector3d* normal) const {
  return ComputeNormal(p, IndexOf(p), normal) == NormalState::kPlanar;
}

PointVector VoxelHashMap::Points() const {
  PointVector out;
  out.reserve(NumPoints());
  for (std::size_t id = 0; id < voxels_.size(); ++id) {
    out.insert(out.end(), PointsOf(id), PointsOf(id) + boxes_[id].count);
  }
  return out;
}

std::size_t VoxelHashMap::NumPoints() const {
  std::size_t n = 0;
  for (const SearchBox& box : boxes_) n += box.count;
  return n;
}

}  // namespace core
}  // namespace multisession_mapper
