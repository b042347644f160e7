// Builds the submaps of one session from de-skewed scans and their odometry poses (reference
// paper, section IV): a new submap starts when the motion from the current submap's origin
// exceeds 20 m or 0.7 rad. Points are accumulated in voxels (centroid per voxel) in the submap
// frame.
//
// In-session dynamic filtering (the paper accumulates submaps "following the map updating
// method of Pomerleau et al. 2014"): every voxel keeps counts of how often later scans
// measured it (consistent) and how often they measured clearly behind it (seen through: free
// space where the point was). A finished submap stays open to these checks for `tail_m` more
// metres of driving, so objects that were still in view at its end are judged too; then voxels
// seen through at least `min_seen_through` times and more often than measured, or seen
// through in each of their last `min_consecutive_seen_through` checks, are dropped. Checks
// beyond `near_range_m` (40 m) count toward the first rule only. A voxel is also checked
// against earlier scans when it is created (`past_checks`): free space where it is before it
// arrived is evidence too.
#pragma once

#include <cstdint>
#include <deque>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "multisession_mapper/core/range_image.h"
#include "multisession_mapper/core/seen_through_groups.h"
#include "multisession_mapper/core/status.h"
#include "multisession_mapper/core/submap.h"
#include "multisession_mapper/core/types.h"
#include "multisession_mapper/core/voxel_height_histogram.h"
#include "multisession_mapper/core/voxel_index_table.h"
#include "multisession_mapper/core/voxel_key.h"

namespace multisession_mapper {
namespace core {

class WorkerPool;

struct InSessionDynamicFilterConfig {
  bool enabled = true;
  RangeImageConfig range_image;
  /// A measured range within margin_base_m + margin_per_m * range of the point's range is
  /// "consistent"; beyond it "seen through" [m, m/m]. Covers range noise and pose error.
  double margin_base_m = 0.3;
  double margin_per_m = 0.02;
  /// Points farther than this from the sensor are not checked [m]. 60 m (the submaps' point
  /// range): moving cars seen only from 40 m or more, where no ring of a VLP-16 1.8 m up
  /// measures flat ground, are otherwise never checked at all (campus seed 1 s00 with 40 m:
  /// 11,589 of the 29,546 kept moving-object points were never checked).
  double max_check_range_m = 60.0;
  /// Within this range the checks are "near"; beyond it, up to max_check_range_m, "far".
  /// Far checks (one ring on a car, grazing ground, a pose tilt of 0.2 deg is 0.2 m at
  /// 60 m) drop a voxel only by the majority rule (min_seen_through_ratio), not by the
  /// consecutive rule, and voxels never measured within this range neither grow nor are
  /// grown into. With far checks counted like near ones, seed 1 lost 0.21 points of static
  /// SA (terrain and canopy 40-60 m from the route, dropped by their last three far
  /// checks and grown from there) [m].
  double near_range_m = 40.0;
  /// Check the open submaps with every n-th scan (costs ~N voxels per check).
  int check_every_n_scans = 2;
  /// Drop a voxel seen through at least this many times ...
  int min_seen_through = 2;
  /// ... and with seen_through / (seen_through + consistent) above this ratio.
  double min_seen_through_ratio = 0.5;
  /// Also drop a voxel whose last this-many checks with evidence all saw through it: it was
  /// there (consistent earlier), then it left. Recent evidence wins, as in Pomerleau et al.
  /// 0 disables.
  int min_consecutive_seen_through = 3;
  /// A finished submap stays open to checks for this much more driving [m].
  double tail_m = 10.0;
  /// Growing of the dropped voxels, for the lowest parts of moving objects (wheels, bumpers,
  /// legs): a beam that passes there now hits the ground just behind at a grazing angle, which
  /// proves nothing, so they get no "seen through" evidence. A kept voxel next to a dropped
  /// one (26-neighbourhood) is dropped too when it was last measured (consistent) no later
  /// than `grow_max_scan_gap` scans after that dropped voxel: it was only seen while the
  /// object was there. The ground under a car that drove on is measured again after it left,
  /// and a hedge next to a pedestrian is measured after the pedestrian walked on, so they
  /// stay. Up to `grow_depth` voxels deep (0 disables) [voxels, scans].
  int grow_depth = 2;
  int grow_max_scan_gap = 4;
  /// The lowest layer of an object that stood on measured ground (feet, wheels): a beam
  /// through a voxel 0.1 m above the ground lands on the ground just behind it, within the
  /// margin, so later checks keep it consistent and the rule above refuses it. With this on,
  /// the growing also enters a neighbour that received no point later than
  /// `grow_max_scan_gap` scans after the dropped voxel was last consistent, while the voxel
  /// right below it (the ground) did and nothing lies below that one: the place was measured
  /// again after the object left, and nothing was there. The last condition keeps the rule
  /// off walls and poles, whose faces the rings sweep over as the robot moves (a synthetic
  /// pedestrian that never left lost 5 of its 29 remaining points without it). A voxel
  /// entered this way was consistent to the end, so it grows on with the limit of the voxel
  /// it was grown from, not its own. Campus s00 alone, true origins, seeds 1 / 3 / 2: moving
  /// objects removed 94.46 -> 94.73 / 94.57 -> 94.97 / 95.42 -> 95.63 %, static SA 99.57 /
  /// 99.69 / 99.71 % unchanged.
  bool grow_over_measured_ground = true;
  /// The layer right above the ground under a dropped object (feet, the bottom of a wheel):
  /// after the rules above and the groups, a kept voxel is dropped too when the voxel right
  /// below it is kept and has nothing below it (the ground), its stored point lies at least
  /// `residue_min_rise_m` above that voxel's (not ground whose returns straddle the boundary
  /// of the two layers), some of the 9 voxels right above it were dropped and none of them is
  /// kept: what stood there was removed, and nothing that stays rests on it. Such a voxel is
  /// kept consistent by the ground just behind it and stands 0.05-0.2 m above the ground
  /// where a pedestrian stood. "Up" is the submap frame's z (the sensor's at the submap's
  /// start); ground steeper than about 17 deg stacks two voxels more than 0.06 m apart in
  /// one column, and the upper one would go under a removed object.
  bool drop_residue_under_removed = true;
  double residue_min_rise_m = 0.06;
  /// Checks against the past: a voxel that a scan creates is also checked against the range
  /// images of this many earlier checks (the last ones, thinned by past_check_stride),
  /// oldest first, as if they had come before it. A beam of an earlier scan that passed where
  /// the point now is saw free space there before the point arrived: something moved in.
  /// Later scans cannot see that for an object that follows the robot or drives away from
  /// it, since it stands in front of its own trail. The evidence counts like that of the
  /// later checks; an object that arrives while the robot passes and stays is kept only if
  /// later checks measure it more often than the earlier images saw through it. A voxel
  /// dropped by it alone (no later check saw through it) is not grown from: the growing's
  /// time limit is when an object left, and an arrival says nothing about that (a car that
  /// follows the robot would otherwise take the ground in front of it, which nothing
  /// measures again). 0: off.
  int past_checks = 16;
  /// The past images are those of every this-many-th check: with 16 and a stride of 4 (and
  /// checks every 2nd scan) they reach 128 scans back at the cost of 16 images. A voxel that
  /// was measured at all since an image was taken is consistent with it (within the margin),
  /// so it is the older images that see an object that moves slowly. Measured on `campus`
  /// (seed 1, s00 alone, true origins; removed / static SA): off 95.12 / 99.70 %, 16 x 1
  /// 96.10 / 99.74 %, 16 x 4 96.42 / 99.72 %, 32 x 2 96.75 / 99.73 % (but 9.6-9.9x real
  /// time against 10.3-11.0x with 16 x 4 and 11.2-11.3x off).
  int past_check_stride = 4;
  /// After the per-voxel rules and the growing, the kept voxels above the ground are judged
  /// per connected group too (see seen_through_groups.h): a group whose checks saw through it
  /// often enough is dropped. For objects seen only from afar, whose few checks per voxel
  /// rarely outvote the consistent ones one voxel at a time.
  SeenThroughGroupsConfig groups;
  /// Threads of each visibility check, the calling one included (same result with 1: each
  /// voxel's evidence is its own). The check is most of the submap building's CPU; with 2 it
  /// runs partly on the core the odometry leaves idle while it waits for scans. In [1, 64].
  int check_threads = 2;

  Status Validate() const;
};

struct SubmapBuilderConfig {
  /// Start a new submap beyond this translation from the current origin [m] (paper: 20 m).
  double max_translation_m = 20.0;
  /// ... or beyond this rotation from the current origin [rad] (paper: 0.7 rad).
  double max_rotation_rad = 0.7;
  /// Submap voxel edge [m]; one point per voxel is stored (the centroid; its height see
  /// robust_height).
  double voxel_size_m = 0.2;
  /// The stored point's height is the mean of the voxel's returns around their median height
  /// (VoxelHeightHistogram: the median's eighth of the voxel and one on each side) instead of
  /// the mean of all: a minority of returns of an object standing on a ground voxel (feet,
  /// a car's underside) does not lift the ground point. x and y stay the centroid's.
  bool robust_height = true;
  /// Scan points farther than this from the sensor are not accumulated [m].
  double max_point_range_m = 60.0;
  /// A scan whose odometry pose lies farther than this from the motion model's prediction
  /// [m] starts a new submap and ends the open ones, so that no submap holds a jump of the
  /// odometry: its points after the jump would be displaced from its origin, and every loop
  /// to it would carry the jump. The jump stays in the odometry link between the two
  /// submaps, where loops can correct it: SessionMapper widens that link's translation sigma
  /// by the jump (Submap::started_at_jump_m). Measured on the `campus` sessions of seeds 1 and 2
  /// against a constant-velocity extrapolation: 0.72-0.89 m at three scans of seed 2 (sharp
  /// turns, where the ICP slid sideways and snapped back), at most 0.58 m anywhere else.
  /// 0: off.
  double break_on_jump_m = 0.6;
  InSessionDynamicFilterConfig dynamic_filter;

  Status Validate() const;
};

struct SubmapBuilderStats {
  std::uint64_t scans = 0;
  std::uint64_t submaps_finished = 0;
  std::uint64_t voxels_dropped_dynamic = 0;  ///< includes the grown ones and the other rules'
  std::uint64_t voxels_dropped_grown = 0;
  std::uint64_t voxels_dropped_groups = 0;  ///< by InSessionDynamicFilterConfig::groups
  /// by InSessionDynamicFilterConfig::drop_residue_under_removed
  std::uint64_t voxels_dropped_residue = 0;
  std::uint64_t voxels_kept = 0;
  std::uint64_t jump_breaks = 0;  ///< submaps ended at a jump of the odometry
};

class SubmapBuilder {
 public:
  static StatusOr<SubmapBuilder> Create(const SubmapBuilderConfig& config,
                                        const std::string& session);

  /// Adds a de-skewed scan (sensor frame at its stamp) taken at `T_odom_sensor`.
  /// Submap origins are in the odometry frame until the pose graph moves them.
  /// `jump_m`: how far the pose lies from the odometry's prediction [m] (see
  /// break_on_jump_m; 0 when unknown).
  void AddScan(const LidarScan& deskewed_scan, const Pose3& T_odom_sensor, double jump_m = 0.0);

  /// Closes every open submap (end of the session).
  void FinishSession();

  /// Submaps finished since the last call, in id order; moved out.
  std::vector<Submap, Eigen::aligned_allocator<Submap>> TakeFinished();

  /// Id of the submap the last scan went into.
  std::uint32_t current_submap_id() const { return next_id_ == 0 ? 0 : next_id_ - 1; }
  const SubmapBuilderStats& stats() const { return stats_; }
  /// New settings (e.g. from dynamic_reconfigure); the check's threads follow check_threads.
  void set_config(const SubmapBuilderConfig& config);
  const SubmapBuilderConfig& config() const { return config_; }

 private:
  struct VoxelPoint {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    std::uint32_t count = 0;
    Eigen::Vector3d centroid() const { return sum / count; }  ///< count >= 1
    std::uint16_t seen_through = 0;
    std::uint16_t consistent = 0;
    std::uint16_t consecutive_seen_through = 0;  ///< since the last consistent check
    bool seen_through_later = false;  ///< by a later scan's check (not only the past's)
    std::uint32_t last_consistent_scan = 0;  ///< scan counter of the last consistent check
    float nearest_range_sq = std::numeric_limits<float>::max();  ///< of its measurements [m^2]
    PointViews views;  ///< scans (indices into the submap's scans) that measured it
  };
  /// A scan point on its way into the current submap (AddScan's look-up buffer).
  struct PendingPoint {
    Eigen::Vector3d p_submap;
    VoxelKey key;
    std::size_t hash = 0;
    std::uint32_t voxel = 0;  ///< index in the current submap's voxels, once looked up
    float range_sq = 0.0f;    ///< from the sensor [m^2]
  };
  /// A range image kept for the checks against the past, with its scan's pose and counter.
  struct PastImage {
    std::shared_ptr<const RangeImage> image;
    Pose3 T_odom_sensor;
    std::uint64_t scan = 0;
    EIGEN_MAKE_ALIGNED_OPERATOR_NEW
  };
  struct OpenSubmap {
    Submap submap;
    /// Voxels in a flat array and their index by voxel key (the visibility checks sweep the
    /// centroid arrays below and touch a voxel only when a check counts for it).
    std::vector<VoxelPoint> voxels;
    /// Each voxel's centroid (sum / count) in float, one array per axis, kept up to date by
    /// AddScan: the checks read these contiguous arrays (RangeImage::CheckMany) instead of
    /// dividing each voxel's double sums at every check.
    std::vector<float> centroid_x, centroid_y, centroid_z;
    /// The heights of each voxel's returns (SubmapBuilderConfig::robust_height; empty when
    /// off), beside `voxels` rather than in them: the checks need none.
    std::vector<VoxelHeightHistogram> heights;
    /// SubmapBuilderConfig::robust_height when the submap started (a change applies from the
    /// next submap on).
    bool robust_height = false;
    VoxelIndexTable voxel_index;
    bool full = false;           ///< a newer submap has started; only checks remain
    std::uint64_t first_scan = 0;  ///< scan counter of its first scan (views' scan 0)
    double tail_driven_m = 0.0;  ///< driving since it became full
    EIGEN_MAKE_ALIGNED_OPERATOR_NEW
  };

  SubmapBuilder(const SubmapBuilderConfig& config, const std::string& session);
  void StartSubmap(const Pose3& T_odom_sensor, double started_at_jump_m = 0.0);
  /// The visibility check of every open submap's voxels against one scan, on pool_.
  void CheckOpenSubmaps(const RangeImage& image, const Pose3& T_odom_sensor);
  /// The check of voxels [begin, end) of `open` (touches only those voxels).
  /// `image_scan`: the scan counter of the image's scan (last_consistent_scan).
  void CheckVisibility(const RangeImage& image, const Pose3& T_odom_sensor,
                       std::uint64_t image_scan, OpenSubmap* open, std::size_t begin,
                       std::size_t end);
  /// The current submap's voxels [begin, end), created by this scan, against the earlier
  /// range images (InSessionDynamicFilterConfig::past_checks and past_check_stride), on pool_.
  void CheckAgainstPast(std::size_t begin, std::size_t end);
  /// Drops the oldest past images beyond past_checks.
  void TrimPastImages();
  void Finalize(OpenSubmap* open);
  /// Marks in `dynamic` the kept voxels of the groups InSessionDynamicFilterConfig::groups
  /// drops (after the per-voxel rules and the growing).
  void DropSeenThroughGroups(const OpenSubmap& open, std::vector<std::uint8_t>* dynamic);
  /// Marks in `dynamic` the kept voxels InSessionDynamicFilterConfig::drop_residue_under_removed
  /// drops (last, after the groups).
  void DropResidueUnderRemoved(const OpenSubmap& open, std::vector<std::uint8_t>* dynamic);
  /// The point voxel `i` of `open` stores: the centroid, with the robust height when the
  /// submap has one (SubmapBuilderConfig::robust_height).
  Eigen::Vector3d StoredPoint(const OpenSubmap& open, std::size_t i) const;
  /// The voxel right below `key` when it is kept (not `dynamic`) and nothing lies below it:
  /// `key` is the layer right above the ground. VoxelIndexTable::kEmpty otherwise.
  std::uint32_t KeptGroundBelow(const OpenSubmap& open, const std::vector<std::uint8_t>& dynamic,
                                const VoxelKey& key) const;
  /// Voxel `v` (at `key`) received no point after scan `since_scan`, the voxel right below it
  /// did and is KeptGroundBelow (InSessionDynamicFilterConfig::grow_over_measured_ground).
  bool OnlyGroundBelowMeasuredSince(const OpenSubmap& open,
                                    const std::vector<std::uint8_t>& dynamic, std::uint32_t v,
                                    const VoxelKey& key, std::uint64_t since_scan) const;

  SubmapBuilderConfig config_;
  std::string session_;
  std::deque<OpenSubmap> open_;  ///< oldest first; the last one receives points
  std::vector<Submap, Eigen::aligned_allocator<Submap>> finished_;
  std::vector<PendingPoint> pending_;  ///< AddScan's buffer, kept to reuse its memory
  /// The last past_checks range images (every past_check_stride-th), oldest first; emptied
  /// at a jump of the odometry, at the end of the session and while the filter is off.
  std::deque<PastImage, Eigen::aligned_allocator<PastImage>> past_images_;
  std::uint64_t checks_ = 0;  ///< checks made while past checks were on (past_check_stride)
  std::uint32_t next_id_ = 0;
  bool has_last_pose_ = false;
  Pose3 last_pose_ = Pose3::Identity();
  SubmapBuilderStats stats_;
  /// The visibility check's threads (null with check_threads 1); copies share it.
  std::shared_ptr<WorkerPool> pool_;
};

}  // namespace core
}  // namespace multisession_mapper
