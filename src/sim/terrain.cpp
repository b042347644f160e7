#include "multisession_mapper/sim/terrain.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>

namespace multisession_mapper {
namespace sim {

double GroundReflectivity(GroundMaterial material) {
  switch (material) {
    case GroundMaterial::kAsphalt:
      return 0.08;
    case GroundMaterial::kPavement:
      return 0.30;
    case GroundMaterial::kGrass:
      return 0.20;
  }
  return 0.2;
}

core::Status TerrainGrid::Validate() const {
  if (!(resolution_m > 0.0) || !origin_m.allFinite()) {
    return core::Status::Error("terrain: resolution_m must be > 0 and the origin finite");
  }
  if (cols < 2 || rows < 2) return core::Status::Error("terrain: need at least 2x2 vertices");
  if (heights_m.size() != static_cast<std::size_t>(cols) * rows) {
    return core::Status::Error("terrain: heights has " + std::to_string(heights_m.size()) +
                               " values, expected rows*cols = " + std::to_string(cols * rows));
  }
  if (materials.size() != static_cast<std::size_t>(cols - 1) * (rows - 1)) {
    return core::Status::Error("terrain: materials must have (rows-1)*(cols-1) values");
  }
  for (float h : heights_m) {
    if (!std::isfinite(h)) return core::Status::Error("terrain: non-finite height");
  }
  return core::Status::Ok();
}

core::StatusOr<Terrain> Terrain::Create(TerrainGrid grid) {
  core::Status status = grid.Validate();
  if (!status.ok()) return status;
  return Terrain(std::move(grid));
}

void Terrain::Locate(double x_m, double y_m, int* cx, int* cy, double* u, double* v) const {
  const double gx = (x_m - grid_.origin_m.x()) / grid_.resolution_m;
  const double gy = (y_m - grid_.origin_m.y()) / grid_.resolution_m;
  const double max_x = grid_.cols - 1;
  const double max_y = grid_.rows - 1;
  const double cgx = std::clamp(gx, 0.0, max_x);
  const double cgy = std::clamp(gy, 0.0, max_y);
  *cx = std::min(static_cast<int>(cgx), grid_.cols - 2);
  *cy = std::min(static_cast<int>(cgy), grid_.rows - 2);
  *u = cgx - *cx;
  *v = cgy - *cy;
}

void Terrain::Facet(double x_m, double y_m, double* h00, double* u, double* v, double* dzdu,
                    double* dzdv) const {
  int cx, cy;
  Locate(x_m, y_m, &cx, &cy, u, v);
  *h00 = Vertex(cx, cy);
  const double h10 = Vertex(cx + 1, cy);
  const double h01 = Vertex(cx, cy + 1);
  const double h11 = Vertex(cx + 1, cy + 1);
  // Each cell is split into two triangles along its diagonal.
  if (*u >= *v) {
    *dzdu = h10 - *h00;
    *dzdv = h11 - h10;
  } else {
    *dzdu = h11 - h01;
    *dzdv = h01 - *h00;
  }
}

double Terrain::Height(double x_m, double y_m) const {
  double h00, u, v, dzdu, dzdv;
  Facet(x_m, y_m, &h00, &u, &v, &dzdu, &dzdv);
  return h00 + u * dzdu + v * dzdv;
}

Eigen::Vector3d Terrain::Normal(double x_m, double y_m) const {
  double h00, u, v, dzdu, dzdv;
  Facet(x_m, y_m, &h00, &u, &v, &dzdu, &dzdv);
  const double r = grid_.resolution_m;
  return Eigen::Vector3d(-dzdu / r, -dzdv / r, 1.0).normalized();
}

GroundMaterial Terrain::Material(double x_m, double y_m) const {
  int cx, cy;
  double u, v;
  Locate(x_m, y_m, &cx, &cy, &u, &v);
  return static_cast<GroundMaterial>(grid_.materials[cy * (grid_.cols - 1) + cx]);
}

void Terrain::CellHeightRange(int cx, int cy, double* z_min, double* z_max) const {
  const double a = Vertex(cx, cy);
  const double b = Vertex(cx + 1, cy);
  const double c = Vertex(cx, cy + 1);
  const double d = Vertex(cx + 1, cy + 1);
  *z_min = std::min(std::min(a, b), std::min(c, d));
  *z_max = std::max(std::max(a, b), std::max(c, d));
}

double Terrain::IntersectCell(int cx, int cy, const Ray& ray, double t_min, double t_max) const {
  const double r = grid_.resolution_m;
  const double x0 = grid_.origin_m.x() + cx * r;
  const double y0 = grid_.origin_m.y() + cy * r;
  const double h00 = Vertex(cx, cy);
  const double h10 = Vertex(cx + 1, cy);
  const double h01 = Vertex(cx, cy + 1);
  const double h11 = Vertex(cx + 1, cy + 1);
  // Ray in cell units: u = (x - x0) / r, v = (y - y0) / r.
  const double ou = (ray.origin.x() - x0) / r;
  const double ov = (ray.origin.y() - y0) / r;
  const double du = ray.direction.x() / r;
  const double dv = ray.direction.y() / r;
  constexpr double kEps = 1e-7;
  double best = -1.0;
  for (int tri = 0; tri < 2; ++tri) {
    // Plane z = a + b u + c v of the triangle.
    const double a = h00;
    const double b = tri == 0 ? h10 - h00 : h11 - h01;
    const double c = tri == 0 ? h11 - h10 : h01 - h00;
    const double denom = ray.direction.z() - b * du - c * dv;
    if (std::abs(denom) < 1e-12) continue;
    const double t = (a + b * ou + c * ov - ray.origin.z()) / denom;
    if (t < t_min || t > t_max) continue;
    const double u = ou + du * t;
    const double v = ov + dv * t;
    if (u < -kEps || u > 1.0 + kEps || v < -kEps || v > 1.0 + kEps) continue;
    if (tri == 0 ? (u + kEps < v) : (v + kEps < u)) continue;
    if (best < 0.0 || t < best) best = t;
  }
  return best;
}

}  // namespace sim
}  // namespace multisession_mapper
