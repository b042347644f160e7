#include "multisession_mapper/core/local_plane.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Eigenvalues>

#include "multisession_mapper/core/fast_atan2.h"

namespace multisession_mapper {
namespace core {

Status LocalPlaneCriteria::Validate() const {
  if (min_points < 3) {
    return Status::Error("local_plane.min_points must be >= 3, got " +
                         std::to_string(min_points));
  }
  if (!std::isfinite(max_flatness) || max_flatness <= 0.0 || max_flatness > 1.0) {
    return Status::Error("local_plane.max_flatness must be in (0, 1], got " +
                         std::to_string(max_flatness));
  }
  if (!std::isfinite(min_mid_to_max) || min_mid_to_max < 0.0 || min_mid_to_max > 1.0) {
    return Status::Error("local_plane.min_mid_to_max must be in [0, 1], got " +
                         std::to_string(min_mid_to_max));
  }
  if (!std::isfinite(min_mid_std_m) || min_mid_std_m < 0.0) {
    return Status::Error("local_plane.min_mid_std_m must be >= 0, got " +
                         std::to_string(min_mid_std_m));
  }
  return Status::Ok();
}

bool CovarianceAccumulator::Normal(const LocalPlaneCriteria& criteria,
                                   Eigen::Vector3d* normal) const {
  if (count_ < criteria.min_points || count_ < 3) return false;
  const double inv_n = 1.0 / count_;
  const Eigen::Vector3d mean = sum_ * inv_n;
  const Eigen::Matrix3d cov = sum_outer_ * inv_n - mean * mean.transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver;
  solver.computeDirect(cov);  // closed form: ~10x faster than the iterative solver for 3x3
  const Eigen::Vector3d& ev = solver.eigenvalues();  // ascending
  if (!(ev(2) > 0.0)) return false;
  if (ev(1) < criteria.min_mid_to_max * ev(2)) return false;
  if (ev(1) < criteria.min_mid_std_m * criteria.min_mid_std_m) return false;
  if (ev(0) > criteria.max_flatness * ev(1)) return false;
  *normal = solver.eigenvectors().col(0).normalized();
  return normal->allFinite();
}

Status ScanNormalConfig::Validate() const {
  if (azimuth_bins < 8) {
    return Status::Error("scan_normal.azimuth_bins must be >= 8, got " +
                         std::to_string(azimuth_bins));
  }
  // In 64 bits: this bound keeps EstimateScanNormals' column look-ups inside their row.
  if (column_reach < 1 || column_step < 1 ||
      std::int64_t{column_reach} * column_step * 2 >= azimuth_bins) {
    return Status::Error("scan_normal.column_reach / column_step must be >= 1 and span less "
                         "than the full circle");
  }
  if (!std::isfinite(max_neighbor_distance_abs_m) || max_neighbor_distance_abs_m <= 0.0 ||
      !std::isfinite(max_neighbor_distance_rel) || max_neighbor_distance_rel < 0.0) {
    return Status::Error("scan_normal.max_neighbor_distance_abs_m must be > 0 and "
                         "max_neighbor_distance_rel >= 0");
  }
  return plane.Validate();
}

namespace {

int AzimuthBin(const Eigen::Vector3f& p, int bins) {
  constexpr double kTwoPi = 2.0 * M_PI;
  double a = FastAtan2(static_cast<double>(p.y()), static_cast<double>(p.x()));
  if (a < 0.0) a += kTwoPi;
  const int bin = static_cast<int>(a * bins / kTwoPi);
  return std::min(bin, bins - 1);
}

}  // namespace

PointVector EstimateScanNormals(const LidarScan& scan, const std::vector<LidarPoint>& queries,
                                const ScanNormalConfig& config) {
  PointVector normals(queries.size(), Eigen::Vector3d::Zero());
  if (!scan.has_ring || queries.empty() || !config.Validate().ok()) return normals;
  int rings = 0;
  for (const LidarPoint& p : scan.points) rings = std::max(rings, static_cast<int>(p.ring) + 1);
  if (rings < 2) return normals;
  const int bins = config.azimuth_bins;
  // Range image: the first point per (ring, azimuth bin), its position held in the cell so that
  // the neighbour look-ups below read one compact array instead of the scattered scan points.
  struct Cell {
    float x, y, z;
    bool filled;
  };
  std::vector<Cell> image(static_cast<std::size_t>(rings) * bins, Cell{0.0f, 0.0f, 0.0f, false});
  for (const LidarPoint& p : scan.points) {
    if (!p.position_m.allFinite()) continue;
    Cell& cell = image[static_cast<std::size_t>(p.ring) * bins + AzimuthBin(p.position_m, bins)];
    if (!cell.filled) cell = Cell{p.position_m.x(), p.position_m.y(), p.position_m.z(), true};
  }
  for (std::size_t k = 0; k < queries.size(); ++k) {
    const LidarPoint& query = queries[k];
    if (!query.position_m.allFinite() || query.ring >= rings) continue;
    const Eigen::Vector3d q = query.position_m.cast<double>();
    const double reach = config.max_neighbor_distance_abs_m +
                         config.max_neighbor_distance_rel * q.norm();
    const double reach_sq = reach * reach;
    const int col = AzimuthBin(query.position_m, bins);
    CovarianceAccumulator acc;
    acc.Add(Eigen::Vector3d::Zero());  // the query itself (centred at the query)
    bool other_ring = false;
    for (int dr = -1; dr <= 1; ++dr) {
      const int ring = static_cast<int>(query.ring) + dr;
      if (ring < 0 || ring >= rings) continue;
      const Cell* row = image.data() + static_cast<std::size_t>(ring) * bins;
      for (int dc = -config.column_reach; dc <= config.column_reach; ++dc) {
        if (dr == 0 && dc == 0) continue;
        // One wrap suffices: Validate keeps column_reach * column_step below half the circle
        // (a modulo here cost two integer divisions per look-up, ~1/4 of this function).
        int c = col + dc * config.column_step;
        if (c < 0) {
          c += bins;
        } else if (c >= bins) {
          c -= bins;
        }
        const Cell& cell = row[c];
        if (!cell.filled) continue;
        const Eigen::Vector3d d = Eigen::Vector3d(cell.x, cell.y, cell.z) - q;
        if (d.squaredNorm() > reach_sq) continue;
        acc.Add(d);
        if (dr != 0) other_ring = true;
      }
    }
    if (!other_ring) continue;
    Eigen::Vector3d n;
    if (acc.Normal(config.plane, &n)) normals[k] = n;
  }
  return normals;
}

void DropHighPointsOffWalls(double min_height_m, double max_abs_normal_z, PointVector* points,
                            PointVector* normals) {
  std::size_t kept = 0;
  for (std::size_t i = 0; i < points->size(); ++i) {
    if ((*points)[i].z() > min_height_m && std::abs((*normals)[i].z()) > max_abs_normal_z) {
      continue;
    }
    (*points)[kept] = (*points)[i];
    (*normals)[kept] = (*normals)[i];
    ++kept;
  }
  points->resize(kept);
  normals->resize(kept);
}

}  // namespace core
}  // namespace multisession_mapper
