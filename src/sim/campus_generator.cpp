#include "multisession_mapper/sim/campus_generator.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <utility>

#include "multisession_mapper/sim/counter_rng.h"
#include "multisession_mapper/sim/road_path.h"
#include "multisession_mapper/sim/terrain.h"

namespace multisession_mapper {
namespace sim {
namespace {

constexpr int kRoads = 6;               // road lines per axis
constexpr double kHalfExtent = 250.0;   // world is [-250, 250]^2
constexpr double kResolution = 2.0;     // terrain vertex spacing
constexpr double kLaneHalf = 3.5;       // two lanes
constexpr double kAsphaltHalf = 5.5;    // lanes + parking strip
constexpr double kSidewalkEdge = 8.0;   // curb to here: pavement
constexpr double kBlockMargin = 9.5;    // block content starts this far from a centreline
constexpr double kCarLaneOffset = 1.75;
constexpr double kSidewalkOffset = 6.8;

struct ProfileSpec {
  double cruise_mps;
  int background_cars;
  int background_pedestrians;
  int encounter_pedestrians;
  int encounter_cars;
  int crossing_pedestrians;
};

ProfileSpec SpecFor(const std::string& profile) {
  if (profile == "campus") return {1.8, 10, 16, 18, 8, 6};
  if (profile == "small") return {3.0, 3, 4, 5, 3, 2};
  return {2.0, 0, 0, 2, 1, 1};  // tiny
}

// Route node: (i, j) indices into the road lines; fractional values lie on a road between two
// intersections.
using Node = std::array<double, 2>;

std::vector<Node> RoutePattern(const std::string& profile, int pattern) {
  if (profile == "campus") {
    switch (pattern) {
      case 0:  // loop around the central 3x3 blocks and beyond its start: intra-session loop
        return {{1, 1.5}, {1, 1}, {4, 1}, {4, 4}, {1, 4}, {1, 1}, {2, 1}};
      case 1:  // the loop in the opposite direction, then through the inner blocks to the west
        return {{4, 2.5}, {4, 1}, {1, 1}, {1, 4}, {3, 4}, {3, 3}, {2, 3}, {2, 2}, {0, 2}};
      default:  // same direction as session 0, a different start, and the east side
        return {{2.5, 1}, {4, 1}, {5, 1}, {5, 4}, {4, 4}, {1, 4}, {1, 2}, {2, 2}, {2, 1}};
    }
  }
  if (profile == "small") {
    switch (pattern) {
      case 0:  // around the small central block and back past the start
        return {{2, 2.8}, {2, 2}, {3, 2}, {3, 3}, {2, 3}, {2, 2.2}};
      case 1:  // opposite direction, other start, then west along a road nobody else takes
        return {{3, 2.6}, {3, 2}, {2, 2}, {2, 3}, {1.4, 3}};
      default:  // same direction as session 0, then south into an area only it sees
        return {{2.4, 2}, {3, 2}, {3, 3}, {2, 3}, {2, 2}, {2, 1.65}};
    }
  }
  switch (pattern) {  // tiny
    case 0:
      return {{2, 2.3}, {2, 2.7}};
    case 1:
      return {{2, 2.7}, {2, 2.3}};
    default:
      return {{2.3, 2}, {2.7, 2}};
  }
}

class Generator {
 public:
  Generator(const CampusConfig& config) : config_(config), rng_(MakeKey(config.seed, 0xCA3905)) {
    spec_ = SpecFor(config.profile);
  }

  core::StatusOr<Campus> Run();

 private:
  double X(double i) const { return Lerp(xs_, i); }
  double Y(double j) const { return Lerp(ys_, j); }
  static double Lerp(const std::array<double, kRoads>& v, double f) {
    const int a = std::clamp(static_cast<int>(std::floor(f)), 0, kRoads - 1);
    const int b = std::min(a + 1, kRoads - 1);
    return v[a] + (f - a) * (v[b] - v[a]);
  }
  Eigen::Vector2d NodeXY(const Node& n) const { return {X(n[0]), Y(n[1])}; }
  double Ground(double x, double y) const { return terrain_->Height(x, y); }
  std::uint64_t AllMask() const { return world_.AllSessionsMask(); }
  // Random non-empty subset of the sessions that is not all of them (when there are >= 2).
  std::uint64_t ChangingMask(double p_present);

  void MakeRoads();
  core::Status MakeTerrain();
  void SetMaterials();
  void MakeCurbs();
  void MakeBlocks();
  void MakeStreetFurniture();
  void MakeParking();
  void MakeMovables();
  core::Status MakeRoutes();
  core::Status MakeMovers();

  // Object builders (positions on the ground at (x, y)).
  WorldObject& Add(ObjectClass cls, const std::string& kind, Shape shape);
  void AddTree(double x, double y, double scale);
  void AddLampPost(double x, double y);
  void AddHedge(double x0, double y0, double x1, double y1, double height, double width);
  void AddWall(double x0, double y0, double x1, double y1, double height, bool fence);
  void AddBuilding(double cx, double cy, double lx, double ly, double height, double yaw);
  void AddCar(double x, double y, double yaw, std::uint64_t mask, ObjectClass cls,
              CounterRng* rng);
  void AddBox(ObjectClass cls, const std::string& kind, double x, double y, double yaw,
              const Eigen::Vector3d& size, double reflectivity, double density,
              std::uint64_t mask);
  bool Free(double x0, double y0, double x1, double y1);
  void Occupy(double x0, double y0, double x1, double y1) {
    occupied_.push_back(Eigen::AlignedBox2d(Eigen::Vector2d(x0, y0), Eigen::Vector2d(x1, y1)));
  }
  std::vector<Node> RandomWalk(int nodes, CounterRng* rng);
  void AddMover(ObjectClass cls, int session, const RoadPath& path, double s0, double speed,
                double offset, double t_begin, double t_end, double t_ref, CounterRng* rng);

  CampusConfig config_;
  ProfileSpec spec_;
  CounterRng rng_;
  World world_;
  std::unique_ptr<Terrain> terrain_;
  std::array<double, kRoads> xs_{};
  std::array<double, kRoads> ys_{};
  std::vector<int> block_type_;  // 0 buildings, 1 park, 2 parking, 3 plaza, 4 courtyard
  std::vector<Eigen::AlignedBox2d> occupied_;
  std::vector<std::array<double, 4>> parking_slots_;  // x, y, yaw, unused
  std::uint32_t next_id_ = 1;
  std::vector<RobotTrajectory> trajectories_;
};

std::uint64_t Generator::ChangingMask(double p_present) {
  const int n = static_cast<int>(world_.session_names.size());
  if (n == 1) return 1ULL;
  for (int attempt = 0; attempt < 64; ++attempt) {
    std::uint64_t mask = 0;
    for (int s = 0; s < n; ++s) {
      if (rng_.Bernoulli(p_present)) mask |= 1ULL << s;
    }
    if (mask != 0 && mask != AllMask()) return mask;
  }
  return 1ULL << rng_.UniformInt(0, n - 1);
}

void Generator::MakeRoads() {
  const std::array<double, kRoads> bx = {-200, -110, -20, 15, 110, 200};
  const std::array<double, kRoads> by = {-200, -100, -10, 20, 120, 210};
  for (int k = 0; k < kRoads; ++k) {
    const double jitter = (k == 2 || k == 3) ? 1.5 : 6.0;
    xs_[k] = std::round(bx[k] + rng_.Uniform(-jitter, jitter));
    ys_[k] = std::round(by[k] + rng_.Uniform(-jitter, jitter));
  }
}

core::Status Generator::MakeTerrain() {
  TerrainGrid& g = world_.terrain;
  g.origin_m = Eigen::Vector2d(-kHalfExtent, -kHalfExtent);
  g.resolution_m = kResolution;
  g.cols = static_cast<int>(2.0 * kHalfExtent / kResolution) + 1;
  g.rows = g.cols;
  const double tilt_x = rng_.Uniform(-0.012, 0.012);
  const double tilt_y = rng_.Uniform(-0.012, 0.012);
  const double a1 = rng_.Uniform(0.8, 1.4), l1 = rng_.Uniform(180, 260), p1 = rng_.Uniform(0, 6.28);
  const double l2 = rng_.Uniform(180, 260), p2 = rng_.Uniform(0, 6.28);
  const double a2 = rng_.Uniform(0.2, 0.4), l3 = rng_.Uniform(90, 130), p3 = rng_.Uniform(0, 6.28);
  // The ramp: the east part of the campus lies 2 m higher, reached over a 25 m slope (8%).
  const double ramp_x = 0.5 * (xs_[3] + xs_[4]) - 12.5;
  const double ramp_len = 25.0;
  const double ramp_h = 2.0;
  g.heights_m.resize(static_cast<std::size_t>(g.cols) * g.rows);
  for (int r = 0; r < g.rows; ++r) {
    for (int c = 0; c < g.cols; ++c) {
      const double x = g.origin_m.x() + c * kResolution;
      const double y = g.origin_m.y() + r * kResolution;
      double h = tilt_x * x + tilt_y * y;
      h += a1 * std::sin(2 * M_PI * x / l1 + p1) * std::cos(2 * M_PI * y / l2 + p2);
      h += a2 * std::sin(2 * M_PI * (x + y) / l3 + p3);
      h += ramp_h * std::clamp((x - ramp_x) / ramp_len, 0.0, 1.0);
      g.heights_m[r * g.cols + c] = static_cast<float>(std::round(h * 1000.0) / 1000.0);
    }
  }
  g.materials.assign(static_cast<std::size_t>(g.cols - 1) * (g.rows - 1), 0);
  SetMaterials();
  auto terrain = Terrain::Create(g);
  if (!terrain.ok()) return terrain.status();
  terrain_ = std::make_unique<Terrain>(std::move(terrain).value());
  return core::Status::Ok();
}

void Generator::SetMaterials() {
  TerrainGrid& g = world_.terrain;
  const double lo_x = xs_.front(), hi_x = xs_.back(), lo_y = ys_.front(), hi_y = ys_.back();
  for (int r = 0; r + 1 < g.rows; ++r) {
    for (int c = 0; c + 1 < g.cols; ++c) {
      const double x = g.origin_m.x() + (c + 0.5) * kResolution;
      const double y = g.origin_m.y() + (r + 0.5) * kResolution;
      double d = 1e9;
      if (y >= lo_y - kSidewalkEdge && y <= hi_y + kSidewalkEdge) {
        for (double rx : xs_) d = std::min(d, std::abs(x - rx));
      }
      if (x >= lo_x - kSidewalkEdge && x <= hi_x + kSidewalkEdge) {
        for (double ry : ys_) d = std::min(d, std::abs(y - ry));
      }
      std::uint8_t m = 0;
      if (d <= kAsphaltHalf) {
        m = static_cast<std::uint8_t>(GroundMaterial::kAsphalt);
      } else if (d <= kSidewalkEdge) {
        m = static_cast<std::uint8_t>(GroundMaterial::kPavement);
      } else {
        // Parking lots are asphalt, plazas paved (block type chosen before the terrain).
        for (int bj = 0; bj + 1 < kRoads; ++bj) {
          for (int bi = 0; bi + 1 < kRoads; ++bi) {
            if (x > xs_[bi] && x < xs_[bi + 1] && y > ys_[bj] && y < ys_[bj + 1]) {
              const int type = block_type_[bj * (kRoads - 1) + bi];
              if (type == 2) m = static_cast<std::uint8_t>(GroundMaterial::kAsphalt);
              if (type == 3) m = static_cast<std::uint8_t>(GroundMaterial::kPavement);
            }
          }
        }
      }
      g.materials[r * (g.cols - 1) + c] = m;
    }
  }
}

WorldObject& Generator::Add(ObjectClass cls, const std::string& kind, Shape shape) {
  world_.objects.emplace_back();
  WorldObject& o = world_.objects.back();
  o.id = next_id_++;
  o.object_class = cls;
  o.kind = kind;
  o.shape = shape;
  o.sessions_mask = AllMask();
  return o;
}

void Generator::AddBox(ObjectClass cls, const std::string& kind, double x, double y, double yaw,
                       const Eigen::Vector3d& size, double reflectivity, double density,
                       std::uint64_t mask) {
  WorldObject& o = Add(cls, kind, Shape::kBox);
  o.position_m = Eigen::Vector3d(x, y, Ground(x, y) + 0.5 * size.z() - 0.1);
  o.yaw_rad = yaw;
  o.size_m = size;
  o.sessions_mask = mask;
  ObjectPart part;
  part.size_m = size;
  part.reflectivity = reflectivity;
  part.density_per_m = density;
  o.parts.push_back(part);
}

bool Generator::Free(double x0, double y0, double x1, double y1) {
  const Eigen::AlignedBox2d box(Eigen::Vector2d(x0, y0), Eigen::Vector2d(x1, y1));
  for (const Eigen::AlignedBox2d& b : occupied_) {
    if (b.intersects(box)) return false;
  }
  return true;
}

void Generator::MakeCurbs() {
  constexpr double kPiece = 4.0;
  constexpr double kGap = 9.0;  // no curb across the intersections
  auto curb_line = [&](Eigen::Vector2d a, Eigen::Vector2d b) {
    const double len = (b - a).norm();
    const Eigen::Vector2d dir = (b - a) / len;
    const Eigen::Vector2d left(-dir.y(), dir.x());
    const int pieces = std::max(1, static_cast<int>(std::round(len / kPiece)));
    const double piece = len / pieces;
    for (int side = -1; side <= 1; side += 2) {
      for (int k = 0; k < pieces; ++k) {
        const Eigen::Vector2d c =
            a + dir * (piece * (k + 0.5)) + left * (side * (kAsphaltHalf + 0.1));
        const Eigen::Vector2d p0 = c - dir * (0.5 * piece);
        const Eigen::Vector2d p1 = c + dir * (0.5 * piece);
        const Eigen::Vector2d q0 = c - left * 0.3;
        const Eigen::Vector2d q1 = c + left * 0.3;
        WorldObject& o = Add(ObjectClass::kTerrain, "curb", Shape::kBox);
        o.yaw_rad = std::atan2(dir.y(), dir.x());
        // Follow the slope: pitch along the curb, roll across it.
        o.pitch_rad = -std::atan2(Ground(p1.x(), p1.y()) - Ground(p0.x(), p0.y()), piece);
        o.roll_rad = std::atan2(Ground(q1.x(), q1.y()) - Ground(q0.x(), q0.y()), 0.6);
        // 0.15 m above the road, 0.15 m buried.
        o.position_m = Eigen::Vector3d(c.x(), c.y(), Ground(c.x(), c.y()));
        o.size_m = Eigen::Vector3d(piece, 0.2, 0.3);
        ObjectPart part;
        part.size_m = o.size_m;
        part.reflectivity = 0.35;
        o.parts.push_back(part);
      }
    }
  };
  for (int i = 0; i < kRoads; ++i) {
    for (int j = 0; j + 1 < kRoads; ++j) {
      curb_line({xs_[i], ys_[j] + kGap}, {xs_[i], ys_[j + 1] - kGap});
      curb_line({xs_[j] + kGap, ys_[i]}, {xs_[j + 1] - kGap, ys_[i]});
    }
  }
}

void Generator::AddTree(double x, double y, double scale) {
  const double trunk_h = rng_.Uniform(2.2, 3.5) * scale;
  const double trunk_d = rng_.Uniform(0.25, 0.45) * scale;
  const double rh = rng_.Uniform(2.0, 3.5) * scale;
  const double rv = rng_.Uniform(1.8, 3.2) * scale;
  const double g = Ground(x, y);
  WorldObject& trunk = Add(ObjectClass::kTrunk, "tree", Shape::kCylinder);
  trunk.position_m = Eigen::Vector3d(x, y, g + 0.5 * (trunk_h + rv) - 0.2);
  trunk.size_m = Eigen::Vector3d(trunk_d, trunk_d, trunk_h + rv + 0.4);
  ObjectPart tp;
  tp.shape = Shape::kCylinder;
  tp.size_m = trunk.size_m;
  tp.reflectivity = rng_.Uniform(0.2, 0.3);
  trunk.parts.push_back(tp);
  WorldObject& canopy = Add(ObjectClass::kCanopy, "tree", Shape::kEllipsoid);
  canopy.position_m = Eigen::Vector3d(x, y, g + trunk_h + 0.8 * rv);
  canopy.yaw_rad = rng_.Uniform(0.0, M_PI);
  canopy.size_m = Eigen::Vector3d(2 * rh, 2 * rh * rng_.Uniform(0.8, 1.0), 2 * rv);
  ObjectPart cp;
  cp.shape = Shape::kEllipsoid;
  cp.size_m = canopy.size_m;
  cp.density_per_m = rng_.Uniform(0.5, 1.3);
  cp.reflectivity = rng_.Uniform(0.15, 0.25);
  canopy.parts.push_back(cp);
}

void Generator::AddLampPost(double x, double y) {
  const double h = rng_.Uniform(5.0, 6.5);
  WorldObject& o = Add(ObjectClass::kPole, "lamp_post", Shape::kBox);
  o.position_m = Eigen::Vector3d(x, y, Ground(x, y) + 0.5 * h - 0.2);
  o.size_m = Eigen::Vector3d(0.8, 0.8, h + 0.4);
  ObjectPart pole;
  pole.shape = Shape::kCylinder;
  pole.size_m = Eigen::Vector3d(0.16, 0.16, h + 0.4);
  pole.reflectivity = 0.55;
  o.parts.push_back(pole);
  ObjectPart lamp;
  lamp.center_m = Eigen::Vector3d(0.0, 0.0, 0.5 * h + 0.05);
  lamp.size_m = Eigen::Vector3d(0.7, 0.35, 0.2);
  lamp.reflectivity = 0.6;
  o.parts.push_back(lamp);
}

void Generator::AddHedge(double x0, double y0, double x1, double y1, double height,
                         double width) {
  const Eigen::Vector2d a(x0, y0), b(x1, y1);
  const double len = (b - a).norm();
  if (len < 1.0) return;
  const int pieces = std::max(1, static_cast<int>(std::ceil(len / 6.0)));
  const Eigen::Vector2d dir = (b - a) / len;
  for (int k = 0; k < pieces; ++k) {
    const Eigen::Vector2d c = a + dir * (len * (k + 0.5) / pieces);
    const double g = Ground(c.x(), c.y());
    WorldObject& o = Add(ObjectClass::kHedge, "hedge", Shape::kBox);
    o.position_m = Eigen::Vector3d(c.x(), c.y(), g + 0.5 * (height - 0.4));
    o.yaw_rad = std::atan2(dir.y(), dir.x());
    o.size_m = Eigen::Vector3d(len / pieces, width, height + 0.4);
    ObjectPart part;
    part.size_m = o.size_m;
    part.density_per_m = 4.0;
    part.reflectivity = 0.15;
    o.parts.push_back(part);
  }
}

void Generator::AddWall(double x0, double y0, double x1, double y1, double height, bool fence) {
  const Eigen::Vector2d a(x0, y0), b(x1, y1);
  const double len = (b - a).norm();
  if (len < 1.0) return;
  const int pieces = std::max(1, static_cast<int>(std::ceil(len / 6.0)));
  const Eigen::Vector2d dir = (b - a) / len;
  for (int k = 0; k < pieces; ++k) {
    const double piece = len / pieces;
    const Eigen::Vector2d c = a + dir * (piece * (k + 0.5));
    const double g = Ground(c.x(), c.y());
    WorldObject& o = Add(ObjectClass::kWall, fence ? "fence" : "wall", Shape::kBox);
    o.position_m = Eigen::Vector3d(c.x(), c.y(), g + 0.5 * (height - 0.5));
    o.yaw_rad = std::atan2(dir.y(), dir.x());
    o.size_m = Eigen::Vector3d(piece, fence ? 0.12 : 0.3, height + 0.5);
    if (fence) {
      ObjectPart mesh;  // chain-link mesh: about half the rays pass
      mesh.size_m = Eigen::Vector3d(piece, 0.05, height + 0.5);
      mesh.density_per_m = 14.0;
      mesh.reflectivity = 0.4;
      o.parts.push_back(mesh);
      ObjectPart post;
      post.shape = Shape::kCylinder;
      post.center_m = Eigen::Vector3d(-0.5 * piece + 0.06, 0.0, 0.0);
      post.size_m = Eigen::Vector3d(0.08, 0.08, height + 0.5);
      post.reflectivity = 0.5;
      o.parts.push_back(post);
    } else {
      ObjectPart part;
      part.size_m = o.size_m;
      part.reflectivity = 0.35;
      o.parts.push_back(part);
    }
  }
}

void Generator::AddBuilding(double cx, double cy, double lx, double ly, double height,
                            double yaw) {
  double g_min = 1e9, g_max = -1e9;
  for (int a = -1; a <= 1; ++a) {
    for (int b = -1; b <= 1; ++b) {
      const double x = cx + a * 0.5 * (lx * std::cos(yaw)) - b * 0.5 * (ly * std::sin(yaw));
      const double y = cy + a * 0.5 * (lx * std::sin(yaw)) + b * 0.5 * (ly * std::cos(yaw));
      g_min = std::min(g_min, Ground(x, y));
      g_max = std::max(g_max, Ground(x, y));
    }
  }
  const double z0 = g_min - 0.5;
  const double z1 = g_max + height;
  const double zc = 0.5 * (z0 + z1);
  const double hz = z1 - z0;
  constexpr double kRelief = 0.3;
  WorldObject& o = Add(ObjectClass::kBuilding, "building", Shape::kBox);
  o.position_m = Eigen::Vector3d(cx, cy, zc);
  o.yaw_rad = yaw;
  o.size_m = Eigen::Vector3d(lx + 2 * kRelief, ly + 2 * kRelief, hz);
  const double refl = rng_.Uniform(0.25, 0.5);
  ObjectPart main;
  main.size_m = Eigen::Vector3d(lx, ly, hz);
  main.reflectivity = refl;
  o.parts.push_back(main);
  // Facade relief: pilasters and floor bands on all four sides.
  const double spacing = rng_.Uniform(3.5, 6.0);
  const int floors = std::max(1, static_cast<int>(height / 3.5));
  for (int side = 0; side < 4; ++side) {
    const bool along_x = side < 2;  // facades at +-ly/2 run along x
    const double sign = (side % 2 == 0) ? 1.0 : -1.0;
    const double facade_len = along_x ? lx : ly;
    const double offset = 0.5 * (along_x ? ly : lx) + 0.5 * kRelief;
    const int pilasters = static_cast<int>(facade_len / spacing);
    for (int k = 1; k < pilasters; ++k) {
      const double u = -0.5 * facade_len + facade_len * k / pilasters;
      ObjectPart p;
      p.center_m = along_x ? Eigen::Vector3d(u, sign * offset, 0.0)
                           : Eigen::Vector3d(sign * offset, u, 0.0);
      p.size_m = along_x ? Eigen::Vector3d(0.5, kRelief, hz) : Eigen::Vector3d(kRelief, 0.5, hz);
      p.reflectivity = refl + 0.05;
      o.parts.push_back(p);
    }
    for (int f = 1; f < floors; ++f) {
      const double z = (g_max + 3.5 * f) - zc;
      ObjectPart band;
      const double half_off = 0.5 * (along_x ? ly : lx) + 0.1;
      band.center_m = along_x ? Eigen::Vector3d(0.0, sign * half_off, z)
                              : Eigen::Vector3d(sign * half_off, 0.0, z);
      band.size_m = along_x ? Eigen::Vector3d(lx, 0.2, 0.3) : Eigen::Vector3d(0.2, ly, 0.3);
      band.reflectivity = refl - 0.05;
      o.parts.push_back(band);
    }
  }
}

void Generator::MakeBlocks() {
  for (int bj = 0; bj + 1 < kRoads; ++bj) {
    for (int bi = 0; bi + 1 < kRoads; ++bi) {
      const int type = block_type_[bj * (kRoads - 1) + bi];
      const double x0 = xs_[bi] + kBlockMargin, x1 = xs_[bi + 1] - kBlockMargin;
      const double y0 = ys_[bj] + kBlockMargin, y1 = ys_[bj + 1] - kBlockMargin;
      const double w = x1 - x0, h = y1 - y0;
      if (w < 5.0 || h < 5.0) continue;
      if (type == 0 || type == 4) {
        // Buildings: one per quadrant (or one for the courtyard block).
        const int q = type == 4 ? 1 : 2;
        for (int qa = 0; qa < q; ++qa) {
          for (int qb = 0; qb < q; ++qb) {
            if (type == 0 && !rng_.Bernoulli(0.75)) continue;
            const double qx0 = x0 + w * qa / q + 3.0, qx1 = x0 + w * (qa + 1) / q - 3.0;
            const double qy0 = y0 + h * qb / q + 3.0, qy1 = y0 + h * (qb + 1) / q - 3.0;
            if (qx1 - qx0 < 5.0 || qy1 - qy0 < 5.0) continue;  // too narrow for a building
            const double lx = (qx1 - qx0) * rng_.Uniform(0.55, 0.9);
            const double ly = (qy1 - qy0) * rng_.Uniform(0.55, 0.9);
            const double cx = rng_.Uniform(qx0 + 0.5 * lx, qx1 - 0.5 * lx);
            const double cy = rng_.Uniform(qy0 + 0.5 * ly, qy1 - 0.5 * ly);
            const double height = type == 4 ? rng_.Uniform(6.0, 9.0) : rng_.Uniform(6.0, 24.0);
            AddBuilding(cx, cy, lx, ly, height, 0.0);
            Occupy(cx - 0.5 * lx - 1, cy - 0.5 * ly - 1, cx + 0.5 * lx + 1, cy + 0.5 * ly + 1);
          }
        }
        if (rng_.Bernoulli(0.5)) AddHedge(x0 + 1, y0 + 0.5, x1 - 1, y0 + 0.5, 1.2, 1.0);
      } else if (type == 2) {
        // Parking lot: rows of perpendicular slots along x, lamp posts between rows.
        for (double yy = y0 + 4.0; yy + 5.0 < y1; yy += 16.0) {
          for (double xx = x0 + 2.0; xx + 2.5 < x1; xx += 2.7) {
            const double yaw = M_PI / 2 * (rng_.Bernoulli(0.5) ? 1 : -1);
            parking_slots_.push_back({xx + 1.25, yy + 2.5, yaw, 0});
          }
          Occupy(x0, yy, x1, yy + 5.0);
          if (yy + 11.0 < y1) AddLampPost(0.5 * (x0 + x1), yy + 10.5);
        }
      } else if (type == 3) {
        // Plaza: low walls, a fence, trees in a ring.
        AddWall(x0 + 2, y1 - 2, x1 - 2, y1 - 2, 1.0, false);
        AddWall(x0 + 2, y0 + 2, x0 + 2, y1 - 6, 2.0, true);
        const Eigen::Vector2d c(0.5 * (x0 + x1), 0.5 * (y0 + y1));
        for (int k = 0; k < 6; ++k) {
          const double a = k * M_PI / 3.0;
          AddTree(c.x() + 12 * std::cos(a), c.y() + 12 * std::sin(a), 0.9);
        }
        Occupy(c.x() - 16, c.y() - 16, c.x() + 16, c.y() + 16);
      }
      // Trees scattered in the free space (parks get many).
      const int trees = static_cast<int>(w * h / (type == 1 ? 120.0 : 900.0));
      for (int k = 0; k < trees; ++k) {
        const double tx = rng_.Uniform(x0 + 2, x1 - 2);
        const double ty = rng_.Uniform(y0 + 2, y1 - 2);
        if (!Free(tx - 2.5, ty - 2.5, tx + 2.5, ty + 2.5)) continue;
        Occupy(tx - 2.5, ty - 2.5, tx + 2.5, ty + 2.5);
        AddTree(tx, ty, rng_.Uniform(0.8, 1.3));
      }
      if (type == 1) {
        // Park hedges and a wall along one edge.
        AddHedge(x0 + 1, y1 - 0.5, 0.5 * (x0 + x1), y1 - 0.5, 1.0, 0.9);
        AddWall(x1 - 0.5, y0 + 1, x1 - 0.5, y1 - 1, rng_.Uniform(1.5, 2.5), rng_.Bernoulli(0.5));
      }
    }
  }
}

void Generator::MakeStreetFurniture() {
  // Lamp posts on the sidewalks, street trees on some roads.
  for (int axis = 0; axis < 2; ++axis) {
    for (int i = 0; i < kRoads; ++i) {
      for (int j = 0; j + 1 < kRoads; ++j) {
        const double a = (axis == 0 ? ys_[j] : xs_[j]) + 12.0;
        const double b = (axis == 0 ? ys_[j + 1] : xs_[j + 1]) - 12.0;
        const double c = axis == 0 ? xs_[i] : ys_[i];
        auto at = [&](double along, double across) {
          return axis == 0 ? Eigen::Vector2d(c + across, along)
                           : Eigen::Vector2d(along, c + across);
        };
        int side = rng_.Bernoulli(0.5) ? 1 : -1;
        for (double u = a; u <= b; u += rng_.Uniform(25.0, 35.0)) {
          const Eigen::Vector2d p = at(u, side * 7.4);
          AddLampPost(p.x(), p.y());
          side = -side;
        }
        if (rng_.Bernoulli(0.5)) {
          const int tside = rng_.Bernoulli(0.5) ? 1 : -1;
          for (double u = a + 5.0; u <= b; u += rng_.Uniform(11.0, 16.0)) {
            const Eigen::Vector2d p = at(u, tside * 10.0);
            if (!Free(p.x() - 1.5, p.y() - 1.5, p.x() + 1.5, p.y() + 1.5)) continue;
            Occupy(p.x() - 1.5, p.y() - 1.5, p.x() + 1.5, p.y() + 1.5);
            AddTree(p.x(), p.y(), rng_.Uniform(0.9, 1.2));
          }
        }
        if (rng_.Bernoulli(0.25)) {
          // A fence or wall along the block edge behind the sidewalk.
          const int wside = rng_.Bernoulli(0.5) ? 1 : -1;
          const Eigen::Vector2d p0 = at(a + 4.0, wside * 8.6);
          const Eigen::Vector2d p1 = at(b - 4.0, wside * 8.6);
          AddWall(p0.x(), p0.y(), p1.x(), p1.y(), rng_.Uniform(1.2, 2.2), rng_.Bernoulli(0.5));
        }
        // Parallel parking slots on the road's strip.
        for (int pside = -1; pside <= 1; pside += 2) {
          if (!rng_.Bernoulli(0.55)) continue;
          const double yaw = axis == 0 ? (pside > 0 ? M_PI / 2 : -M_PI / 2)
                                       : (pside > 0 ? M_PI : 0.0);
          for (double u = a + 3.0; u + 6.0 <= b; u += 6.2) {
            const Eigen::Vector2d p = at(u + 3.0, pside * 4.5);
            parking_slots_.push_back({p.x(), p.y(), yaw, 0});
          }
        }
      }
    }
  }
}

void Generator::AddCar(double x, double y, double yaw, std::uint64_t mask, ObjectClass cls,
                       CounterRng* rng) {
  const bool van = rng->Bernoulli(0.12);
  const double l = van ? rng->Uniform(4.9, 5.4) : rng->Uniform(4.0, 4.9);
  const double w = van ? rng->Uniform(1.9, 2.05) : rng->Uniform(1.7, 1.9);
  const double h = van ? rng->Uniform(1.9, 2.2) : rng->Uniform(1.4, 1.6);
  WorldObject& o = Add(cls, van ? "van" : "car", Shape::kBox);
  o.position_m = Eigen::Vector3d(x, y, Ground(x, y) + 0.5 * h);
  o.yaw_rad = yaw;
  o.size_m = Eigen::Vector3d(l, w, h);
  o.sessions_mask = mask;
  const double paint = rng->Uniform(0.08, 0.6);
  const double body_h = van ? h - 0.3 : 0.62;
  ObjectPart body;  // lower body, above the ground clearance
  body.center_m = Eigen::Vector3d(0.0, 0.0, -0.5 * h + 0.28 + 0.5 * body_h);
  body.size_m = Eigen::Vector3d(l, w, body_h);
  body.reflectivity = paint;
  o.parts.push_back(body);
  const double cabin_h = h - 0.28 - body_h;
  if (cabin_h > 0.05) {
    ObjectPart cabin;  // narrower, shorter greenhouse: the rounded silhouette
    cabin.center_m = Eigen::Vector3d(-0.06 * l, 0.0, 0.5 * h - 0.5 * cabin_h);
    cabin.size_m = Eigen::Vector3d(0.55 * l, 0.9 * w, cabin_h);
    cabin.reflectivity = 0.1;  // mostly glass
    o.parts.push_back(cabin);
  }
  for (int k = 0; k < 4; ++k) {
    ObjectPart wheel;
    wheel.shape = Shape::kCylinder;
    wheel.center_m = Eigen::Vector3d((k < 2 ? 0.33 : -0.33) * l, (k % 2 ? 0.5 : -0.5) * (w - 0.22),
                                     -0.5 * h + 0.32);
    wheel.rpy_rad = Eigen::Vector3d(M_PI / 2, 0.0, 0.0);
    wheel.size_m = Eigen::Vector3d(0.64, 0.64, 0.22);
    wheel.reflectivity = 0.05;
    o.parts.push_back(wheel);
  }
}

void Generator::MakeParking() {
  const int n = static_cast<int>(world_.session_names.size());
  for (std::size_t k = 0; k < parking_slots_.size(); ++k) {
    const auto& slot = parking_slots_[k];
    CounterRng rng(MakeKey(config_.seed, 0x5107, k));
    const double jx = rng.Uniform(-0.25, 0.25), jy = rng.Uniform(-0.15, 0.15);
    const double x = slot[0] + jx * std::cos(slot[2]) - jy * std::sin(slot[2]);
    const double y = slot[1] + jx * std::sin(slot[2]) + jy * std::cos(slot[2]);
    if (rng.Bernoulli(config_.always_parked_fraction)) {
      AddCar(x, y, slot[2] + rng.Uniform(-0.03, 0.03), AllMask(), ObjectClass::kParkedCar, &rng);
      continue;
    }
    // A changing slot: per session a car or none; a car may stay for consecutive sessions.
    std::uint64_t current = 0;
    for (int s = 0; s < n; ++s) {
      const bool occupied = rng.Bernoulli(config_.parked_car_density);
      const bool stays = current != 0 && occupied && rng.Bernoulli(0.3);
      if (!occupied || !stays) {
        if (current != 0) {
          const double yaw =
              slot[2] + (rng.Bernoulli(0.15) ? M_PI : 0.0) + rng.Uniform(-0.05, 0.05);
          AddCar(x + rng.Uniform(-0.3, 0.3), y + rng.Uniform(-0.15, 0.15), yaw, current,
                 ObjectClass::kParkedCar, &rng);
        }
        current = occupied ? (1ULL << s) : 0;
      } else {
        current |= 1ULL << s;
      }
    }
    if (current != 0) {
      AddCar(x, y, slot[2] + rng.Uniform(-0.05, 0.05), current, ObjectClass::kParkedCar, &rng);
    }
  }
}

void Generator::MakeMovables() {
  const double d = config_.movable_density;
  // Bins near the intersections' sidewalks; construction fences and trucks on the roads' edges.
  for (int i = 0; i < kRoads; ++i) {
    for (int j = 0; j < kRoads; ++j) {
      if (!rng_.Bernoulli(std::min(1.0, 0.35 * d))) continue;
      const double x = xs_[i] + (rng_.Bernoulli(0.5) ? 1 : -1) * rng_.Uniform(9.5, 14.0);
      const double y = ys_[j] + (rng_.Bernoulli(0.5) ? 1 : -1) * 7.0;
      const std::uint64_t mask = ChangingMask(0.5);
      const int count = rng_.UniformInt(1, 3);
      for (int k = 0; k < count; ++k) {
        WorldObject& o = Add(ObjectClass::kMovable, "bin", Shape::kCylinder);
        o.position_m = Eigen::Vector3d(x + 0.8 * k, y, Ground(x + 0.8 * k, y) + 0.5);
        o.size_m = Eigen::Vector3d(0.65, 0.65, 1.0);
        o.sessions_mask = mask;
        ObjectPart p;
        p.shape = Shape::kCylinder;
        p.size_m = o.size_m;
        p.reflectivity = 0.3;
        o.parts.push_back(p);
      }
    }
  }
  const int fences = static_cast<int>(std::round(8 * d));
  for (int k = 0; k < fences; ++k) {
    // Along a road, on the sidewalk: 2-4 porous panels.
    const bool vertical = rng_.Bernoulli(0.5);
    const int i = rng_.UniformInt(0, kRoads - 1), j = rng_.UniformInt(0, kRoads - 2);
    const double u = rng_.Uniform(0.25, 0.75);
    const double side = rng_.Bernoulli(0.5) ? 1 : -1;
    const int panels = rng_.UniformInt(2, 4);
    const std::uint64_t mask = ChangingMask(0.4);
    for (int p = 0; p < panels; ++p) {
      double x, y, yaw;
      if (vertical) {
        x = xs_[i] + side * 6.6;
        y = ys_[j] + u * (ys_[j + 1] - ys_[j]) + 3.6 * p;
        yaw = M_PI / 2;
      } else {
        x = xs_[j] + u * (xs_[j + 1] - xs_[j]) + 3.6 * p;
        y = ys_[i] + side * 6.6;
        yaw = 0.0;
      }
      AddBox(ObjectClass::kMovable, "construction_fence", x, y, yaw,
             Eigen::Vector3d(3.5, 0.08, 2.0), 0.45, 10.0, mask);
    }
  }
  const int trucks = static_cast<int>(std::round(5 * d));
  for (int k = 0; k < trucks && !parking_slots_.empty(); ++k) {
    // A truck parked in the parking strip, half a slot further out than cars.
    const bool vertical = rng_.Bernoulli(0.5);
    const int i = rng_.UniformInt(0, kRoads - 1), j = rng_.UniformInt(0, kRoads - 2);
    const double u = rng_.Uniform(0.3, 0.7);
    const double side = rng_.Bernoulli(0.5) ? 1 : -1;
    double x, y, yaw;
    if (vertical) {
      x = xs_[i] + side * 11.5;
      y = ys_[j] + u * (ys_[j + 1] - ys_[j]);
      yaw = M_PI / 2;
    } else {
      x = xs_[j] + u * (xs_[j + 1] - xs_[j]);
      y = ys_[i] + side * 11.5;
      yaw = 0.0;
    }
    const double hx = vertical ? 1.5 : 4.2, hy = vertical ? 4.2 : 1.5;
    if (!Free(x - hx, y - hy, x + hx, y + hy)) continue;
    Occupy(x - hx, y - hy, x + hx, y + hy);
    const std::uint64_t mask = ChangingMask(0.4);
    WorldObject& o = Add(ObjectClass::kMovable, "truck", Shape::kBox);
    o.position_m = Eigen::Vector3d(x, y, Ground(x, y) + 1.6);
    o.yaw_rad = yaw;
    o.size_m = Eigen::Vector3d(8.0, 2.5, 3.2);
    o.sessions_mask = mask;
    ObjectPart cargo;
    cargo.center_m = Eigen::Vector3d(-1.0, 0.0, 0.15);
    cargo.size_m = Eigen::Vector3d(6.0, 2.5, 2.9);
    cargo.reflectivity = 0.5;
    o.parts.push_back(cargo);
    ObjectPart cab;
    cab.center_m = Eigen::Vector3d(3.0, 0.0, -0.2);
    cab.size_m = Eigen::Vector3d(2.0, 2.4, 2.4);
    cab.reflectivity = 0.3;
    o.parts.push_back(cab);
  }
}

core::Status Generator::MakeRoutes() {
  const int n = static_cast<int>(world_.session_names.size());
  RobotTrajectoryConfig robot = config_.robot;
  robot.cruise_speed_mps =
      config_.cruise_speed_mps > 0.0 ? config_.cruise_speed_mps : spec_.cruise_mps;
  for (int s = 0; s < n; ++s) {
    std::vector<Node> nodes = RoutePattern(config_.profile, s % 3);
    if ((s / 3) % 2 == 1) std::reverse(nodes.begin(), nodes.end());
    std::vector<Eigen::Vector2d> waypoints;
    for (const Node& node : nodes) waypoints.push_back(NodeXY(node));
    const double start = config_.base_stamp_s + s * config_.session_spacing_s;
    auto traj = RobotTrajectory::Create(robot, waypoints, *terrain_, start);
    if (!traj.ok()) {
      return core::Status::Error("route of session " + SessionName(s) + ": " +
                                 traj.status().message());
    }
    trajectories_.push_back(std::move(traj).value());
  }
  return core::Status::Ok();
}

std::vector<Node> Generator::RandomWalk(int nodes, CounterRng* rng) {
  std::vector<Node> walk;
  int i = rng->UniformInt(0, kRoads - 1), j = rng->UniformInt(0, kRoads - 1);
  int pi = -1, pj = -1;
  walk.push_back({static_cast<double>(i), static_cast<double>(j)});
  for (int k = 1; k < nodes; ++k) {
    std::vector<std::array<int, 2>> next;
    const int di[4] = {1, -1, 0, 0}, dj[4] = {0, 0, 1, -1};
    for (int d = 0; d < 4; ++d) {
      const int ni = i + di[d], nj = j + dj[d];
      if (ni < 0 || nj < 0 || ni >= kRoads || nj >= kRoads || (ni == pi && nj == pj)) continue;
      next.push_back({ni, nj});
    }
    const auto& choice = next[rng->UniformInt(0, static_cast<int>(next.size()) - 1)];
    pi = i;
    pj = j;
    i = choice[0];
    j = choice[1];
    walk.push_back({static_cast<double>(i), static_cast<double>(j)});
  }
  return walk;
}

void Generator::AddMover(ObjectClass cls, int session, const RoadPath& path, double s0,
                         double speed, double offset, double t_begin, double t_end,
                         double t_ref, CounterRng* rng) {
  // Position at time t: arc length s0 + speed * (t - t_ref) along `path` (speed < 0: against
  // the path's direction), `offset` to the right of the path.
  std::vector<TrajectoryRow> rows;
  constexpr double kDt = 0.2;
  // Only while the session records.
  t_begin = std::max(t_begin, trajectories_[session].start_stamp_s());
  t_end = std::min(t_end, trajectories_[session].end_stamp_s());
  const double t0 = std::ceil(t_begin / kDt) * kDt;
  const bool car = cls == ObjectClass::kMovingCar;
  const double half_h = car ? 0.75 : 0.875;
  for (double t = t0; t <= t_end + 1e-9; t += kDt) {
    const double s = s0 + speed * (t - t_ref);
    if (s < 0.0 || s > path.length_m()) {
      if (!rows.empty()) break;
      continue;
    }
    Eigen::Vector2d tangent;
    const Eigen::Vector2d p = path.Point(s, offset, &tangent);
    if (speed < 0.0) tangent = -tangent;
    TrajectoryRow row;
    row.stamp_s = std::round(t * 1e6) / 1e6;
    row.position_m = Eigen::Vector3d(p.x(), p.y(), Ground(p.x(), p.y()) + half_h);
    row.yaw_rad = std::atan2(tangent.y(), tangent.x());
    rows.push_back(row);
  }
  if (rows.size() < 2) return;
  if (car) {
    AddCar(rows[0].position_m.x(), rows[0].position_m.y(), rows[0].yaw_rad, 1ULL << session,
           ObjectClass::kMovingCar, rng);
    WorldObject& o = world_.objects.back();
    for (TrajectoryRow& row : rows) {
      row.position_m.z() = Ground(row.position_m.x(), row.position_m.y()) + 0.5 * o.size_m.z();
    }
    o.position_m = rows[0].position_m;
    o.trajectory = std::move(rows);
    return;
  }
  WorldObject& o = Add(ObjectClass::kPedestrian, "pedestrian", Shape::kCylinder);
  const double height = rng->Uniform(1.55, 1.9);
  o.size_m = Eigen::Vector3d(0.5, 0.5, height);
  o.sessions_mask = 1ULL << session;
  for (TrajectoryRow& row : rows) row.position_m.z() += 0.5 * height - half_h;
  o.position_m = rows[0].position_m;
  o.yaw_rad = rows[0].yaw_rad;
  ObjectPart body;
  body.shape = Shape::kCylinder;
  body.center_m = Eigen::Vector3d(0.0, 0.0, -0.12);
  body.size_m = Eigen::Vector3d(0.46, 0.46, height - 0.24);
  body.reflectivity = rng->Uniform(0.1, 0.5);
  o.parts.push_back(body);
  ObjectPart head;
  head.shape = Shape::kEllipsoid;
  head.center_m = Eigen::Vector3d(0.0, 0.0, 0.5 * height - 0.13);
  head.size_m = Eigen::Vector3d(0.2, 0.2, 0.26);
  head.reflectivity = 0.3;
  o.parts.push_back(head);
  o.trajectory = std::move(rows);
}

core::Status Generator::MakeMovers() {
  const double d = config_.moving_object_density;
  auto count = [d](int base) { return static_cast<int>(std::round(base * d)); };
  for (std::size_t s = 0; s < trajectories_.size(); ++s) {
    const RobotTrajectory& robot = trajectories_[s];
    const double t0 = robot.start_stamp_s(), t1 = robot.end_stamp_s();
    const int session = static_cast<int>(s);
    CounterRng rng(MakeKey(config_.seed, 0x30E5, s));
    // Background traffic on the road grid.
    for (int k = 0; k < count(spec_.background_cars) + count(spec_.background_pedestrians); ++k) {
      const bool car = k < count(spec_.background_cars);
      const double speed = car ? rng.Uniform(5.0, 8.0) : rng.Uniform(1.1, 1.6);
      const int nodes = std::max(3, static_cast<int>((t1 - t0) * speed / 80.0) + 2);
      std::vector<Eigen::Vector2d> waypoints;
      for (const Node& node : RandomWalk(nodes, &rng)) waypoints.push_back(NodeXY(node));
      auto path = RoadPath::Create(waypoints, car ? 8.0 : 10.0, 0.2);
      if (!path.ok()) return path.status();
      const double offset = car ? kCarLaneOffset : (rng.Bernoulli(0.5) ? 1 : -1) * kSidewalkOffset;
      AddMover(car ? ObjectClass::kMovingCar : ObjectClass::kPedestrian, session, path.value(),
               rng.Uniform(0.0, 50.0), speed, offset, t0, t1, t0, &rng);
    }
    // Encounters: movers along the robot's own road, timed to pass it closely.
    const RoadPath& route = robot.path();
    const int walkers = count(spec_.encounter_pedestrians);
    for (int k = 0; k < walkers; ++k) {
      const double te = t0 + (t1 - t0) * (k + rng.Uniform(0.2, 0.8)) / walkers;
      const double se = robot.ArcLength(te);
      const double speed = rng.Uniform(1.0, 1.6) * (rng.Bernoulli(0.6) ? -1.0 : 1.0);
      const double offsets[4] = {kSidewalkOffset, -kSidewalkOffset, 4.0, -1.2};
      const double offset = offsets[rng.UniformInt(0, 3)];
      AddMover(ObjectClass::kPedestrian, session, route, se + (speed > 0 ? 6.0 : 0.0), speed,
               offset, te - 30.0, te + 30.0, te, &rng);
    }
    const int cars = count(spec_.encounter_cars);
    for (int k = 0; k < cars; ++k) {
      const double te = t0 + (t1 - t0) * (k + rng.Uniform(0.2, 0.8)) / cars;
      const double se = robot.ArcLength(te);
      // Oncoming in the other lane, or overtaking in it.
      const double speed = rng.Bernoulli(0.7) ? -rng.Uniform(5.0, 8.0) : rng.Uniform(4.0, 5.0);
      AddMover(ObjectClass::kMovingCar, session, route, se, speed, -kCarLaneOffset, te - 25.0,
               te + 25.0, te, &rng);
    }
    const int crossers = count(spec_.crossing_pedestrians);
    for (int k = 0; k < crossers; ++k) {
      const double te = t0 + (t1 - t0) * (k + rng.Uniform(0.2, 0.8)) / crossers;
      const double ahead = rng.Uniform(6.0, 12.0);
      const double s_cross = robot.ArcLength(te) + ahead;
      Eigen::Vector2d tangent;
      const Eigen::Vector2d c = route.Point(s_cross, 0.0, &tangent);
      const Eigen::Vector2d right(tangent.y(), -tangent.x());
      const double dir = rng.Bernoulli(0.5) ? 1.0 : -1.0;
      const double speed = rng.Uniform(1.1, 1.5);
      // Crosses the centreline about two seconds before the robot gets there.
      const double t_centre = te + ahead / std::max(robot.Speed(te), 0.5) - 2.0;
      const Eigen::Vector2d a = c - right * dir * 9.0;
      const Eigen::Vector2d b = c + right * dir * 9.0;
      auto crossing = RoadPath::Create({a, b}, 1.0, 0.2);
      if (!crossing.ok()) return crossing.status();
      AddMover(ObjectClass::kPedestrian, session, crossing.value(), 9.0, speed, 0.0,
               t_centre - 9.0 / speed, t_centre + 9.0 / speed, t_centre, &rng);
    }
  }
  return core::Status::Ok();
}

core::StatusOr<Campus> Generator::Run() {
  world_.profile = config_.profile;
  world_.seed = config_.seed;
  for (int s = 0; s < config_.num_sessions; ++s) world_.session_names.push_back(SessionName(s));
  MakeRoads();
  block_type_.resize((kRoads - 1) * (kRoads - 1));
  for (int k = 0; k < static_cast<int>(block_type_.size()); ++k) {
    const double u = rng_.Uniform();
    block_type_[k] = u < 0.45 ? 0 : u < 0.7 ? 1 : u < 0.85 ? 2 : 3;
  }
  block_type_[2 * (kRoads - 1) + 2] = 4;  // the small central block: a courtyard building
  core::Status status = MakeTerrain();
  if (!status.ok()) return status;
  MakeCurbs();
  MakeBlocks();
  MakeStreetFurniture();
  MakeMovables();
  MakeParking();
  status = MakeRoutes();
  if (!status.ok()) return status;
  status = MakeMovers();
  if (!status.ok()) return status;
  status = world_.Validate();
  if (!status.ok()) return status;
  Campus campus;
  campus.world = std::move(world_);
  campus.trajectories = std::move(trajectories_);
  return campus;
}

}  // namespace

std::string SessionName(int index) {
  char buffer[16];
  std::snprintf(buffer, sizeof(buffer), "s%02d", index);
  return buffer;
}

core::Status CampusConfig::Validate() const {
  if (profile != "campus" && profile != "small" && profile != "tiny") {
    return core::Status::Error("profile must be campus, small or tiny, got '" + profile + "'");
  }
  if (num_sessions < 1 || num_sessions > 64) {
    return core::Status::Error("sessions must be in [1, 64], got " +
                               std::to_string(num_sessions));
  }
  auto fraction = [](double v) { return std::isfinite(v) && v >= 0.0 && v <= 1.0; };
  if (!fraction(parked_car_density) || !fraction(always_parked_fraction)) {
    return core::Status::Error("parked car densities must be in [0, 1]");
  }
  if (!(movable_density >= 0.0 && movable_density <= 10.0) ||
      !(moving_object_density >= 0.0 && moving_object_density <= 10.0)) {
    return core::Status::Error("movable/moving object densities must be in [0, 10]");
  }
  if (!(cruise_speed_mps >= 0.0 && cruise_speed_mps <= 10.0)) {
    return core::Status::Error("cruise_speed_mps must be in [0, 10] (0: profile default)");
  }
  if (!std::isfinite(base_stamp_s) || base_stamp_s <= 0.0 || !(session_spacing_s > 0.0)) {
    return core::Status::Error("base_stamp_s and session_spacing_s must be > 0");
  }
  RobotTrajectoryConfig robot_check = robot;
  if (cruise_speed_mps > 0.0) robot_check.cruise_speed_mps = cruise_speed_mps;
  robot_check.cruise_speed_mps = std::max(robot_check.cruise_speed_mps, robot.end_speed_mps);
  return robot_check.Validate();
}

core::StatusOr<Campus> GenerateCampus(const CampusConfig& config) {
  core::Status status = config.Validate();
  if (!status.ok()) return status;
  Generator generator(config);
  return generator.Run();
}

}  // namespace sim
}  // namespace multisession_mapper
