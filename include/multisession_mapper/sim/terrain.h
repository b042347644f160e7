// Terrain of the simulated world: a regular height grid, triangulated (two triangles per cell,
// split along the (0,0)-(1,1) diagonal), so that height queries, ray hits and the robot's
// wheel contacts all see the same surface. Each cell also carries a ground material (asphalt,
// pavement, grass) that sets the return intensity.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "multisession_mapper/core/status.h"
#include "multisession_mapper/sim/primitive.h"

namespace multisession_mapper {
namespace sim {

enum class GroundMaterial : std::uint8_t { kGrass = 0, kAsphalt = 1, kPavement = 2 };

/// Diffuse reflectivity of a ground material (typical VLP-16 returns: asphalt dark, paving
/// light, grass medium).
double GroundReflectivity(GroundMaterial material);

struct TerrainGrid {
  Eigen::Vector2d origin_m = Eigen::Vector2d::Zero();  ///< world x/y of vertex (0, 0)
  double resolution_m = 2.0;                            ///< vertex spacing [m]
  int cols = 0;  ///< vertices along x
  int rows = 0;  ///< vertices along y
  std::vector<float> heights_m;              ///< rows x cols, row-major (row = y index)
  std::vector<std::uint8_t> materials;       ///< (rows-1) x (cols-1) cells, GroundMaterial

  core::Status Validate() const;
};

class Terrain {
 public:
  /// `grid` must be valid (TerrainGrid::Validate).
  static core::StatusOr<Terrain> Create(TerrainGrid grid);

  const TerrainGrid& grid() const { return grid_; }
  int cell_cols() const { return grid_.cols - 1; }
  int cell_rows() const { return grid_.rows - 1; }

  /// Height of the triangulated surface [m]; positions outside are clamped to the border.
  double Height(double x_m, double y_m) const;
  /// Upward unit normal of the triangle under (x, y).
  Eigen::Vector3d Normal(double x_m, double y_m) const;
  GroundMaterial Material(double x_m, double y_m) const;

  /// Lowest and highest vertex of cell (cx, cy).
  void CellHeightRange(int cx, int cy, double* z_min, double* z_max) const;
  /// First hit of the ray on the two triangles of cell (cx, cy) with t in [t_min, t_max];
  /// negative when none.
  double IntersectCell(int cx, int cy, const Ray& ray, double t_min, double t_max) const;

 private:
  explicit Terrain(TerrainGrid grid) : grid_(std::move(grid)) {}
  double Vertex(int ix, int iy) const { return grid_.heights_m[iy * grid_.cols + ix]; }
  /// Cell index and local coordinates (u, v) in [0, 1] of a position (clamped).
  void Locate(double x_m, double y_m, int* cx, int* cy, double* u, double* v) const;
  /// The triangle under (x, y): corner height, cell coordinates and slopes per cell.
  void Facet(double x_m, double y_m, double* h00, double* u, double* v, double* dzdu,
             double* dzdv) const;

  TerrainGrid grid_;
};

}  // namespace sim
}  // namespace multisession_mapper
