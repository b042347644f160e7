#include "multisession_mapper/sim/primitive.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "multisession_mapper/sim/counter_rng.h"

namespace multisession_mapper {
namespace sim {
namespace {

constexpr std::array<const char*, kNumObjectClasses> kClassNames = {
    "terrain", "building",   "wall",        "pole",    "hedge",     "trunk",
    "canopy",  "parked_car", "movable",     "moving_car", "pedestrian"};
constexpr std::array<const char*, 3> kShapeNames = {"box", "cylinder", "ellipsoid"};
constexpr double kInf = std::numeric_limits<double>::infinity();

// Ray in the primitive's local frame (direction keeps unit length: rotation only).
void ToLocal(const Primitive& p, const Ray& ray, Eigen::Vector3d* o, Eigen::Vector3d* d) {
  const Eigen::Matrix3d rt = p.pose.linear().transpose();
  *o = rt * (ray.origin - p.pose.translation());
  *d = rt * ray.direction;
}

bool SlabInterval(const Eigen::Vector3d& o, const Eigen::Vector3d& d, const Eigen::Vector3d& h,
                  double* t0, double* t1) {
  double lo = -kInf;
  double hi = kInf;
  for (int i = 0; i < 3; ++i) {
    if (std::abs(d[i]) < 1e-12) {
      if (o[i] < -h[i] || o[i] > h[i]) return false;
      continue;
    }
    const double inv = 1.0 / d[i];
    double a = (-h[i] - o[i]) * inv;
    double b = (h[i] - o[i]) * inv;
    if (a > b) std::swap(a, b);
    lo = std::max(lo, a);
    hi = std::min(hi, b);
    if (lo > hi) return false;
  }
  *t0 = lo;
  *t1 = hi;
  return true;
}

bool CylinderInterval(const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                      const Eigen::Vector3d& h, double* t0, double* t1) {
  const double r = h.x();
  double lo = -kInf;
  double hi = kInf;
  const double a = d.x() * d.x() + d.y() * d.y();
  const double c = o.x() * o.x() + o.y() * o.y() - r * r;
  if (a < 1e-14) {
    if (c > 0.0) return false;
  } else {
    const double b = o.x() * d.x() + o.y() * d.y();
    const double disc = b * b - a * c;
    if (disc < 0.0) return false;
    const double s = std::sqrt(disc);
    lo = (-b - s) / a;
    hi = (-b + s) / a;
  }
  if (std::abs(d.z()) < 1e-12) {
    if (o.z() < -h.z() || o.z() > h.z()) return false;
  } else {
    double za = (-h.z() - o.z()) / d.z();
    double zb = (h.z() - o.z()) / d.z();
    if (za > zb) std::swap(za, zb);
    lo = std::max(lo, za);
    hi = std::min(hi, zb);
  }
  if (lo > hi) return false;
  *t0 = lo;
  *t1 = hi;
  return true;
}

bool EllipsoidInterval(const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                       const Eigen::Vector3d& h, double* t0, double* t1) {
  const Eigen::Vector3d os = o.cwiseQuotient(h);
  const Eigen::Vector3d ds = d.cwiseQuotient(h);
  const double a = ds.squaredNorm();
  const double b = os.dot(ds);
  const double c = os.squaredNorm() - 1.0;
  const double disc = b * b - a * c;
  if (disc < 0.0 || a <= 0.0) return false;
  const double s = std::sqrt(disc);
  *t0 = (-b - s) / a;
  *t1 = (-b + s) / a;
  return true;
}

}  // namespace

const char* ObjectClassName(ObjectClass object_class) {
  const int i = static_cast<int>(object_class);
  return (i >= 0 && i < kNumObjectClasses) ? kClassNames[i] : "unknown";
}

core::StatusOr<ObjectClass> ParseObjectClass(const std::string& name) {
  for (int i = 0; i < kNumObjectClasses; ++i) {
    if (name == kClassNames[i]) return static_cast<ObjectClass>(i);
  }
  return core::Status::Error("unknown object class '" + name + "'");
}

const char* ShapeName(Shape shape) {
  const int i = static_cast<int>(shape);
  return (i >= 0 && i < 3) ? kShapeNames[i] : "unknown";
}

core::StatusOr<Shape> ParseShape(const std::string& name) {
  for (int i = 0; i < 3; ++i) {
    if (name == kShapeNames[i]) return static_cast<Shape>(i);
  }
  return core::Status::Error("unknown shape '" + name + "'");
}

bool IntersectInterval(const Primitive& primitive, const Ray& ray, double* t_enter,
                       double* t_exit) {
  Eigen::Vector3d o;
  Eigen::Vector3d d;
  ToLocal(primitive, ray, &o, &d);
  bool hit = false;
  switch (primitive.shape) {
    case Shape::kBox:
      hit = SlabInterval(o, d, primitive.half_size_m, t_enter, t_exit);
      break;
    case Shape::kCylinder:
      hit = CylinderInterval(o, d, primitive.half_size_m, t_enter, t_exit);
      break;
    case Shape::kEllipsoid:
      hit = EllipsoidInterval(o, d, primitive.half_size_m, t_enter, t_exit);
      break;
  }
  return hit && *t_exit >= 0.0;
}

double HitDistance(const Primitive& primitive, const Ray& ray, double t_min, double t_max,
                   std::uint64_t key) {
  double t0 = 0.0;
  double t1 = 0.0;
  if (!IntersectInterval(primitive, ray, &t0, &t1)) return -1.0;
  if (primitive.density_per_m <= 0.0) {
    return (t0 >= t_min && t0 <= t_max) ? t0 : -1.0;
  }
  const double start = std::max(t0, t_min);
  const double end = std::min(t1, t_max);
  if (start >= end) return -1.0;
  const double u = UniformFromKey(MakeKey(key, primitive.object_id, 0x9A5E));
  const double depth = -std::log(1.0 - u) / primitive.density_per_m;
  const double t = std::max(t0, 0.0) + depth;
  // The depth is measured from where the ray enters the volume, so clipping [t_min, t_max]
  // (grid cells) does not change where the leaf is.
  return (t >= start && t <= end) ? t : -1.0;
}

Eigen::Vector3d SurfaceNormal(const Primitive& primitive, const Eigen::Vector3d& point_world) {
  const Eigen::Matrix3d rt = primitive.pose.linear().transpose();
  const Eigen::Vector3d p = rt * (point_world - primitive.pose.translation());
  const Eigen::Vector3d& h = primitive.half_size_m;
  Eigen::Vector3d n = Eigen::Vector3d::UnitZ();
  switch (primitive.shape) {
    case Shape::kBox: {
      int best = 0;
      double best_gap = kInf;
      for (int i = 0; i < 3; ++i) {
        const double gap = std::abs(h[i] - std::abs(p[i]));
        if (gap < best_gap) {
          best_gap = gap;
          best = i;
        }
      }
      n = Eigen::Vector3d::Zero();
      n[best] = p[best] >= 0.0 ? 1.0 : -1.0;
      break;
    }
    case Shape::kCylinder: {
      const double radial = std::hypot(p.x(), p.y());
      if (std::abs(h.z() - std::abs(p.z())) < std::abs(h.x() - radial) || radial < 1e-9) {
        n = Eigen::Vector3d(0.0, 0.0, p.z() >= 0.0 ? 1.0 : -1.0);
      } else {
        n = Eigen::Vector3d(p.x() / radial, p.y() / radial, 0.0);
      }
      break;
    }
    case Shape::kEllipsoid: {
      n = p.cwiseQuotient(h.cwiseProduct(h));
      if (n.norm() < 1e-12) n = Eigen::Vector3d::UnitZ();
      n.normalize();
      break;
    }
  }
  return primitive.pose.linear() * n;
}

double SignedDistance(const Primitive& primitive, const Eigen::Vector3d& point_world) {
  const Eigen::Matrix3d rt = primitive.pose.linear().transpose();
  const Eigen::Vector3d p = rt * (point_world - primitive.pose.translation());
  const Eigen::Vector3d& h = primitive.half_size_m;
  switch (primitive.shape) {
    case Shape::kBox: {
      const Eigen::Vector3d q = p.cwiseAbs() - h;
      return q.cwiseMax(0.0).norm() + std::min(q.maxCoeff(), 0.0);
    }
    case Shape::kCylinder: {
      const double dr = std::hypot(p.x(), p.y()) - h.x();
      const double dz = std::abs(p.z()) - h.z();
      return std::min(std::max(dr, dz), 0.0) + std::hypot(std::max(dr, 0.0), std::max(dz, 0.0));
    }
    case Shape::kEllipsoid: {
      const double k = p.cwiseQuotient(h).norm();
      if (k < 1e-12) return -h.minCoeff();
      // First-order estimate: (k - 1) scaled by the local gradient norm.
      const double k1 = p.cwiseQuotient(h.cwiseProduct(h)).norm();
      return k * (k - 1.0) / k1;
    }
  }
  return kInf;
}

Eigen::AlignedBox3d WorldBounds(const Primitive& primitive) {
  // |R| * h bounds the rotated box; it also bounds the cylinder and the ellipsoid.
  const Eigen::Vector3d extent = primitive.pose.linear().cwiseAbs() * primitive.half_size_m;
  const Eigen::Vector3d c = primitive.pose.translation();
  return Eigen::AlignedBox3d(c - extent, c + extent);
}

}  // namespace sim
}  // namespace multisession_mapper
