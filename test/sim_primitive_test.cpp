#include "multisession_mapper/sim/primitive.h"

#include <cmath>

#include <gtest/gtest.h>

#include "multisession_mapper/core/se3.h"

namespace multisession_mapper {
namespace sim {
namespace {

Ray MakeRay(const Eigen::Vector3d& o, const Eigen::Vector3d& d) {
  Ray r;
  r.origin = o;
  r.direction = d.normalized();
  return r;
}

Primitive Box(const Eigen::Vector3d& centre, const Eigen::Vector3d& half, double yaw = 0.0) {
  Primitive p;
  p.shape = Shape::kBox;
  p.pose = core::se3::FromXyzRpy(centre.x(), centre.y(), centre.z(), 0.0, 0.0, yaw);
  p.half_size_m = half;
  return p;
}

TEST(SimPrimitiveTest, AxisAlignedBoxEntryAndExit) {
  const Primitive box = Box({10, 0, 0}, {1, 2, 3});
  double t0, t1;
  ASSERT_TRUE(IntersectInterval(box, MakeRay({0, 0, 0}, {1, 0, 0}), &t0, &t1));
  EXPECT_NEAR(t0, 9.0, 1e-12);
  EXPECT_NEAR(t1, 11.0, 1e-12);
  EXPECT_FALSE(IntersectInterval(box, MakeRay({0, 0, 0}, {-1, 0, 0}), &t0, &t1));
  EXPECT_FALSE(IntersectInterval(box, MakeRay({0, 2.5, 0}, {1, 0, 0}), &t0, &t1));
  EXPECT_NEAR(HitDistance(box, MakeRay({0, 0, 0}, {1, 0, 0}), 0.0, 100.0, 1), 9.0, 1e-12);
  // Outside the search window: no hit.
  EXPECT_LT(HitDistance(box, MakeRay({0, 0, 0}, {1, 0, 0}), 0.0, 8.0, 1), 0.0);
}

TEST(SimPrimitiveTest, RotatedBoxUsesItsOwnFrame) {
  // A 45-degree box seen along x: the near corner is at centre - half * sqrt(2).
  const Primitive box = Box({10, 0, 0}, {1, 1, 1}, M_PI / 4);
  double t0, t1;
  ASSERT_TRUE(IntersectInterval(box, MakeRay({0, 0, 0}, {1, 0, 0}), &t0, &t1));
  EXPECT_NEAR(t0, 10.0 - std::sqrt(2.0), 1e-9);
  EXPECT_NEAR(t1, 10.0 + std::sqrt(2.0), 1e-9);
  // Centre of the local -x face: normal R * (-1, 0, 0).
  const double c = std::sqrt(0.5);
  const Eigen::Vector3d n = SurfaceNormal(box, Eigen::Vector3d(10.0 - c, -c, 0.0));
  EXPECT_NEAR(n.x(), -c, 1e-9);
  EXPECT_NEAR(n.y(), -c, 1e-9);
  EXPECT_NEAR(n.z(), 0.0, 1e-9);
}

TEST(SimPrimitiveTest, VerticalCylinderAndCaps) {
  Primitive cyl;
  cyl.shape = Shape::kCylinder;
  cyl.pose = core::se3::FromXyzRpy(5, 0, 0, 0, 0, 0);
  cyl.half_size_m = Eigen::Vector3d(0.5, 0.5, 2.0);
  double t0, t1;
  ASSERT_TRUE(IntersectInterval(cyl, MakeRay({0, 0, 0}, {1, 0, 0}), &t0, &t1));
  EXPECT_NEAR(t0, 4.5, 1e-12);
  EXPECT_NEAR(t1, 5.5, 1e-12);
  // From above, straight down: the top cap.
  ASSERT_TRUE(IntersectInterval(cyl, MakeRay({5, 0.1, 10}, {0, 0, -1}), &t0, &t1));
  EXPECT_NEAR(t0, 8.0, 1e-12);
  // Passing above the top.
  EXPECT_FALSE(IntersectInterval(cyl, MakeRay({0, 0, 2.5}, {1, 0, 0}), &t0, &t1));
  EXPECT_NEAR(SignedDistance(cyl, Eigen::Vector3d(5, 1.5, 0)), 1.0, 1e-12);
  EXPECT_NEAR(SignedDistance(cyl, Eigen::Vector3d(5, 0, 0)), -0.5, 1e-12);
  EXPECT_NEAR(SurfaceNormal(cyl, Eigen::Vector3d(4.5, 0, 0)).x(), -1.0, 1e-12);
}

TEST(SimPrimitiveTest, SphereAndEllipsoid) {
  Primitive e;
  e.shape = Shape::kEllipsoid;
  e.pose = core::se3::FromXyzRpy(0, 0, 10, 0, 0, 0);
  e.half_size_m = Eigen::Vector3d(2, 2, 2);
  double t0, t1;
  ASSERT_TRUE(IntersectInterval(e, MakeRay({0, 0, 0}, {0, 0, 1}), &t0, &t1));
  EXPECT_NEAR(t0, 8.0, 1e-12);
  EXPECT_NEAR(t1, 12.0, 1e-12);
  EXPECT_NEAR(SignedDistance(e, Eigen::Vector3d(0, 0, 13)), 1.0, 1e-12);
  e.half_size_m = Eigen::Vector3d(4, 1, 1);
  ASSERT_TRUE(IntersectInterval(e, MakeRay({-10, 0, 10}, {1, 0, 0}), &t0, &t1));
  EXPECT_NEAR(t0, 6.0, 1e-12);
  EXPECT_NEAR(SignedDistance(e, Eigen::Vector3d(5, 0, 10)), 1.0, 1e-9);
}

TEST(SimPrimitiveTest, BoxSignedDistanceAndBounds) {
  const Primitive box = Box({0, 0, 0}, {1, 2, 3});
  EXPECT_NEAR(SignedDistance(box, Eigen::Vector3d(2, 0, 0)), 1.0, 1e-12);
  EXPECT_NEAR(SignedDistance(box, Eigen::Vector3d(2, 3, 0)), std::sqrt(2.0), 1e-12);
  EXPECT_NEAR(SignedDistance(box, Eigen::Vector3d(0.5, 0, 0)), -0.5, 1e-12);
  const Eigen::AlignedBox3d b = WorldBounds(Box({1, 1, 1}, {1, 1, 1}, M_PI / 4));
  EXPECT_NEAR(b.max().x(), 1.0 + std::sqrt(2.0), 1e-9);
  EXPECT_NEAR(b.max().z(), 2.0, 1e-9);
}

TEST(SimPrimitiveTest, PorousVolumeFollowsBeerLambert) {
  // A 1 m thick porous slab with density 1/m stops 1 - e^-1 = 63% of the rays, at an
  // exponentially distributed depth, and the draw depends only on the key.
  Primitive slab = Box({10.5, 0, 0}, {0.5, 5, 5});
  slab.density_per_m = 1.0;
  slab.object_id = 7;
  const Ray ray = MakeRay({0, 0, 0}, {1, 0, 0});
  int hits = 0;
  double depth_sum = 0.0;
  const int n = 20000;
  for (int k = 0; k < n; ++k) {
    const double t = HitDistance(slab, ray, 0.0, 100.0, static_cast<std::uint64_t>(k));
    if (t >= 0.0) {
      ++hits;
      EXPECT_GE(t, 10.0);
      EXPECT_LE(t, 11.0);
      depth_sum += t - 10.0;
    }
    EXPECT_EQ(t, HitDistance(slab, ray, 0.0, 100.0, static_cast<std::uint64_t>(k)));
  }
  EXPECT_NEAR(static_cast<double>(hits) / n, 1.0 - std::exp(-1.0), 0.01);
  // Mean depth of a unit-rate exponential truncated to [0, 1]: 1/(1) - 1/(e - 1) = 0.418.
  EXPECT_NEAR(depth_sum / hits, 1.0 - 1.0 / (std::exp(1.0) - 1.0), 0.01);
  // Clipping the search window (grid cells) does not move the leaf.
  int beyond = 0;
  for (int k = 0; k < 1000; ++k) {
    const double full = HitDistance(slab, ray, 0.0, 100.0, k);
    const double part = HitDistance(slab, ray, 10.5, 100.0, k);
    if (full >= 10.5) {
      EXPECT_EQ(part, full);
      ++beyond;
    } else {
      EXPECT_LT(part, 0.0);  // the leaf lies before the window, or the ray passes
    }
  }
  EXPECT_GT(beyond, 100);
}

TEST(SimPrimitiveTest, ClassAndShapeNamesRoundTrip) {
  for (int i = 0; i < kNumObjectClasses; ++i) {
    const auto c = static_cast<ObjectClass>(i);
    auto parsed = ParseObjectClass(ObjectClassName(c));
    ASSERT_TRUE(parsed.ok());
    EXPECT_EQ(parsed.value(), c);
  }
  EXPECT_EQ(std::string(ObjectClassName(ObjectClass::kParkedCar)), "parked_car");
  EXPECT_FALSE(ParseObjectClass("spaceship").ok());
  EXPECT_TRUE(ParseShape("ellipsoid").ok());
  EXPECT_FALSE(ParseShape("torus").ok());
}

}  // namespace
}  // namespace sim
}  // namespace multisession_mapper
