#include "multisession_mapper/core/submap_builder.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "multisession_mapper/core/se3.h"
#include "multisession_mapper/core/worker_pool.h"

namespace multisession_mapper {
namespace core {

Status InSessionDynamicFilterConfig::Validate() const {
  Status s = range_image.Validate();
  if (!s.ok()) return s;
  if (!(residue_min_rise_m >= 0.0) || !std::isfinite(residue_min_rise_m)) {
    return Status::Error("in_session_dynamics.residue_min_rise_m must be >= 0");
  }
  if (!(margin_base_m > 0.0) || !(margin_per_m >= 0.0) || !std::isfinite(margin_base_m) ||
      !std::isfinite(margin_per_m)) {
    return Status::Error("dynamic_filter.margin_base_m must be > 0 and margin_per_m >= 0");
  }
  if (!(max_check_range_m > 0.0)) return Status::Error("dynamic_filter.max_check_range_m must be > 0");
  if (!(near_range_m > 0.0) || !std::isfinite(near_range_m)) {
    return Status::Error("dynamic_filter.near_range_m must be > 0");
  }
  if (check_every_n_scans < 1) return Status::Error("dynamic_filter.check_every_n_scans must be >= 1");
  if (min_seen_through < 1) return Status::Error("dynamic_filter.min_seen_through must be >= 1");
  if (!(min_seen_through_ratio >= 0.0 && min_seen_through_ratio < 1.0)) {
    return Status::Error("dynamic_filter.min_seen_through_ratio must be in [0, 1)");
  }
  if (grow_depth < 0) return Status::Error("dynamic_filter.grow_depth must be >= 0");
  if (grow_max_scan_gap < 0) return Status::Error("dynamic_filter.grow_max_scan_gap must be >= 0");
  if (min_consecutive_seen_through < 0) {
    return Status::Error("dynamic_filter.min_consecutive_seen_through must be >= 0");
  }
  if (!(tail_m >= 0.0)) return Status::Error("dynamic_filter.tail_m must be >= 0");
  if (past_checks < 0 || past_checks > 64) {
    return Status::Error("dynamic_filter.past_checks must be in [0, 64]");
  }
  if (past_check_stride < 1 || past_check_stride > 64) {
    return Status::Error("dynamic_filter.past_check_stride must be in [1, 64]");
  }
  if (check_threads < 1 || check_threads > 64) {
    return Status::Error("dynamic_filter.check_threads must be in [1, 64]");
  }
  return groups.Validate();
}

Status SubmapBuilderConfig::Validate() const {
  if (!(max_translation_m > 0.0) || !std::isfinite(max_translation_m)) {
    return Status::Error("submap.max_translation_m must be > 0");
  }
  if (!(max_rotation_rad > 0.0) || !std::isfinite(max_rotation_rad)) {
    return Status::Error("submap.max_rotation_rad must be > 0");
  }
  if (!(break_on_jump_m >= 0.0) || !std::isfinite(break_on_jump_m)) {
    return Status::Error("submap.break_on_jump_m must be >= 0 (0: off)");
  }
  if (!(voxel_size_m >= 0.01) || !std::isfinite(voxel_size_m)) {
    return Status::Error("submap.voxel_size_m must be >= 0.01");
  }
  if (!(max_point_range_m > 0.0)) return Status::Error("submap.max_point_range_m must be > 0");
  return dynamic_filter.Validate();
}

StatusOr<SubmapBuilder> SubmapBuilder::Create(const SubmapBuilderConfig& config,
                                              const std::string& session) {
  Status s = config.Validate();
  if (!s.ok()) return s;
  if (session.empty()) return Status::Error("submap builder needs a session name");
  return SubmapBuilder(config, session);
}

SubmapBuilder::SubmapBuilder(const SubmapBuilderConfig& config, const std::string& session)
    : session_(session) {
  set_config(config);
}

void SubmapBuilder::set_config(const SubmapBuilderConfig& config) {
  const int threads = config.dynamic_filter.check_threads;
  if (threads <= 1) {
    pool_.reset();
  } else if (pool_ == nullptr || pool_->threads() != threads) {
    pool_ = std::make_shared<WorkerPool>(threads);
  }
  config_ = config;
  TrimPastImages();
}

void SubmapBuilder::StartSubmap(const Pose3& T_odom_sensor, double started_at_jump_m) {
  if (!open_.empty()) open_.back().full = true;
  OpenSubmap open;
  open.submap.session = session_;
  open.submap.id = next_id_++;
  open.submap.T_map_submap = T_odom_sensor;
  open.submap.started_at_jump_m = started_at_jump_m;
  open.first_scan = stats_.scans;
  open.robust_height = config_.robust_height;
  open_.push_back(std::move(open));
}

void SubmapBuilder::CheckOpenSubmaps(const RangeImage& image, const Pose3& T_odom_sensor) {
  if (pool_ == nullptr) {
    for (OpenSubmap& open : open_) {
      CheckVisibility(image, T_odom_sensor, stats_.scans, &open, 0, open.voxels.size());
    }
    return;
  }
  // Blocks of voxels, one work item each (the pool hands them out one at a time).
  constexpr std::size_t kBlock = 8192;
  struct Block {
    OpenSubmap* open;
    std::size_t begin, end;
  };
  std::vector<Block> blocks;
  for (OpenSubmap& open : open_) {
    for (std::size_t begin = 0; begin < open.voxels.size(); begin += kBlock) {
      blocks.push_back({&open, begin, std::min(open.voxels.size(), begin + kBlock)});
    }
  }
  const auto check = [&](std::size_t b) {
    CheckVisibility(image, T_odom_sensor, stats_.scans, blocks[b].open, blocks[b].begin,
                    blocks[b].end);
  };
  pool_->Run(blocks.size(), check);
}

void SubmapBuilder::CheckAgainstPast(std::size_t begin, std::size_t end) {
  if (past_images_.empty()) return;
  OpenSubmap* current = &open_.back();
  // One scan creates a few thousand voxels (the check of all open voxels: hundreds of
  // thousands, in blocks of 8192): smaller blocks, so that both threads get some. Each block
  // goes through every image, oldest first (the order of the evidence).
  constexpr std::size_t kBlock = 2048;
  WorkerPool::RunBlocks(pool_.get(), begin, end, kBlock, [&](std::size_t first, std::size_t last) {
    for (const PastImage& past : past_images_) {
      CheckVisibility(*past.image, past.T_odom_sensor, past.scan, current, first, last);
    }
  });
}

void SubmapBuilder::TrimPastImages() {
  while (past_images_.size() > static_cast<std::size_t>(config_.dynamic_filter.past_checks)) {
    past_images_.pop_front();
  }
}

void SubmapBuilder::CheckVisibility(const RangeImage& image, const Pose3& T_odom_sensor,
                                    std::uint64_t image_scan, OpenSubmap* open,
                                    std::size_t begin, std::size_t end) {
  const InSessionDynamicFilterConfig& c = config_.dynamic_filter;
  const Pose3 T_sensor_submap = T_odom_sensor.inverse() * open->submap.T_map_submap;
  RangeImage::Batch batch;
  batch.R_sensor_frame = T_sensor_submap.linear().cast<float>();
  batch.t_sensor_frame = T_sensor_submap.translation().cast<float>();
  batch.max_range_m = c.max_check_range_m;
  batch.margin_base_m = c.margin_base_m;
  batch.margin_per_m = c.margin_per_m;
  const bool past = image_scan < stats_.scans;  // an image from before this scan
  constexpr std::size_t kChunk = 1024;
  Visibility seen[kChunk];
  float ranges[kChunk];
  for (std::size_t first = begin; first < end; first += kChunk) {
    const std::size_t n = std::min(kChunk, end - first);
    image.CheckMany(batch, open->centroid_x.data() + first, open->centroid_y.data() + first,
                    open->centroid_z.data() + first, n, seen, ranges);
    for (std::size_t k = 0; k < n; ++k) {
      if (seen[k] != Visibility::kSeenThrough && seen[k] != Visibility::kConsistent) continue;
      VoxelPoint& voxel = open->voxels[first + k];
      if (seen[k] == Visibility::kSeenThrough) {
        if (voxel.seen_through < std::numeric_limits<std::uint16_t>::max()) ++voxel.seen_through;
        if (!past) voxel.seen_through_later = true;
        if (ranges[k] <= c.near_range_m &&
            voxel.consecutive_seen_through < std::numeric_limits<std::uint16_t>::max()) {
          ++voxel.consecutive_seen_through;
        }
      } else {
        if (voxel.consistent < std::numeric_limits<std::uint16_t>::max()) ++voxel.consistent;
        voxel.consecutive_seen_through = 0;
        voxel.last_consistent_scan =
            std::max(voxel.last_consistent_scan, static_cast<std::uint32_t>(image_scan));
      }
    }
  }
}

void SubmapBuilder::AddScan(const LidarScan& deskewed_scan, const Pose3& T_odom_sensor,
                            double jump_m) {
  ++stats_.scans;
  const double step_m =
      has_last_pose_ ? (T_odom_sensor.translation() - last_pose_.translation()).norm() : 0.0;
  has_last_pose_ = true;
  last_pose_ = T_odom_sensor;

  // Submap splitting on motion from the current origin, or at a jump of the odometry: the
  // open submaps end before it (their tails are not checked against scans that do not fit
  // them).
  const bool jump = config_.break_on_jump_m > 0.0 && jump_m > config_.break_on_jump_m;
  // After a jump their poses do not fit the scans; with the filter off they grow old.
  if (jump || !config_.dynamic_filter.enabled) past_images_.clear();
  if (jump && !open_.empty()) {
    ++stats_.jump_breaks;
    for (OpenSubmap& open : open_) {
      Finalize(&open);
    }
    open_.clear();
    StartSubmap(T_odom_sensor, jump_m);
  } else if (open_.empty() || open_.back().full) {
    StartSubmap(T_odom_sensor);
  } else {
    const Pose3 motion = se3::Between(open_.back().submap.T_map_submap, T_odom_sensor);
    if (se3::TranslationNorm(motion) > config_.max_translation_m ||
        se3::RotationAngleRad(motion) > config_.max_rotation_rad) {
      StartSubmap(T_odom_sensor);
    }
  }
  OpenSubmap& current = open_.back();
  current.submap.length_m += step_m;

  // Visibility checks of everything accumulated so far, before this scan's points go in.
  const InSessionDynamicFilterConfig& filter = config_.dynamic_filter;
  std::shared_ptr<const RangeImage> image;
  if (filter.enabled &&
      stats_.scans % static_cast<std::uint64_t>(filter.check_every_n_scans) == 0) {
    image = std::make_shared<const RangeImage>(deskewed_scan, filter.range_image);
    CheckOpenSubmaps(*image, T_odom_sensor);
  }
  const std::size_t voxels_before = current.voxels.size();

  // Accumulate.
  SubmapScanRecord record;
  record.stamp_s = deskewed_scan.stamp_s;
  record.T_submap_sensor = se3::Between(current.submap.T_map_submap, T_odom_sensor);
  current.submap.scans.push_back(record);
  const double max_range_sq = config_.max_point_range_m * config_.max_point_range_m;
  // First every point's submap position, voxel key and hash; then the look-ups in the same
  // order, a few points ahead of the sums, with memory prefetched ahead of both: the voxel
  // table and voxels of a large submap are tens of MB, and each look-up otherwise waited for
  // memory (on the whole `campus` s00 bag the look-ups and sums took 6.6-7.5 s per 4000 scans
  // in one loop, 3.4-3.6 s now). Successive points of a ring often share a voxel: the key is
  // looked up only when it changes. Same voxels, same order, same sums as one loop.
  pending_.clear();
  for (const LidarPoint& p : deskewed_scan.points) {
    const Eigen::Vector3d p_sensor = p.position_m.cast<double>();
    if (!p_sensor.allFinite() || p_sensor.squaredNorm() > max_range_sq) continue;
    PendingPoint q;
    q.p_submap = record.T_submap_sensor * p_sensor;
    q.key = ToVoxelKey(q.p_submap, config_.voxel_size_m);
    q.hash = VoxelIndexTable::Hash(q.key);
    q.range_sq = static_cast<float>(p_sensor.squaredNorm());
    pending_.push_back(q);
  }
  // Two stages in step: the look-up of point i + kVoxelLag (it prefetches the table slot of
  // the point kSlotLag further on, and the voxel it finds), and the sum of point i.
  constexpr std::size_t kSlotLag = 8;
  constexpr std::size_t kVoxelLag = 4;
  VoxelKey last_key(std::numeric_limits<int>::min(), 0, 0);
  std::uint32_t last_index = 0;
  std::size_t looked_up = 0;
  const std::size_t n = pending_.size();
  const auto scan_index = static_cast<std::uint32_t>(current.submap.scans.size() - 1);
  for (std::size_t i = 0; i < n; ++i) {
    for (; looked_up < n && looked_up <= i + kVoxelLag; ++looked_up) {
      if (looked_up + kSlotLag < n) {
        current.voxel_index.Prefetch(pending_[looked_up + kSlotLag].hash);
      }
      PendingPoint& q = pending_[looked_up];
      if (q.key != last_key) {
        const auto found = current.voxel_index.FindOrInsert(
            q.key, q.hash, static_cast<std::uint32_t>(current.voxels.size()));
        if (found.second) {
          current.voxels.emplace_back();
          current.centroid_x.push_back(0.0f);
          current.centroid_y.push_back(0.0f);
          current.centroid_z.push_back(0.0f);
          if (current.robust_height) {
            current.heights.emplace_back(q.key.z() * config_.voxel_size_m);
          }
        }
        last_key = q.key;
        last_index = found.first;
        __builtin_prefetch(&current.voxels[last_index]);
        if (current.robust_height) __builtin_prefetch(&current.heights[last_index]);
      }
      q.voxel = last_index;
    }
    VoxelPoint& voxel = current.voxels[pending_[i].voxel];
    voxel.sum += pending_[i].p_submap;
    ++voxel.count;
    voxel.views.last_scan = scan_index;
    if (current.robust_height) {
      current.heights[pending_[i].voxel].Add(pending_[i].p_submap.z(), config_.voxel_size_m);
    }
    if (pending_[i].range_sq < voxel.nearest_range_sq) {
      voxel.nearest_range_sq = pending_[i].range_sq;
      voxel.views.nearest_scan = scan_index;
    }
  }
  // The float centroids of the voxels this scan touched (runs of points share a voxel).
  std::uint32_t updated = VoxelIndexTable::kEmpty;
  for (const PendingPoint& q : pending_) {
    if (q.voxel == updated) continue;
    updated = q.voxel;
    const VoxelPoint& voxel = current.voxels[q.voxel];
    const Eigen::Vector3d centroid = voxel.centroid();
    current.centroid_x[q.voxel] = static_cast<float>(centroid.x());
    current.centroid_y[q.voxel] = static_cast<float>(centroid.y());
    current.centroid_z[q.voxel] = static_cast<float>(centroid.z());
  }

  // The voxels this scan created, against the earlier images; then this scan's image joins
  // them.
  if (filter.enabled && filter.past_checks > 0) {
    CheckAgainstPast(voxels_before, current.voxels.size());
    if (image != nullptr &&
        checks_++ % static_cast<std::uint64_t>(filter.past_check_stride) == 0) {
      past_images_.push_back({image, T_odom_sensor, stats_.scans});
      TrimPastImages();
    }
  }

  // Submaps whose tail is driven are final.
  for (OpenSubmap& open : open_) {
    if (open.full) open.tail_driven_m += step_m;
  }
  while (!open_.empty() && open_.front().full &&
         (!config_.dynamic_filter.enabled ||
          open_.front().tail_driven_m >= config_.dynamic_filter.tail_m)) {
    Finalize(&open_.front());
    open_.pop_front();
  }
}

bool SubmapBuilder::OnlyGroundBelowMeasuredSince(const OpenSubmap& open,
                                                 const std::vector<std::uint8_t>& dynamic,
                                                 std::uint32_t v, const VoxelKey& key,
                                                 std::uint64_t since_scan) const {
  const auto last_hit = [&open](const VoxelPoint& x) {
    return open.first_scan + static_cast<std::uint64_t>(x.views.last_scan);
  };
  if (last_hit(open.voxels[v]) > since_scan) return false;
  const std::uint32_t below = KeptGroundBelow(open, dynamic, key);
  return below != VoxelIndexTable::kEmpty && last_hit(open.voxels[below]) > since_scan;
}

std::uint32_t SubmapBuilder::KeptGroundBelow(const OpenSubmap& open,
                                             const std::vector<std::uint8_t>& dynamic,
                                             const VoxelKey& key) const {
  const std::uint32_t below = open.voxel_index.Find(VoxelKey(key.x(), key.y(), key.z() - 1));
  if (below == VoxelIndexTable::kEmpty || dynamic[below]) return VoxelIndexTable::kEmpty;
  // The voxel below is the surface (nothing under it): `key` is the layer right above the
  // ground, not a voxel of a wall or pole whose face the rings sweep over as the robot moves.
  const bool under = open.voxel_index.Find(VoxelKey(key.x(), key.y(), key.z() - 2)) !=
                     VoxelIndexTable::kEmpty;
  return under ? VoxelIndexTable::kEmpty : below;
}

void SubmapBuilder::Finalize(OpenSubmap* open) {
  const InSessionDynamicFilterConfig& c = config_.dynamic_filter;
  Submap& submap = open->submap;
  submap.points.clear();
  submap.points.reserve(open->voxels.size());
  submap.views.clear();
  submap.views.reserve(open->voxels.size());
  std::vector<std::uint8_t> dynamic(open->voxels.size(), 0);
  // Growing starts only from voxels measured within near_range_m, and enters only such
  // voxels (see InSessionDynamicFilterConfig::near_range_m).
  const float near_sq = static_cast<float>(c.near_range_m * c.near_range_m);
  // Each frontier voxel carries the scan after which its neighbours must not have been
  // measured: its own last consistent check + grow_max_scan_gap, or, for a voxel entered by
  // the ground rule (consistent up to the end, it was never free), the limit it inherited.
  struct Source {
    std::uint32_t voxel;
    std::uint64_t latest;
  };
  const auto own_limit = [&](std::uint32_t i) {
    return static_cast<std::uint64_t>(open->voxels[i].last_consistent_scan) + c.grow_max_scan_gap;
  };
  std::vector<Source> frontier;
  for (std::size_t i = 0; i < open->voxels.size() && c.enabled; ++i) {
    const VoxelPoint& voxel = open->voxels[i];
    const bool mostly_free =
        voxel.seen_through >= c.min_seen_through &&
        voxel.seen_through > c.min_seen_through_ratio * (voxel.seen_through + voxel.consistent);
    const bool left = c.min_consecutive_seen_through > 0 &&
                      voxel.consecutive_seen_through >= c.min_consecutive_seen_through;
    if (mostly_free || left) {
      dynamic[i] = 1;
      const auto index = static_cast<std::uint32_t>(i);
      if (voxel.nearest_range_sq <= near_sq && voxel.seen_through_later) {
        frontier.push_back({index, own_limit(index)});
      }
    }
  }
  // Growing (see InSessionDynamicFilterConfig::grow_depth).
  std::vector<Source> next;
  for (int depth = 0; depth < c.grow_depth && !frontier.empty(); ++depth) {
    next.clear();
    for (const Source& u : frontier) {
      const VoxelPoint& from = open->voxels[u.voxel];
      const VoxelKey key = ToVoxelKey(from.centroid(), config_.voxel_size_m);
      for (int dx = -1; dx <= 1; ++dx) {
        for (int dy = -1; dy <= 1; ++dy) {
          for (int dz = -1; dz <= 1; ++dz) {
            const VoxelKey neighbour(key.x() + dx, key.y() + dy, key.z() + dz);
            const std::uint32_t v = open->voxel_index.Find(neighbour);
            if (v == VoxelIndexTable::kEmpty || dynamic[v]) continue;
            if (open->voxels[v].nearest_range_sq > near_sq) continue;
            if (open->voxels[v].last_consistent_scan <= u.latest) {
              next.push_back({v, own_limit(v)});
            } else if (c.grow_over_measured_ground &&
                       OnlyGroundBelowMeasuredSince(*open, dynamic, v, neighbour, u.latest)) {
              next.push_back({v, u.latest});
            } else {
              continue;
            }
            dynamic[v] = 1;
            ++stats_.voxels_dropped_grown;
          }
        }
      }
    }
    frontier.swap(next);
  }
  if (c.enabled) DropSeenThroughGroups(*open, &dynamic);
  if (c.enabled && c.drop_residue_under_removed) DropResidueUnderRemoved(*open, &dynamic);
  for (std::size_t i = 0; i < open->voxels.size(); ++i) {
    if (dynamic[i]) {
      ++stats_.voxels_dropped_dynamic;
      continue;
    }
    submap.points.push_back(StoredPoint(*open, i));
    submap.views.push_back(open->voxels[i].views);
    ++stats_.voxels_kept;
  }
  SortSubmapPointsInVoxelBlocks(config_.voxel_size_m, &submap);
  open->voxels = {};
  open->heights = {};
  open->centroid_x = {};
  open->centroid_y = {};
  open->centroid_z = {};
  open->voxel_index.Release();
  ++stats_.submaps_finished;
  finished_.push_back(std::move(submap));
}

void SubmapBuilder::DropSeenThroughGroups(const OpenSubmap& open,
                                          std::vector<std::uint8_t>* dynamic) {
  if (config_.dynamic_filter.groups.min_seen_through_ratio <= 0.0) return;
  std::vector<GroupVoxel> kept;
  std::vector<std::uint32_t> index;  // kept -> voxel
  kept.reserve(open.voxels.size());
  index.reserve(open.voxels.size());
  for (std::size_t i = 0; i < open.voxels.size(); ++i) {
    if ((*dynamic)[i]) continue;
    const VoxelPoint& voxel = open.voxels[i];
    const Eigen::Vector3d p_submap = voxel.centroid();
    GroupVoxel v;
    v.key = ToVoxelKey(p_submap, config_.voxel_size_m);
    v.point_up = open.submap.T_map_submap * p_submap;  // the odometry frame: z up
    v.seen_through = voxel.seen_through;
    v.consistent = voxel.consistent;
    v.nearest_range_m = std::sqrt(voxel.nearest_range_sq);
    kept.push_back(v);
    index.push_back(static_cast<std::uint32_t>(i));
  }
  for (const std::uint32_t k : SeenThroughGroups(config_.dynamic_filter.groups, kept)) {
    (*dynamic)[index[k]] = 1;
    ++stats_.voxels_dropped_groups;
  }
}

Eigen::Vector3d SubmapBuilder::StoredPoint(const OpenSubmap& open, std::size_t i) const {
  const VoxelPoint& voxel = open.voxels[i];
  Eigen::Vector3d point = voxel.centroid();
  if (open.robust_height) point.z() = open.heights[i].RobustHeight(point.z());
  return point;
}

void SubmapBuilder::DropResidueUnderRemoved(const OpenSubmap& open,
                                            std::vector<std::uint8_t>* dynamic) {
  std::vector<std::uint32_t> residue;
  const double min_rise_m = config_.dynamic_filter.residue_min_rise_m;
  for (std::size_t i = 0; i < open.voxels.size(); ++i) {
    if ((*dynamic)[i]) continue;
    const VoxelPoint& voxel = open.voxels[i];
    const VoxelKey key = ToVoxelKey(voxel.centroid(), config_.voxel_size_m);
    const std::uint32_t below = KeptGroundBelow(open, *dynamic, key);
    if (below == VoxelIndexTable::kEmpty) continue;
    // Ground whose returns straddle the layers' boundary fills both voxels at about one height.
    if (StoredPoint(open, i).z() - StoredPoint(open, below).z() < min_rise_m) continue;
    bool removed_above = false;
    bool kept_above = false;
    for (int dx = -1; dx <= 1 && !kept_above; ++dx) {
      for (int dy = -1; dy <= 1 && !kept_above; ++dy) {
        const std::uint32_t v =
            open.voxel_index.Find(VoxelKey(key.x() + dx, key.y() + dy, key.z() + 1));
        if (v == VoxelIndexTable::kEmpty) continue;
        if ((*dynamic)[v]) {
          removed_above = true;
        } else {
          kept_above = true;
        }
      }
    }
    if (removed_above && !kept_above) residue.push_back(static_cast<std::uint32_t>(i));
  }
  for (const std::uint32_t v : residue) (*dynamic)[v] = 1;
  stats_.voxels_dropped_residue += residue.size();
}

void SubmapBuilder::FinishSession() {
  past_images_.clear();
  while (!open_.empty()) {
    Finalize(&open_.front());
    open_.pop_front();
  }
}

std::vector<Submap, Eigen::aligned_allocator<Submap>> SubmapBuilder::TakeFinished() {
  std::vector<Submap, Eigen::aligned_allocator<Submap>> out;
  out.swap(finished_);
  return out;
}

}  // namespace core
}  // namespace multisession_mapper
