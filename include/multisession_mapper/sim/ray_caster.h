// Ray casting against the static world: terrain plus every static or low-dynamic primitive,
// indexed in a two-level uniform 2D grid (cells = terrain cells, blocks of block_cells x
// block_cells cells) that stores the height range of its contents. A ray walks the blocks with
// a 2D DDA (Amanatides and Woo, "A fast voxel traversal algorithm for ray tracing",
// Eurographics 1987), skips every block or cell whose height range it passes above or below,
// and tests only the primitives listed in the cells it crosses. Rays over open ground or into
// the sky therefore cost a handful of steps; a VLP-16 sweep (28,800 rays) costs a few ms.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "multisession_mapper/core/status.h"
#include "multisession_mapper/sim/primitive.h"
#include "multisession_mapper/sim/terrain.h"

namespace multisession_mapper {
namespace sim {

struct RayHit {
  double range_m = -1.0;  ///< distance along the ray; negative: no hit
  ObjectClass object_class = ObjectClass::kTerrain;
  std::uint32_t object_id = 0;  ///< 0 for the terrain
  double reflectivity = 0.0;
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  ///< unit surface normal (world)
};

struct RayCasterConfig {
  /// Cells per block side of the coarse level (a block is block_cells * resolution wide).
  int block_cells = 4;
  core::Status Validate() const;
};

class RayCaster {
 public:
  static core::StatusOr<RayCaster> Create(Terrain terrain, std::vector<Primitive> primitives,
                                          const RayCasterConfig& config = RayCasterConfig());

  /// Nearest return along `ray` in (min_range_m, max_range_m] for session `session`
  /// (primitives whose sessions_mask lacks the bit are ignored). `key` seeds the porous
  /// volumes' draws for this ray. Returns false (and hit->range_m < 0) for no return.
  bool Cast(const Ray& ray, double min_range_m, double max_range_m, int session,
            std::uint64_t key, RayHit* hit) const;

  /// Unsigned distance from `point` to the nearest surface present in `session` among the
  /// terrain and the primitives of the point's cell [m]; 0 inside porous volumes. Meant for
  /// points on or near surfaces (validation), not as a global distance field.
  double DistanceToSurface(const Eigen::Vector3d& point, int session) const;

  const Terrain& terrain() const { return terrain_; }
  const std::vector<Primitive>& primitives() const { return primitives_; }

 private:
  RayCaster(Terrain terrain, std::vector<Primitive> primitives, const RayCasterConfig& config);
  void BuildIndex();
  int CellIndex(int cx, int cy) const { return cy * nx_ + cx; }

  Terrain terrain_;
  std::vector<Primitive> primitives_;
  RayCasterConfig config_;
  int nx_ = 0;
  int ny_ = 0;
  int nbx_ = 0;
  int nby_ = 0;
  std::vector<std::uint32_t> cell_offsets_;  ///< CSR: primitives of cell i are
  std::vector<std::uint32_t> cell_items_;    ///< cell_items_[cell_offsets_[i] .. [i+1])
  std::vector<float> cell_z_min_;
  std::vector<float> cell_z_max_;
  std::vector<float> cell_terrain_max_;
  std::vector<float> primitive_z_min_;  ///< world AABB height range per primitive
  std::vector<float> primitive_z_max_;
  std::vector<float> block_z_min_;
  std::vector<float> block_z_max_;
};

}  // namespace sim
}  // namespace multisession_mapper
