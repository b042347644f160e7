#include "multisession_mapper/core/intra_session_pairs.h"

#include <pthread.h>
#include <sched.h>

#include <algorithm>
#include <chrono>
#include <string>
#include <system_error>
#include <utility>

#include "multisession_mapper/core/parallel_for.h"
#include "multisession_mapper/core/point_index_pool.h"
#include "multisession_mapper/core/stopwatch.h"

namespace multisession_mapper {
namespace core {

Status IntraSessionPairsConfig::Validate() const {
  if (neighbours < 1 || neighbours > 8) {
    return Status::Error("intra-session pairs: neighbours must be in [1, 8], got " +
                         std::to_string(neighbours));
  }
  if (!(max_dynamic_fraction > 0.0 && max_dynamic_fraction <= 1.0)) {
    return Status::Error("intra-session pairs: max_dynamic_fraction must be in (0, 1], got " +
                         std::to_string(max_dynamic_fraction));
  }
  if (num_threads < 1 || num_threads > 64) {
    return Status::Error("intra-session pairs: num_threads must be in [1, 64], got " +
                         std::to_string(num_threads));
  }
  return DetectionConfig().Validate();
}

DynamicDetectionConfig IntraSessionPairsConfig::DetectionConfig() const {
  DynamicDetectionConfig c = detection;
  c.rays_from_viewing_scans = rays_from_viewing_scans;
  c.min_pass_incidence_rad = min_pass_incidence_rad;
  c.min_cluster_coarse_fraction = min_cluster_coarse_fraction;
  c.own_ground_max_gap_m = own_ground_max_gap_m;
  c.changed_objects_enabled = changed_objects_enabled;
  c.far_range_m = far_range_m;
  return c;
}

namespace {

// Best effort: idle, a worker that only takes the CPU time the pipeline's threads leave;
// normal, one that is waited for (raising it back may be refused without privileges; it then
// still runs on the cores its waiter leaves idle).
void SetPriority(std::thread::native_handle_type thread, bool idle) {
#if defined(__linux__) && defined(SCHED_IDLE)
  sched_param param{};
  param.sched_priority = 0;
  pthread_setschedparam(thread, idle ? SCHED_IDLE : SCHED_OTHER, &param);
#else
  (void)thread;
  (void)idle;
#endif
}

}  // namespace

StatusOr<std::unique_ptr<IntraSessionPairDetector>> IntraSessionPairDetector::Create(
    const IntraSessionPairsConfig& config) {
  Status valid = config.Validate();
  if (!valid.ok()) return valid;
  StatusOr<DynamicDetector> detector = DynamicDetector::Create(config.DetectionConfig());
  if (!detector.ok()) return detector.status();
  std::unique_ptr<IntraSessionPairDetector> pairs(
      new IntraSessionPairDetector(config, std::move(detector.value())));
  if (config.during_session) {
    try {
      pairs->worker_ = std::thread([p = pairs.get()] { p->RunWorker(); });
    } catch (const std::system_error&) {
      pairs->config_.during_session = false;  // no thread to be had: every pair at Finish
    }
  }
  return pairs;
}

IntraSessionPairDetector::IntraSessionPairDetector(const IntraSessionPairsConfig& config,
                                                   DynamicDetector detector)
    : config_(config), detector_(std::move(detector)) {}

IntraSessionPairDetector::~IntraSessionPairDetector() { StopWorker(); }

void IntraSessionPairDetector::StopWorker() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  if (!worker_.joinable()) return;
  SetPriority(worker_.native_handle(), false);  // its current pair is now waited for
  worker_.join();
}

void IntraSessionPairDetector::CatchUp() {
  if (!worker_.joinable()) return;
  SetPriority(worker_.native_handle(), false);
  {
    std::unique_lock<std::mutex> lock(mutex_);
    caught_up_.wait(lock, [&] { return stop_ || worker_idle_; });
  }
  SetPriority(worker_.native_handle(), true);
}

void IntraSessionPairDetector::Add(const Submap& submap, const Pose3& T_odometry_submap) {
  const std::size_t k = odometry_poses_.size();
  odometry_poses_.push_back(T_odometry_submap);
  point_counts_.push_back(submap.points.size());
  usable_.push_back(!submap.points.empty() && !submap.scans.empty());
  // Not across a jump of the odometry (Submap::started_at_jump_m): the two sides of a jump
  // are placed only by a weak link unless a loop corrected it, and a misplaced pair passes for
  // change.
  if (k > 0 && submap.started_at_jump_m > 0.0) last_jump_ = k;
  std::vector<Pair, Eigen::aligned_allocator<Pair>> added;
  std::vector<std::shared_ptr<const Submap>> dropped;  // freed after the lock
  const std::size_t first = k > static_cast<std::size_t>(config_.neighbours)
                                ? k - static_cast<std::size_t>(config_.neighbours)
                                : 0;
  for (std::size_t i = first; i < k; ++i) {
    if (!usable_[i]) continue;
    if (last_jump_ > i) {
      ++stats_.pairs_across_jumps;
      continue;
    }
    if (!usable_[k]) continue;
    Pair p;
    p.earlier = i;
    p.later = k;
    p.T_later_earlier = T_odometry_submap.inverse() * odometry_poses_[i];
    added.push_back(p);
  }
  // A copy also for the pairs to come, in which it is the earlier submap; none while
  // kMaxCopies wait for the worker (a starved worker leaves its pairs to Finish).
  std::shared_ptr<const Submap> copy;
  if (config_.during_session && usable_[k] && copies_alive() < kMaxCopies) {
    copy = std::make_shared<const Submap>(submap);
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    pending_uses_.push_back(0);
    copies_.push_back(std::move(copy));
    for (const Pair& p : added) {
      ++pending_uses_[p.earlier];
      ++pending_uses_[p.later];
    }
    pairs_.insert(pairs_.end(), added.begin(), added.end());
    results_.resize(pairs_.size());
    if (!added.empty()) worker_idle_ = false;
    ReleaseCopies(&dropped);
  }
  if (!added.empty()) wake_.notify_all();
}

std::size_t IntraSessionPairDetector::copies_alive() {
  std::lock_guard<std::mutex> lock(mutex_);
  std::size_t alive = 0;
  for (std::size_t id = release_from_; id < copies_.size(); ++id) alive += copies_[id] != nullptr;
  return alive;
}

void IntraSessionPairDetector::ReleaseCopies(std::vector<std::shared_ptr<const Submap>>* dropped) {
  // A submap can still be the earlier one of a future pair while it is among the last
  // `neighbours` added.
  const std::size_t added = copies_.size();
  const std::size_t n = static_cast<std::size_t>(config_.neighbours);
  for (std::size_t id = release_from_; id + n < added; ++id) {
    if (copies_[id] && pending_uses_[id] == 0) dropped->push_back(std::move(copies_[id]));
  }
  while (release_from_ + n < added && !copies_[release_from_] &&
         pending_uses_[release_from_] == 0) {
    ++release_from_;
  }
}

void IntraSessionPairDetector::RunWorker() {
  SetPriority(pthread_self(), true);
  std::unique_lock<std::mutex> lock(mutex_);
  while (true) {
    if (next_ == pairs_.size()) {
      worker_idle_ = true;
      caught_up_.notify_all();
    }
    wake_.wait(lock, [&] { return stop_ || next_ < pairs_.size(); });
    if (stop_) {
      caught_up_.notify_all();
      return;
    }
    const std::size_t index = next_++;
    const Pair pair = pairs_[index];
    std::shared_ptr<const Submap> earlier = copies_[pair.earlier];
    std::shared_ptr<const Submap> later = copies_[pair.later];
    std::vector<std::shared_ptr<const Submap>> dropped;  // freed after the lock
    if (earlier && later) {  // else not copied (kMaxCopies): left for Finish
      lock.unlock();
      StatusOr<DynamicDetectionResult> result = DetectOnCopies(pair, *earlier, *later);
      earlier.reset();
      later.reset();
      lock.lock();
      results_[index] = std::move(result);
      ++stats_.pairs_during_session;
    }
    --pending_uses_[pair.earlier];
    --pending_uses_[pair.later];
    ReleaseCopies(&dropped);
    lock.unlock();
    dropped.clear();
    lock.lock();
  }
}

StatusOr<DynamicDetectionResult> IntraSessionPairDetector::DetectOnCopies(
    const Pair& p, const Submap& earlier, const Submap& later) {
  // Pairs come in the order of their later submap, so an index older than the earliest
  // submap the coming pairs can hold is not needed again.
  const std::size_t n = static_cast<std::size_t>(config_.neighbours);
  indices_.erase(indices_.begin(), indices_.lower_bound(p.later > n ? p.later - n : 0));
  double build_s = 0.0;
  auto index_of = [&](std::size_t id, const Submap& submap) -> StatusOr<const PointIndex*> {
    auto it = indices_.find(id);
    if (it == indices_.end()) {
      const auto start = std::chrono::steady_clock::now();
      StatusOr<PointIndex> built = PointIndex::Create(submap.points);
      if (!built.ok()) return built.status();
      it = indices_.emplace(id, std::make_shared<const PointIndex>(std::move(built.value())))
               .first;
      build_s += SecondsSince(start);
    }
    return it->second.get();
  };
  StatusOr<const PointIndex*> earlier_index = index_of(p.earlier, earlier);
  if (!earlier_index.ok()) return earlier_index.status();
  StatusOr<const PointIndex*> later_index = index_of(p.later, later);
  if (!later_index.ok()) return later_index.status();
  StatusOr<DynamicDetectionResult> result =
      detector_.Detect(earlier, later, p.T_later_earlier, *earlier_index.value(),
                       *later_index.value());
  if (result.ok()) {  // charged as the pools charge a built index: to the pair that built it
    result.value().time_s += build_s;
    result.value().stage.index_s += build_s;
  }
  return result;
}

std::size_t IntraSessionPairDetector::pairs_known() {
  std::lock_guard<std::mutex> lock(mutex_);
  return pairs_.size();
}

std::size_t IntraSessionPairDetector::pairs_detected_during_session() {
  std::lock_guard<std::mutex> lock(mutex_);
  return stats_.pairs_during_session;
}

StatusOr<IntraSessionPairsStats> IntraSessionPairDetector::Finish(
    std::vector<Submap, Eigen::aligned_allocator<Submap>>* submaps) {
  StopWorker();
  if (finished_) return Status::Error("intra-session pairs: Finish called twice");
  finished_ = true;
  std::vector<Submap, Eigen::aligned_allocator<Submap>>& maps = *submaps;
  if (maps.size() != point_counts_.size()) {
    return Status::Error("intra-session pairs: " + std::to_string(maps.size()) +
                         " submaps given, " + std::to_string(point_counts_.size()) + " added");
  }
  for (std::size_t k = 0; k < maps.size(); ++k) {
    if (maps[k].points.size() != point_counts_[k]) {
      return Status::Error("intra-session pairs: submap " + std::to_string(k) +
                           " changed after it was added");
    }
  }
  copies_.clear();
  indices_.clear();
  // The pairs the worker did not reach: each submap's neighbour index built once (in its own
  // frame) and shared by its pairs.
  std::vector<std::size_t> left;
  std::vector<int> uses(maps.size(), 0);
  for (std::size_t i = 0; i < pairs_.size(); ++i) {
    if (results_[i].has_value()) continue;
    left.push_back(i);
    ++uses[pairs_[i].earlier];
    ++uses[pairs_[i].later];
  }
  PointIndexPool indices(std::move(uses),
                         [&](std::size_t k) -> const PointVector& { return maps[k].points; });
  ParallelFor(left.size(), config_.num_threads, [&](std::size_t i) {
    const Pair& p = pairs_[left[i]];
    results_[left[i]] = detector_.Detect(maps[p.earlier], maps[p.later], p.T_later_earlier,
                                         &indices, p.earlier, &indices, p.later);
  });
  IntraSessionPairsStats stats = stats_;
  stats.pairs = pairs_.size();
  std::vector<std::vector<std::uint8_t>> dynamic(maps.size());
  for (std::size_t k = 0; k < maps.size(); ++k) dynamic[k].assign(maps[k].points.size(), 0);
  for (std::size_t i = 0; i < pairs_.size(); ++i) {
    const StatusOr<DynamicDetectionResult>& detection = *results_[i];
    if (!detection.ok()) {
      ++stats.skipped_pairs;
      continue;
    }
    const DynamicDetectionResult& d = detection.value();
    stats.pair_s.push_back(d.time_s);
    stats.stage_s.Add(d.stage);
    const Pair& p = pairs_[i];
    if (d.MarksMoreThan(config_.max_dynamic_fraction, maps[p.earlier].points.size(),
                        maps[p.later].points.size())) {
      ++stats.skipped_pairs;
      continue;
    }
    for (std::uint32_t k : d.history_dynamic) {
      if (k < dynamic[p.earlier].size()) dynamic[p.earlier][k] = 1;
    }
    for (std::uint32_t k : d.current_dynamic) {
      if (k < dynamic[p.later].size()) dynamic[p.later][k] = 1;
    }
  }
  for (std::size_t k = 0; k < maps.size(); ++k) {
    const std::size_t before = maps[k].points.size();
    DropSubmapPoints(dynamic[k], &maps[k]);
    stats.points_removed += before - maps[k].points.size();
  }
  return stats;
}

StatusOr<IntraSessionPairsStats> RemoveDynamicsBetweenSubmaps(
    const IntraSessionPairsConfig& config,
    std::vector<Submap, Eigen::aligned_allocator<Submap>>* submaps) {
  IntraSessionPairsConfig at_once = config;
  at_once.during_session = false;
  StatusOr<std::unique_ptr<IntraSessionPairDetector>> pairs =
      IntraSessionPairDetector::Create(at_once);
  if (!pairs.ok()) return pairs.status();
  for (const Submap& submap : *submaps) pairs.value()->Add(submap, submap.T_map_submap);
  return pairs.value()->Finish(submaps);
}

}  // namespace core
}  // namespace multisession_mapper
