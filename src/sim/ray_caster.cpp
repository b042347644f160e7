#include "multisession_mapper/sim/ray_caster.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

namespace multisession_mapper {
namespace sim {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Per-ray constants of the 2D walk, computed once (divisions are the expensive part).
struct RayWalk {
  double ox, oy, dx, dy;
  double inv_dx, inv_dy;  // 1 / |d| per axis, infinite for an axis-parallel ray
  int step_x, step_y;
};

RayWalk MakeWalk(const Ray& ray) {
  RayWalk w;
  w.ox = ray.origin.x();
  w.oy = ray.origin.y();
  w.dx = ray.direction.x();
  w.dy = ray.direction.y();
  w.step_x = w.dx > 0.0 ? 1 : -1;
  w.step_y = w.dy > 0.0 ? 1 : -1;
  w.inv_dx = std::abs(w.dx) > 1e-12 ? 1.0 / w.dx : 0.0;
  w.inv_dy = std::abs(w.dy) > 1e-12 ? 1.0 / w.dy : 0.0;
  return w;
}

// 2D DDA over a grid of nx x ny square cells of size `cell` (inverse `inv_cell`) starting at
// `origin`, for ray parameters in [t_begin, t_end]. visit(ix, iy, t_in, t_out) returns false to
// stop.
template <typename Visit>
void Traverse(const RayWalk& w, const Eigen::Vector2d& origin, double cell, double inv_cell,
              int nx, int ny, double t_begin, double t_end, Visit&& visit) {
  if (t_begin > t_end) return;
  const double t_mid = t_begin + 1e-9;
  int ix = static_cast<int>(std::floor((w.ox + w.dx * t_mid - origin.x()) * inv_cell));
  int iy = static_cast<int>(std::floor((w.oy + w.dy * t_mid - origin.y()) * inv_cell));
  ix = std::clamp(ix, 0, nx - 1);
  iy = std::clamp(iy, 0, ny - 1);
  double t_max_x = kInf;
  double t_max_y = kInf;
  double t_delta_x = kInf;
  double t_delta_y = kInf;
  if (w.inv_dx != 0.0) {
    t_max_x = (origin.x() + (ix + (w.step_x > 0 ? 1 : 0)) * cell - w.ox) * w.inv_dx;
    t_delta_x = cell * std::abs(w.inv_dx);
  }
  if (w.inv_dy != 0.0) {
    t_max_y = (origin.y() + (iy + (w.step_y > 0 ? 1 : 0)) * cell - w.oy) * w.inv_dy;
    t_delta_y = cell * std::abs(w.inv_dy);
  }
  double t = t_begin;
  while (true) {
    const double t_next = std::min(std::min(t_max_x, t_max_y), t_end);
    if (!visit(ix, iy, t, t_next)) return;
    if (t_next >= t_end) return;
    if (t_max_x < t_max_y) {
      ix += w.step_x;
      t = t_max_x;
      t_max_x += t_delta_x;
    } else {
      iy += w.step_y;
      t = t_max_y;
      t_max_y += t_delta_y;
    }
    if (ix < 0 || iy < 0 || ix >= nx || iy >= ny) return;
  }
}

bool ZOverlap(const Ray& ray, double t_in, double t_out, float z_min, float z_max) {
  const double za = ray.origin.z() + ray.direction.z() * t_in;
  const double zb = ray.origin.z() + ray.direction.z() * t_out;
  return std::max(za, zb) >= z_min - 1e-6 && std::min(za, zb) <= z_max + 1e-6;
}

}  // namespace

core::Status RayCasterConfig::Validate() const {
  if (block_cells < 1 || block_cells > 256) {
    return core::Status::Error("ray_caster.block_cells must be in [1, 256]");
  }
  return core::Status::Ok();
}

core::StatusOr<RayCaster> RayCaster::Create(Terrain terrain, std::vector<Primitive> primitives,
                                            const RayCasterConfig& config) {
  core::Status status = config.Validate();
  if (!status.ok()) return status;
  for (const Primitive& p : primitives) {
    if (!p.half_size_m.allFinite() || (p.half_size_m.array() <= 0.0).any() ||
        !p.pose.matrix().allFinite() || !(p.density_per_m >= 0.0)) {
      return core::Status::Error("ray_caster: primitive of object " +
                                 std::to_string(p.object_id) +
                                 " has a non-positive size, a non-finite pose or density");
    }
  }
  RayCaster caster(std::move(terrain), std::move(primitives), config);
  caster.BuildIndex();
  return caster;
}

RayCaster::RayCaster(Terrain terrain, std::vector<Primitive> primitives,
                     const RayCasterConfig& config)
    : terrain_(std::move(terrain)), primitives_(std::move(primitives)), config_(config) {}

void RayCaster::BuildIndex() {
  const TerrainGrid& g = terrain_.grid();
  nx_ = terrain_.cell_cols();
  ny_ = terrain_.cell_rows();
  const int n = nx_ * ny_;
  cell_z_min_.assign(n, 0.0f);
  cell_z_max_.assign(n, 0.0f);
  for (int cy = 0; cy < ny_; ++cy) {
    for (int cx = 0; cx < nx_; ++cx) {
      double lo, hi;
      terrain_.CellHeightRange(cx, cy, &lo, &hi);
      cell_z_min_[CellIndex(cx, cy)] = static_cast<float>(lo);
      cell_z_max_[CellIndex(cx, cy)] = static_cast<float>(hi);
    }
  }
  cell_terrain_max_ = cell_z_max_;
  primitive_z_min_.resize(primitives_.size());
  primitive_z_max_.resize(primitives_.size());
  // Two passes (count, fill) build the compressed lists in primitive order: deterministic.
  std::vector<std::uint32_t> counts(n + 1, 0);
  std::vector<std::array<int, 4>> ranges(primitives_.size());
  constexpr double kPad = 0.05;
  for (std::size_t i = 0; i < primitives_.size(); ++i) {
    const Eigen::AlignedBox3d box = WorldBounds(primitives_[i]);
    primitive_z_min_[i] = static_cast<float>(box.min().z() - 1e-3);
    primitive_z_max_[i] = static_cast<float>(box.max().z() + 1e-3);
    auto to_cell = [&](double v, double o, int nmax) {
      return std::clamp(static_cast<int>(std::floor((v - o) / g.resolution_m)), 0, nmax - 1);
    };
    const int x0 = to_cell(box.min().x() - kPad, g.origin_m.x(), nx_);
    const int x1 = to_cell(box.max().x() + kPad, g.origin_m.x(), nx_);
    const int y0 = to_cell(box.min().y() - kPad, g.origin_m.y(), ny_);
    const int y1 = to_cell(box.max().y() + kPad, g.origin_m.y(), ny_);
    ranges[i] = {x0, x1, y0, y1};
    for (int cy = y0; cy <= y1; ++cy) {
      for (int cx = x0; cx <= x1; ++cx) {
        const int c = CellIndex(cx, cy);
        ++counts[c + 1];
        cell_z_min_[c] = std::min(cell_z_min_[c], static_cast<float>(box.min().z()));
        cell_z_max_[c] = std::max(cell_z_max_[c], static_cast<float>(box.max().z()));
      }
    }
  }
  cell_offsets_.assign(n + 1, 0);
  for (int c = 0; c < n; ++c) cell_offsets_[c + 1] = cell_offsets_[c] + counts[c + 1];
  cell_items_.assign(cell_offsets_[n], 0);
  std::vector<std::uint32_t> fill(cell_offsets_.begin(), cell_offsets_.end() - 1);
  for (std::size_t i = 0; i < primitives_.size(); ++i) {
    const auto& r = ranges[i];
    for (int cy = r[2]; cy <= r[3]; ++cy) {
      for (int cx = r[0]; cx <= r[1]; ++cx) {
        cell_items_[fill[CellIndex(cx, cy)]++] = static_cast<std::uint32_t>(i);
      }
    }
  }
  const int b = config_.block_cells;
  nbx_ = (nx_ + b - 1) / b;
  nby_ = (ny_ + b - 1) / b;
  block_z_min_.assign(nbx_ * nby_, std::numeric_limits<float>::max());
  block_z_max_.assign(nbx_ * nby_, std::numeric_limits<float>::lowest());
  for (int cy = 0; cy < ny_; ++cy) {
    for (int cx = 0; cx < nx_; ++cx) {
      const int bi = (cy / b) * nbx_ + cx / b;
      block_z_min_[bi] = std::min(block_z_min_[bi], cell_z_min_[CellIndex(cx, cy)]);
      block_z_max_[bi] = std::max(block_z_max_[bi], cell_z_max_[CellIndex(cx, cy)]);
    }
  }
}

bool RayCaster::Cast(const Ray& ray, double min_range_m, double max_range_m, int session,
                     std::uint64_t key, RayHit* hit) const {
  hit->range_m = -1.0;
  const TerrainGrid& g = terrain_.grid();
  const double res = g.resolution_m;
  // Clip the ray to the grid's footprint.
  double t_begin = std::max(min_range_m, 0.0);
  double t_end = max_range_m;
  const double lo[2] = {g.origin_m.x(), g.origin_m.y()};
  const double hi[2] = {g.origin_m.x() + nx_ * res, g.origin_m.y() + ny_ * res};
  for (int a = 0; a < 2; ++a) {
    const double o = ray.origin[a];
    const double d = ray.direction[a];
    if (std::abs(d) < 1e-12) {
      if (o < lo[a] || o > hi[a]) return false;
      continue;
    }
    double ta = (lo[a] - o) / d;
    double tb = (hi[a] - o) / d;
    if (ta > tb) std::swap(ta, tb);
    t_begin = std::max(t_begin, ta);
    t_end = std::min(t_end, tb);
  }
  if (t_begin >= t_end) return false;

  const std::uint64_t session_bit = 1ULL << session;
  double best_t = kInf;
  int best_primitive = -2;  // -2 none, -1 terrain
  std::uint32_t recent[8] = {~0u, ~0u, ~0u, ~0u, ~0u, ~0u, ~0u, ~0u};
  int recent_pos = 0;

  auto visit_cell = [&](int cx, int cy, double t_in, double t_out) {
    if (t_in > best_t) return false;
    const int c = CellIndex(cx, cy);
    const double za = ray.origin.z() + ray.direction.z() * t_in;
    const double zb = ray.origin.z() + ray.direction.z() * t_out;
    const float ray_z_lo = static_cast<float>(std::min(za, zb) - 1e-6);
    const float ray_z_hi = static_cast<float>(std::max(za, zb) + 1e-6);
    if (ray_z_hi < cell_z_min_[c] || ray_z_lo > cell_z_max_[c]) return true;
    if (ray_z_lo <= cell_terrain_max_[c]) {
      const double t_hi = std::min(t_out + 1e-6, best_t);
      const double tt =
          terrain_.IntersectCell(cx, cy, ray, std::max(t_in - 1e-6, t_begin), t_hi);
      if (tt >= 0.0 && tt < best_t) {
        best_t = tt;
        best_primitive = -1;
      }
    }
    for (std::uint32_t k = cell_offsets_[c]; k < cell_offsets_[c + 1]; ++k) {
      const std::uint32_t pi = cell_items_[k];
      // The primitive is listed in every cell it covers: test it where the ray is at its height.
      if (ray_z_hi < primitive_z_min_[pi] || ray_z_lo > primitive_z_max_[pi]) continue;
      const Primitive& p = primitives_[pi];
      if (!(p.sessions_mask & session_bit)) continue;
      bool seen = false;
      for (std::uint32_t r : recent) seen |= (r == pi);
      if (seen) continue;
      recent[recent_pos] = pi;
      recent_pos = (recent_pos + 1) & 7;
      const double t = HitDistance(p, ray, t_begin, std::min(best_t, t_end), key);
      if (t >= 0.0 && t < best_t) {
        best_t = t;
        best_primitive = static_cast<int>(pi);
      }
    }
    return best_t > t_out;  // a hit inside this cell is final
  };

  const double block_size = res * config_.block_cells;
  const RayWalk walk = MakeWalk(ray);
  const double inv_res = 1.0 / res;
  const double inv_block = 1.0 / block_size;
  Traverse(walk, g.origin_m, block_size, inv_block, nbx_, nby_, t_begin, t_end,
           [&](int bx, int by, double t_in, double t_out) {
             if (t_in > best_t) return false;
             const int bi = by * nbx_ + bx;
             if (!ZOverlap(ray, t_in, t_out, block_z_min_[bi], block_z_max_[bi])) return true;
             Traverse(walk, g.origin_m, res, inv_res, nx_, ny_, t_in, t_out, visit_cell);
             return best_t > t_out;
           });

  if (best_primitive == -2 || best_t > max_range_m) return false;
  hit->range_m = best_t;
  const Eigen::Vector3d point = ray.origin + ray.direction * best_t;
  if (best_primitive == -1) {
    hit->object_class = ObjectClass::kTerrain;
    hit->object_id = 0;
    hit->reflectivity = GroundReflectivity(terrain_.Material(point.x(), point.y()));
    hit->normal = terrain_.Normal(point.x(), point.y());
  } else {
    const Primitive& p = primitives_[best_primitive];
    hit->object_class = p.object_class;
    hit->object_id = p.object_id;
    hit->reflectivity = p.reflectivity;
    // Leaves in a porous volume face every way: use the ray itself as the normal.
    hit->normal = p.density_per_m > 0.0 ? Eigen::Vector3d(-ray.direction)
                                        : SurfaceNormal(p, point);
  }
  return true;
}

double RayCaster::DistanceToSurface(const Eigen::Vector3d& point, int session) const {
  const TerrainGrid& g = terrain_.grid();
  const Eigen::Vector3d n = terrain_.Normal(point.x(), point.y());
  double best = std::abs(point.z() - terrain_.Height(point.x(), point.y())) * n.z();
  const int cx = std::clamp(
      static_cast<int>(std::floor((point.x() - g.origin_m.x()) / g.resolution_m)), 0, nx_ - 1);
  const int cy = std::clamp(
      static_cast<int>(std::floor((point.y() - g.origin_m.y()) / g.resolution_m)), 0, ny_ - 1);
  const int c = CellIndex(cx, cy);
  const std::uint64_t session_bit = 1ULL << session;
  for (std::uint32_t k = cell_offsets_[c]; k < cell_offsets_[c + 1]; ++k) {
    const Primitive& p = primitives_[cell_items_[k]];
    if (!(p.sessions_mask & session_bit)) continue;
    double d = SignedDistance(p, point);
    if (p.density_per_m > 0.0 && d < 0.0) d = 0.0;
    best = std::min(best, std::abs(d));
  }
  return best;
}

}  // namespace sim
}  // namespace multisession_mapper
