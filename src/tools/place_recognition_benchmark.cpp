// Timing benchmark of the place-recognition core (issue 6), not a test:
//  - descriptor computation per scan (ring histogram and Scan Context) on the real VLP-16 scans
//    of ../shared/data/real/vlp16_indoor (or a folder given as the first argument);
//  - database query time on a synthetic database of 100,000 entries (or the second argument),
//    for both descriptor kinds and three noise levels (see MakeEntries and BenchQuery).
// Prints medians and 95th percentiles in milliseconds.
//
// Usage: place_recognition_benchmark [vlp16_pcd_dir] [database_entries]
//            [approximate|within|exact] [index_dim] [ring_histogram_candidates] [search_eps]
//            [scan_context_candidates]
#define PCL_NO_PRECOMPILE
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include <pcl/io/pcd_io.h>
#include <pcl/point_types.h>

#include "multisession_mapper/core/descriptor_database.h"
#include "multisession_mapper/core/ring_histogram_descriptor.h"
#include "multisession_mapper/core/scan_context_descriptor.h"

// The layout of the real VLP-16 files: x y z intensity ring (padding fields are skipped).
namespace msm_bench {
struct EIGEN_ALIGN16 PointXYZIR {
  PCL_ADD_POINT4D;
  float intensity;
  std::uint16_t ring;
  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};
}  // namespace msm_bench
POINT_CLOUD_REGISTER_POINT_STRUCT(msm_bench::PointXYZIR,
                                  (float, x, x)(float, y, y)(float, z, z)(float, intensity,
                                                                         intensity)(
                                      std::uint16_t, ring, ring))

namespace {

namespace core = multisession_mapper::core;
using Clock = std::chrono::steady_clock;

double Ms(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

struct Summary {
  double median = 0.0;
  double p95 = 0.0;
};

Summary Summarise(std::vector<double> values) {
  Summary s;
  if (values.empty()) return s;
  std::sort(values.begin(), values.end());
  s.median = values[values.size() / 2];
  s.p95 = values[std::min(values.size() - 1, values.size() * 95 / 100)];
  return s;
}

std::vector<core::LidarScan> LoadScans(const std::string& dir) {
  std::vector<core::LidarScan> scans;
  for (int i = 0; i < 1000; ++i) {
    const std::string path = dir + "/" + std::to_string(i) + ".pcd";
    if (!std::filesystem::exists(path)) break;
    pcl::PointCloud<msm_bench::PointXYZIR> cloud;
    if (pcl::io::loadPCDFile(path, cloud) != 0) continue;
    bool has_ring = false;
    core::LidarScan scan;
    scan.stamp_s = i;
    for (const auto& p : cloud.points) {
      core::LidarPoint lp;
      lp.position_m = Eigen::Vector3f(p.x, p.y, p.z);
      lp.intensity = p.intensity;
      lp.ring = p.ring;
      has_ring = has_ring || p.ring != 0;
      scan.points.push_back(lp);
    }
    // Files without a ring field (6.pcd is not a sensor-frame sweep) are left out.
    if (!has_ring) continue;
    scan.has_ring = true;
    scans.push_back(std::move(scan));
  }
  return scans;
}

// Synthetic database content: a robot path through places. Entry i lies between two places
// (anchors: real scan descriptors) with a weight moving along the path, plus Gaussian noise on
// every value whose norm is `noise_fraction` of the place's norm (0.065 gives ~0.09 between two
// noisy copies of a unit ring-histogram vector: the simulator's median same-place distance).
std::vector<core::PlaceDescriptor> MakeEntries(const std::vector<core::PlaceDescriptor>& anchors,
                                               std::size_t count, double noise_fraction,
                                               std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::vector<core::PlaceDescriptor> out(count, anchors.front());
  const std::size_t key_dim = anchors.front().key.size();
  const std::size_t matrix_size = anchors.front().matrix.size();
  std::uniform_int_distribution<std::size_t> pick(0, anchors.size() - 1);
  std::normal_distribution<float> unit(0.0f, 1.0f);
  const auto norm = [](const std::vector<float>& v) {
    double sum = 0.0;
    for (float x : v) sum += double(x) * x;
    return std::sqrt(sum);
  };
  const std::size_t steps_per_segment = 200;
  std::size_t a = pick(rng), b = pick(rng);
  for (std::size_t i = 0; i < count; ++i) {
    if (i % steps_per_segment == 0) {
      a = b;
      b = pick(rng);
    }
    core::PlaceDescriptor& d = out[i];
    const float w = static_cast<float>(i % steps_per_segment) / steps_per_segment;
    const float key_sigma =
        static_cast<float>(noise_fraction * norm(anchors[a].key) /
                           std::sqrt(double(std::max<std::size_t>(1, key_dim))));
    const float matrix_sigma = static_cast<float>(
        noise_fraction * norm(anchors[a].matrix) /
        std::sqrt(double(std::max<std::size_t>(1, matrix_size))));
    for (std::size_t k = 0; k < key_dim; ++k) {
      d.key[k] = std::max(0.0f, (1 - w) * anchors[a].key[k] + w * anchors[b].key[k] +
                                    key_sigma * unit(rng));
    }
    for (std::size_t k = 0; k < matrix_size; ++k) {
      d.matrix[k] = std::max(0.0f, (1 - w) * anchors[a].matrix[k] + w * anchors[b].matrix[k] +
                                       matrix_sigma * unit(rng));
    }
    if (d.kind == core::DescriptorKind::kScanContext) {  // ring key = row means of the matrix
      for (int r = 0; r < d.rows; ++r) {
        double sum = 0.0;
        for (int c = 0; c < d.cols; ++c) sum += d.matrix[static_cast<std::size_t>(r * d.cols + c)];
        d.key[static_cast<std::size_t>(r)] = static_cast<float>(sum / d.cols);
      }
    }
  }
  return out;
}

// Times queries on a database of `count` synthetic entries built from all but the last
// `held_out` anchors; queries are new noisy samples: 3/4 from the stored places, 1/4 from the
// held-out places (new places, "no match").
void BenchQuery(const char* label, const std::vector<core::PlaceDescriptor>& anchors,
                std::size_t count, double noise_fraction,
                const core::DescriptorDatabaseConfig& config) {
  const core::PlaceDescriptor& first = anchors.front();
  auto db_or = core::DescriptorDatabase::Create(config, first.kind,
                                                static_cast<int>(first.key.size()), first.rows,
                                                first.cols);
  if (!db_or.ok()) {
    std::printf("%s: %s\n", label, db_or.status().message().c_str());
    return;
  }
  core::DescriptorDatabase db = std::move(db_or).value();
  const std::size_t held_out = std::min<std::size_t>(5, anchors.size() / 4);
  const std::vector<core::PlaceDescriptor> stored(anchors.begin(), anchors.end() - held_out);
  const std::vector<core::PlaceDescriptor> fresh(anchors.end() - held_out, anchors.end());
  const std::vector<core::PlaceDescriptor> entries = MakeEntries(stored, count, noise_fraction, 1);
  std::vector<core::DatabaseEntry> meta(count);
  for (std::size_t i = 0; i < count; ++i) meta[i] = {"synthetic", double(i) * 0.1, int(i / 100)};
  const auto t0 = Clock::now();
  const core::Status status = db.Insert(meta, entries);
  const auto t1 = Clock::now();
  if (!status.ok()) {
    std::printf("%s: %s\n", label, status.message().c_str());
    return;
  }
  std::vector<core::PlaceDescriptor> queries = MakeEntries(stored, 1500, noise_fraction, 2);
  if (!fresh.empty()) {
    const std::vector<core::PlaceDescriptor> new_places =
        MakeEntries(fresh, 500, noise_fraction, 3);
    queries.insert(queries.end(), new_places.begin(), new_places.end());
  }
  std::vector<double> times;
  std::size_t matched = 0, inexact = 0;
  for (std::size_t i = 0; i < queries.size(); i += 2) {
    const auto q0 = Clock::now();
    auto result = db.Query(queries[i]);
    const auto q1 = Clock::now();
    if (!result.ok()) {
      std::printf("%s: %s\n", label, result.status().message().c_str());
      return;
    }
    times.push_back(Ms(q0, q1));
    matched += result.value().matched;
    inexact += !result.value().exact;  // always counted for Scan Context
  }
  // Agreement with a brute-force search (ring histogram; Scan Context has no exact mode): the
  // nearest found is the true nearest, or within 2 % of its distance (in these synthetic data
  // many entries are near-equivalent, so the exact index is not the point).
  std::size_t agree = 0, close = 0, compared = 0;
  if (first.kind == core::DescriptorKind::kRingHistogram) {
    for (std::size_t i = 1; i < queries.size(); i += 10) {
      double best = 1e30;
      std::size_t best_index = 0;
      for (std::size_t e = 0; e < entries.size(); ++e) {
        double sum = 0.0;
        for (std::size_t k = 0; k < first.key.size(); ++k) {
          const double d = queries[i].key[k] - entries[e].key[k];
          sum += d * d;
        }
        if (sum < best) {
          best = sum;
          best_index = e;
        }
      }
      const auto result = db.Query(queries[i]);
      if (!result.ok()) continue;
      const core::DatabaseNeighbor& found = result.value().neighbors.front();
      agree += found.index == best_index;
      close += found.distance <= 1.02 * std::sqrt(best) + 1e-6;
      ++compared;
    }
  }
  const Summary s = Summarise(times);
  std::printf("query %-30s noise %.3f entries %zu dim %zu: build %.0f ms, query median %.3f ms, "
              "p95 %.3f ms (%zu/%zu matched, %zu not proven exact; vs brute force: same %zu, "
              "within 2 %% %zu of %zu)\n",
              label, noise_fraction, count, first.key.size(), Ms(t0, t1), s.median, s.p95,
              matched, times.size(), inexact, agree, close, compared);
}

}  // namespace

int main(int argc, char** argv) {
  const std::string dir =
      argc > 1 ? argv[1] : std::string(MSM_SHARED_DATA_DIR) + "/real/vlp16_indoor";
  const std::size_t count = argc > 2 ? std::stoul(argv[2]) : 100000;
  const std::vector<core::LidarScan> scans = LoadScans(dir);
  if (scans.empty()) {
    std::fprintf(stderr, "no VLP-16 scans (0.pcd, 1.pcd, ...) in %s\n", dir.c_str());
    return 1;
  }
  std::size_t points = 0;
  for (const auto& s : scans) points += s.points.size();
  std::printf("%zu real VLP-16 scans from %s, %zu points on average\n", scans.size(), dir.c_str(),
              points / scans.size());

  auto rh = core::RingHistogramDescriptor::Create(core::RingHistogramDescriptorConfig());
  auto sc = core::ScanContextDescriptor::Create(core::ScanContextConfig());
  if (!rh.ok() || !sc.ok()) return 1;
  std::vector<core::PlaceDescriptor> rh_anchors, sc_anchors;
  std::vector<double> rh_times, sc_times;
  const int repeats = 10;
  for (int r = 0; r < repeats; ++r) {
    for (const core::LidarScan& scan : scans) {
      const auto t0 = Clock::now();
      core::PlaceDescriptor a = rh.value().Compute(scan);
      const auto t1 = Clock::now();
      core::PlaceDescriptor b = sc.value().Compute(scan);
      const auto t2 = Clock::now();
      rh_times.push_back(Ms(t0, t1));
      sc_times.push_back(Ms(t1, t2));
      if (r == 0) {
        rh_anchors.push_back(std::move(a));
        sc_anchors.push_back(std::move(b));
      }
    }
  }
  const Summary rs = Summarise(rh_times), ss = Summarise(sc_times);
  std::printf("descriptor ring_histogram (dim %d): median %.3f ms, p95 %.3f ms per scan\n",
              rh.value().dimension(), rs.median, rs.p95);
  std::printf("descriptor scan_context (%dx%d): median %.3f ms, p95 %.3f ms per scan\n",
              sc.value().config().num_rings, sc.value().config().num_sectors, ss.median, ss.p95);

  core::DescriptorDatabaseConfig config;
  if (argc > 3) {
    const std::string mode = argv[3];
    using Mode = core::DescriptorDatabaseConfig::SearchMode;
    config.search_mode = mode == "exact"    ? Mode::kExact
                         : mode == "within" ? Mode::kExactWithinDAlpha
                                            : Mode::kApproximate;
  }
  if (argc > 4) config.index_dim = std::stoi(argv[4]);
  if (argc > 5) config.rerank_candidates_ring_histogram = std::stoi(argv[5]);
  if (argc > 6) config.search_eps = std::stod(argv[6]);
  if (argc > 7) config.rerank_candidates_scan_context = std::stoi(argv[7]);
  const core::Status valid = config.Validate();
  if (!valid.ok()) {
    std::fprintf(stderr, "%s\n", valid.message().c_str());
    return 1;
  }
  std::printf("database: search mode %s, index_dim %d, ring histogram candidates %d, "
              "scan context candidates %d, search_eps %.2f\n",
              argc > 3 ? argv[3] : "approximate", config.index_dim,
              config.rerank_candidates_ring_histogram, config.rerank_candidates_scan_context,
              config.search_eps);
  for (double noise : {0.02, 0.065, 0.15}) {
    BenchQuery("ring_histogram", rh_anchors, count, noise, config);
    BenchQuery("scan_context", sc_anchors, count, noise, config);
  }
  return 0;
}
