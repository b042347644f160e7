#include "multisession_mapper/core/odometry.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "multisession_mapper/core/voxel_downsample.h"

namespace multisession_mapper {
namespace core {
namespace {

class Stopwatch {
 public:
  Stopwatch() : start_(std::chrono::steady_clock::now()) {}
  /// Milliseconds since construction or the previous Lap().
  double Lap() {
    const auto now = std::chrono::steady_clock::now();
    const double ms = std::chrono::duration<double, std::milli>(now - start_).count();
    start_ = now;
    return ms;
  }

 private:
  std::chrono::steady_clock::time_point start_;
};

}  // namespace

Status OdometryConfig::Validate() const {
  Status status = input_filter.Validate();
  if (!status.ok()) return status;
  if (!(status = deskew.Validate()).ok()) return status;
  if (!(status = local_map.Validate()).ok()) return status;
  if (!(status = icp.Validate()).ok()) return status;
  if (!(status = threshold.Validate()).ok()) return status;
  if (!(status = scan_normals.Validate()).ok()) return status;
  if (!std::isfinite(map_voxel_size_m) || map_voxel_size_m <= 0.0) {
    return Status::Error("odometry.map_voxel_size_m must be > 0, got " +
                         std::to_string(map_voxel_size_m));
  }
  if (std::isnan(high_point_min_height_m) ||
      !(high_point_max_normal_z >= 0.0 && high_point_max_normal_z <= 1.0)) {
    return Status::Error(
        "odometry.high_point_min_height_m must be a number (inf: off) and "
        "odometry.high_point_max_normal_z in [0, 1]");
  }
  if (std::isnan(map_ground_min_depth_m) ||
      map_ground_min_depth_m == -std::numeric_limits<double>::infinity() ||
      !(map_ground_min_normal_z >= 0.0 && map_ground_min_normal_z <= 1.0)) {
    return Status::Error(
        "odometry.map_ground_min_depth_m must be a number (inf: off) and "
        "odometry.map_ground_min_normal_z in [0, 1]");
  }
  if (!std::isfinite(registration_voxel_size_m) ||
      registration_voxel_size_m < map_voxel_size_m) {
    return Status::Error("odometry.registration_voxel_size_m must be >= map_voxel_size_m, got " +
                         std::to_string(registration_voxel_size_m));
  }
  if (!std::isfinite(correspondence_sigma_factor) || correspondence_sigma_factor <= 0.0 ||
      !std::isfinite(kernel_sigma_factor) || kernel_sigma_factor <= 0.0) {
    return Status::Error("odometry.correspondence_sigma_factor / kernel_sigma_factor must be > 0");
  }
  if (!std::isfinite(refine_min_translation_m) || refine_min_translation_m < 0.0 ||
      !std::isfinite(refine_min_rotation_rad) || refine_min_rotation_rad < 0.0) {
    return Status::Error(
        "odometry.refine_min_translation_m / refine_min_rotation_rad must be >= 0");
  }
  if (!std::isfinite(motion_prior_release_ratio) || motion_prior_release_ratio < 0.0 ||
      motion_prior_release_ratio > 1.0) {
    return Status::Error("odometry.motion_prior_release_ratio must be in [0, 1], got " +
                         std::to_string(motion_prior_release_ratio));
  }
  if (!std::isfinite(motion_prior_weight) || motion_prior_weight < 0.0) {
    return Status::Error("odometry.motion_prior_weight must be >= 0, got " +
                         std::to_string(motion_prior_weight));
  }
  if (!std::isfinite(turn_hypothesis_step_rad_s) || turn_hypothesis_step_rad_s < 0.0 ||
      !std::isfinite(turn_hypothesis_margin) || turn_hypothesis_margin < 1.0) {
    return Status::Error(
        "odometry.turn_hypothesis_step_rad_s must be >= 0 and turn_hypothesis_margin >= 1");
  }
  if (!std::isfinite(turn_hypothesis_trigger) || turn_hypothesis_trigger < 0.0 ||
      turn_hypothesis_window_scans < 1 || turn_hypothesis_levels < 1) {
    return Status::Error(
        "odometry.turn_hypothesis_trigger must be >= 0, turn_hypothesis_window_scans and "
        "turn_hypothesis_levels >= 1");
  }
  if (!std::isfinite(judge_convergence_translation_m) || judge_convergence_translation_m < 0.0 ||
      !std::isfinite(judge_convergence_rotation_rad) || judge_convergence_rotation_rad < 0.0 ||
      judge_max_iterations < 1) {
    return Status::Error(
        "odometry.judge_convergence_translation_m / judge_convergence_rotation_rad must be >= 0 "
        "and judge_max_iterations >= 1");
  }
  if (velocity_window_scans < 1 || rotation_window_scans < 1) {
    return Status::Error("odometry.velocity_window_scans and rotation_window_scans must be >= 1, "
                         "got " + std::to_string(velocity_window_scans) + " and " +
                         std::to_string(rotation_window_scans));
  }
  if (!std::isfinite(max_scan_gap_s) || max_scan_gap_s <= 0.0) {
    return Status::Error("odometry.max_scan_gap_s must be > 0, got " +
                         std::to_string(max_scan_gap_s));
  }
  return Status::Ok();
}

StatusOr<Odometry> Odometry::Create(const OdometryConfig& config, const Pose3& initial_pose) {
  const Status status = config.Validate();
  if (!status.ok()) return status;
  if (!se3::IsValid(initial_pose, 1e-4)) return Status::Error("odometry: invalid initial pose");
  // Every Create below validates a sub-config that Validate() already checked.
  IcpRegistration icp = IcpRegistration::Create(config.icp).value();
  // The judge is never coarser than the registration itself.
  IcpRegistration judge_icp =
      icp.WithConvergence(
             std::min(config.icp.convergence_translation_m, config.judge_convergence_translation_m),
             std::min(config.icp.convergence_rotation_rad, config.judge_convergence_rotation_rad),
             std::max(config.icp.max_iterations, config.judge_max_iterations))
          .value();
  return Odometry(config, se3::Normalized(initial_pose),
                  InputFilter::Create(config.input_filter).value(),
                  Deskewer::Create(config.deskew).value(),
                  VoxelHashMap::Create(config.local_map).value(), std::move(icp),
                  std::move(judge_icp), AdaptiveThreshold::Create(config.threshold).value());
}

Odometry::Odometry(const OdometryConfig& config, const Pose3& initial_pose, InputFilter filter,
                   Deskewer deskewer, VoxelHashMap map, IcpRegistration icp,
                   IcpRegistration judge_icp, AdaptiveThreshold threshold)
    : config_(config),
      filter_(std::move(filter)),
      deskewer_(std::move(deskewer)),
      local_map_(std::move(map)),
      icp_(std::move(icp)),
      judge_icp_(std::move(judge_icp)),
      threshold_(std::move(threshold)),
      pose_(initial_pose) {}

StatusOr<OdometryResult> Odometry::ProcessScan(const LidarScan& scan) {
  if (!std::isfinite(scan.stamp_s)) return Status::Error("odometry: non-finite scan stamp");
  if (has_scan_ && scan.stamp_s <= last_stamp_s_) {
    return Status::Error("odometry: scan stamp " + std::to_string(scan.stamp_s) +
                         " s does not increase (previous " + std::to_string(last_stamp_s_) +
                         " s)");
  }
  Stopwatch total;
  Stopwatch watch;
  OdometryResult result;
  result.stamp_s = scan.stamp_s;

  LidarScan filtered = filter_.Apply(scan, &result.filter_stats);
  result.timing.filter_ms = watch.Lap();
  if (filtered.points.empty()) {
    return Status::Error("odometry: no point of the scan at " + std::to_string(scan.stamp_s) +
                         " s survived the input filter");
  }

  // Constant-velocity model; a long gap makes the last velocity meaningless.
  const double dt = has_scan_ ? scan.stamp_s - last_stamp_s_ : 0.0;
  const bool continuous = has_scan_ && dt <= config_.max_scan_gap_s;
  // Constant-velocity model, for the stamp interval and for this sweep alike.
  const se3::Vector6d velocity = continuous ? velocity_ : se3::Vector6d::Zero();
  result.prediction = se3::Normalized(pose_ * se3::Exp(velocity * dt));

  PointVector source;
  PointVector source_normals;  // empty: ICP with the local map's normals only
  // The last search of the last registration of `source` against the local map (which does
  // not change within a scan): the next registration of the same points starts from it, with
  // the same results (IcpSearchMemory). prepare() makes new points and forgets it.
  IcpSearchMemory memory;
  // De-skews with `v` and downsamples: map points, then the coarser registration points
  // (with their normals from the scan's rings).
  const auto prepare = [&](const se3::Vector6d& v) {
    Stopwatch prepare_watch;
    result.deskewed_scan = deskewer_.Apply(filtered, v, &result.deskew_stats);
    result.timing.deskew_ms += prepare_watch.Lap();
    const LidarScan map_scan = VoxelDownsample(result.deskewed_scan, config_.map_voxel_size_m);
    result.map_points = ScanToPointVector(map_scan);
    const LidarScan source_scan = VoxelDownsample(map_scan, config_.registration_voxel_size_m);
    source = ScanToPointVector(source_scan);
    source_normals.clear();
    memory = IcpSearchMemory();
    if (config_.use_scan_normals && result.deskewed_scan.has_ring) {
      source_normals =
          EstimateScanNormals(result.deskewed_scan, source_scan.points, config_.scan_normals);
      DropHighPointsOffWalls(config_.high_point_min_height_m, config_.high_point_max_normal_z,
                             &source, &source_normals);
    }
    result.timing.downsample_ms += prepare_watch.Lap();
  };
  // The motion model's position as a prior where the pairs constrain little (see the config).
  IcpTranslationPrior prior;
  prior.translation = result.prediction.translation();
  prior.weight = continuous ? config_.motion_prior_weight : 0.0;
  // Registers at the configured convergence, or at the judge's steps; `normals` replaces
  // source_normals (the final refinement below, with the far ground's map normals).
  const auto register_scan = [&](const Pose3& guess, double max_distance_m, double kernel_m,
                                 bool at_judge_steps, const PointVector* normals = nullptr) {
    const IcpRegistration& runner = at_judge_steps ? judge_icp_ : icp_;
    StatusOr<IcpResult> icp = Status::Error("icp: not run");
    if (source_normals.empty()) {
      icp = runner.Register(source, local_map_, guess, max_distance_m, kernel_m, prior);
    } else {
      local_map_.SetNormalsEnabled(false);  // unused by this ICP; they cost most of a match
      icp = runner.Register(source, normals != nullptr ? *normals : source_normals, local_map_,
                            guess, max_distance_m, kernel_m, prior, &memory);
      local_map_.SetNormalsEnabled(true);
    }
    ++result.registrations;
    if (icp.ok()) {
      result.icp_iterations += icp.value().iterations;
      result.icp_searches += icp.value().searches;
    }
    return icp;
  };
  prepare(velocity);
  watch.Lap();

  // The recent fits' median, for the prior's release and the turn hypotheses' trigger alike
  // (the window changes only at the end of the scan).
  const std::optional<double> median_weight = RecentWeightMedian();
  const double sigma = threshold_.Sigma();
  result.sigma_m = sigma;
  const double max_distance_m = config_.correspondence_sigma_factor * sigma;
  const double kernel_m = config_.kernel_sigma_factor * sigma;
  Pose3 estimate = result.prediction;
  bool add_to_map = true;
  // Whether the scan's registration ran at the judge's settings (see
  // judge_convergence_translation_m): once one fit is compared with another, every later run
  // of the scan is judged too.
  bool judged = false;
  // Runs the registration `fit` on from where it stopped to the judge's settings, once per
  // scan.
  const auto run_on_to_judge_steps = [&](IcpResult* fit) {
    if (judged) return;
    judged = true;
    StatusOr<IcpResult> continued = register_scan(fit->pose, max_distance_m, kernel_m, true);
    if (continued.ok()) *fit = continued.value();
  };
  if (has_scan_ && !local_map_.empty()) {
    StatusOr<IcpResult> icp = register_scan(result.prediction, max_distance_m, kernel_m, false);
    // A poor fit with the prior: perhaps the motion model broke (a yaw-rate step), which the
    // prior must not hold; try without it (see the config).
    if (prior.weight > 0.0 && config_.motion_prior_release_ratio > 0.0 && median_weight &&
        (!icp.ok() ||
         icp.value().mean_weight < config_.motion_prior_release_ratio * *median_weight)) {
      if (icp.ok()) run_on_to_judge_steps(&icp.value());
      judged = true;  // the run without the prior below is judged either way
      const double prior_weight = prior.weight;
      prior.weight = 0.0;
      StatusOr<IcpResult> free_icp =
          register_scan(result.prediction, max_distance_m, kernel_m, true);
      if (free_icp.ok() && (!icp.ok() || free_icp.value().mean_weight > icp.value().mean_weight)) {
        icp = std::move(free_icp);
        result.motion_prior_released = true;
      } else {
        prior.weight = prior_weight;
      }
    }
    if (icp.ok()) {
      result.icp = icp.value();
      result.registered = true;
      estimate = icp.value().pose;
    } else {
      result.message = icp.status().message();
      add_to_map = false;
    }
  }
  result.timing.registration_ms += watch.Lap();

  se3::Vector6d estimated_velocity = velocity;
  // The scan's registration run on to the judge's settings (once), and its velocity.
  const auto judge_registration = [&]() {
    if (judged) return;
    run_on_to_judge_steps(&result.icp);
    estimate = result.icp.pose;
    estimated_velocity = WindowVelocity(estimate, scan.stamp_s);
  };
  if (result.registered && continuous && dt > 0.0) {
    estimated_velocity = WindowVelocity(estimate, scan.stamp_s);
    // The prediction's velocity was wrong over this sweep (start, sharp turn): de-skew again
    // with the estimated one and refine, so that the map only receives well de-skewed points.
    const double sweep_s = result.deskew_stats.max_time_offset_s;
    const Pose3 mismatch = se3::Exp((estimated_velocity - velocity) * sweep_s);
    if (config_.refine_deskew && result.deskew_stats.applied &&
        (se3::TranslationNorm(mismatch) > config_.refine_min_translation_m ||
         se3::RotationAngleRad(mismatch) > config_.refine_min_rotation_rad)) {
      // The new de-skew takes its rotation rate from this scan's own estimate, which a
      // coarse stop lags in a turn's first scan.
      watch.Lap();
      judge_registration();
      result.timing.registration_ms += watch.Lap();
      prepare(estimated_velocity);
      watch.Lap();
      StatusOr<IcpResult> refined = register_scan(estimate, max_distance_m, kernel_m, judged);
      if (refined.ok()) {
        result.icp = refined.value();
        estimate = refined.value().pose;
        estimated_velocity = WindowVelocity(estimate, scan.stamp_s);
      }
      result.refined = true;
      result.timing.registration_ms += watch.Lap();
    }
  }

  if (result.registered && continuous && dt > 0.0 && config_.turn_hypothesis_step_rad_s > 0.0 &&
      (TurnHypothesesTriggered(result.icp.mean_weight, velocity(5), median_weight) ||
       (config_.turn_hypothesis_on_release && result.motion_prior_released))) {
    // Yaw-rate hypotheses, each de-skewed with its own rate: a turn that starts or ends within
    // one scan leaves the prediction (and its de-skew) a whole step off.
    result.turn_hypotheses_tried = true;
    judge_registration();  // the registration they are compared with
    const double step = config_.turn_hypothesis_step_rad_s;
    const double predicted_rate = velocity(5);
    std::vector<double> rates;
    for (int level = 1; level <= config_.turn_hypothesis_levels; ++level) {
      const double offset = step * level / config_.turn_hypothesis_levels;
      rates.push_back(predicted_rate - offset);
      rates.push_back(predicted_rate + offset);
    }
    // In a turn also its end, unless the rates above hold it already.
    if (InTurn(predicted_rate) &&
        std::none_of(rates.begin(), rates.end(), [](double r) { return std::abs(r) < 1e-9; })) {
      rates.push_back(0.0);
    }
    struct Best {
      double score;
      Pose3 pose;
      IcpResult icp;
      LidarScan deskewed;
      PointVector map_points;
      se3::Vector6d velocity;
      PointVector source, source_normals;
      IcpSearchMemory memory;
      bool changed = false;
    };
    // The registration's scan and points move into `best`; prepare() refills result's.
    Best best{result.icp.mean_weight * config_.turn_hypothesis_margin, estimate, result.icp,
              std::move(result.deskewed_scan), std::move(result.map_points), estimated_velocity,
              std::move(source), std::move(source_normals), std::move(memory)};
    for (double rate : rates) {
      se3::Vector6d v = velocity;
      v(5) = rate;
      const Pose3 guess = se3::Normalized(pose_ * se3::Exp(v * dt));
      prepare(v);
      StatusOr<IcpResult> h = register_scan(guess, max_distance_m, kernel_m, true);
      if (!h.ok() || !(h.value().mean_weight > best.score)) continue;
      best = Best{h.value().mean_weight, h.value().pose, h.value(),
                  std::move(result.deskewed_scan), std::move(result.map_points),
                  WindowVelocity(h.value().pose, scan.stamp_s), std::move(source),
                  std::move(source_normals), std::move(memory), true};
    }
    // Leave the chosen hypothesis' scan and points behind (prepare overwrote them).
    result.deskewed_scan = std::move(best.deskewed);
    result.map_points = std::move(best.map_points);
    source = std::move(best.source);
    source_normals = std::move(best.source_normals);
    memory = std::move(best.memory);
    if (best.changed) {
      result.turn_hypothesis_won = true;
      estimate = best.pose;
      result.icp = best.icp;
      estimated_velocity = best.velocity;
    }
    result.timing.registration_ms += watch.Lap();
  }

  if (result.registered && !source_normals.empty() &&
      std::isfinite(config_.map_ground_min_depth_m)) {
    // The chosen fit refined with the far ground's map normals (see the config). Only here:
    // ground pairs say nothing about yaw but fit well under a wrong one, and in the fits
    // compared above (prior release, turn hypotheses) they blurred the kernel weights that
    // tell a lost turn (seed 1 s02's turn at 239 s went 3.3 deg wrong). The scan keeps that
    // fit's mean weight for the recent median.
    // Skipped when no point qualifies (also the dynamic_reconfigure "off": a depth no point
    // reaches).
    watch.Lap();
    std::size_t added = 0;
    const PointVector ground_normals =
        WithMapGroundNormals(source, source_normals, estimate, &added);
    StatusOr<IcpResult> refined = Status::Error("no map ground normal");
    if (added > 0) {
      refined = register_scan(estimate, max_distance_m, kernel_m, judged, &ground_normals);
    }
    if (refined.ok()) {
      // Ground planes measure height, roll and pitch: only those are taken from the
      // refinement; heading and horizontal position stay the chosen fit's (a refinement
      // moving them changed the velocity estimates before that turn and lost it again).
      estimate = se3::WithTiltAndHeightOf(estimate, refined.value().pose);
      if (continuous && dt > 0.0) estimated_velocity = WindowVelocity(estimate, scan.stamp_s);
    }
    result.timing.map_ground_ms = watch.Lap();
  }

  if (result.registered) {
    threshold_.Update(se3::Between(result.prediction, estimate), se3::Between(pose_, estimate));
    velocity_ = continuous ? estimated_velocity : se3::Vector6d::Zero();
  } else if (has_scan_) {
    velocity_ = velocity;  // keep predicting with the model through an ICP failure
  }
  result.pose = estimate;
  watch.Lap();
  if (add_to_map) {
    if (first_scan_.has_value() && result.registered) {
      // The first scan went into the map un-de-skewed (no velocity yet): replace it by its
      // de-skewed version now that the velocity is known.
      local_map_.Clear();
      InsertIntoMap(VoxelDownsample(
                        ScanToPointVector(deskewer_.Apply(*first_scan_, velocity_)),
                        config_.map_voxel_size_m),
                    trajectory_.front().pose);
      first_scan_.reset();
    }
    InsertIntoMap(result.map_points, estimate);
    if (!has_scan_ && filtered.has_time && config_.deskew.enabled) first_scan_ = filtered;
  }
  result.timing.map_update_ms = watch.Lap();

  pose_ = estimate;
  last_stamp_s_ = scan.stamp_s;
  has_scan_ = true;
  StampedPose stamped;
  stamped.stamp_s = scan.stamp_s;
  stamped.pose = estimate;
  trajectory_.push_back(stamped);
  if (!continuous) {  // the windows never span a gap
    recent_.clear();
    recent_weights_.clear();
  }
  recent_.push_back(stamped);
  while (recent_.size() > static_cast<std::size_t>(std::max(config_.velocity_window_scans,
                                                               config_.rotation_window_scans))) {
    recent_.pop_front();
  }
  if (result.registered) recent_weights_.push_back(result.icp.mean_weight);
  while (recent_weights_.size() > static_cast<std::size_t>(config_.turn_hypothesis_window_scans)) {
    recent_weights_.pop_front();
  }
  result.timing.total_ms = total.Lap();
  return result;
}

bool Odometry::InTurn(double yaw_rate) const {
  return std::abs(yaw_rate) > 0.5 * config_.turn_hypothesis_step_rad_s;
}

bool Odometry::TurnHypothesesTriggered(double mean_weight, double predicted_yaw_rate,
                                       const std::optional<double>& median_weight) const {
  if (!median_weight) return false;  // the window is not full yet
  if (config_.turn_hypothesis_trigger <= 0.0) return true;
  if (config_.turn_hypothesis_in_turns && InTurn(predicted_yaw_rate)) return true;
  return mean_weight < config_.turn_hypothesis_trigger * *median_weight;
}

std::optional<double> Odometry::RecentWeightMedian() const {
  // turn_hypothesis_window_scans >= 1 (Validate): a full window is never empty.
  if (recent_weights_.size() < static_cast<std::size_t>(config_.turn_hypothesis_window_scans)) {
    return std::nullopt;
  }
  std::vector<double> weights(recent_weights_.begin(), recent_weights_.end());
  const auto middle = weights.begin() + static_cast<std::ptrdiff_t>(weights.size() / 2);
  std::nth_element(weights.begin(), middle, weights.end());
  return *middle;
}

// Why a window: with the velocity of the last interval only, an along-track pose error e_k
// of scan k gives the next scan a velocity error (e_k - e_{k-1}) / dt, and de-skewing with it
// shears that scan so that ICP moves it by about half of that the other way:
// e_{k+1} ~ -(e_k - e_{k-1}) / 2, whose characteristic roots are 0.5 and -1, an oscillation
// that never decays. Over n intervals it is e_{k+1} ~ -(e_k - e_{k-n}) / (2n), stable for
// n >= 2. A constant twist has the same body-frame coordinates along the whole motion, so the
// mean over the window needs no change of frame. The rotation rate has a window of its own
// (rotation_window_scans, see the config).
se3::Vector6d Odometry::WindowVelocity(const Pose3& estimate, double stamp_s) const {
  if (recent_.empty()) return se3::Vector6d::Zero();
  // The pose `intervals` scans before this one (or the oldest kept).
  const auto back = [&](int intervals) -> const StampedPose& {
    const std::size_t n = std::min(recent_.size(), static_cast<std::size_t>(intervals));
    return recent_[recent_.size() - n];
  };
  const StampedPose& translation_from = back(config_.velocity_window_scans);
  se3::Vector6d velocity = Deskewer::VelocityFromMotion(
      se3::Between(translation_from.pose, estimate), stamp_s - translation_from.stamp_s);
  // The same window for both (the defaults): that motion's rotation rate already.
  if (config_.rotation_window_scans == config_.velocity_window_scans) return velocity;
  const StampedPose& rotation_from = back(config_.rotation_window_scans);
  velocity.tail<3>() = Deskewer::VelocityFromMotion(se3::Between(rotation_from.pose, estimate),
                                                    stamp_s - rotation_from.stamp_s)
                           .tail<3>();
  return velocity;
}

PointVector Odometry::WithMapGroundNormals(const PointVector& source,
                                           const PointVector& normals, const Pose3& guess,
                                           std::size_t* added) const {
  PointVector out = normals;
  *added = 0;
  if (local_map_.empty()) return out;  // (the caller skips an infinite depth: off)
  const Eigen::Matrix3d R_sensor_map = guess.linear().transpose();
  Eigen::Vector3d n;
  for (std::size_t i = 0; i < source.size() && i < out.size(); ++i) {
    if (!out[i].isZero(0.0) || source[i].z() > -config_.map_ground_min_depth_m) continue;
    if (!local_map_.PlaneNormalAt(guess * source[i], &n)) continue;
    if (std::abs(n.z()) < config_.map_ground_min_normal_z) continue;
    out[i] = R_sensor_map * (n.z() < 0.0 ? -n : n);
    ++*added;
  }
  return out;
}

void Odometry::InsertIntoMap(const PointVector& points_in_sensor, const Pose3& pose) {
  PointVector in_map;
  in_map.reserve(points_in_sensor.size());
  for (const Eigen::Vector3d& p : points_in_sensor) in_map.push_back(pose * p);
  local_map_.Update(in_map, pose.translation());
}

}  // namespace core
}  // namespace multisession_mapper
