#include "multisession_mapper/sim/world.h"

#include <cmath>

#include <gtest/gtest.h>

namespace multisession_mapper {
namespace sim {
namespace {

World OneCellWorld() {
  World w;
  w.session_names = {"s00", "s01", "s02"};
  w.terrain.cols = w.terrain.rows = 2;
  w.terrain.heights_m = {0, 0, 0, 0};
  w.terrain.materials = {0};
  return w;
}

TEST(SimWorldTest, MovingObjectsInterpolateAndVanish) {
  WorldObject o;
  o.id = 3;
  o.trajectory = {{10.0, Eigen::Vector3d(0, 0, 1), 0.0}, {12.0, Eigen::Vector3d(4, 0, 1), 0.5}};
  core::Pose3 pose;
  ASSERT_TRUE(o.PoseAt(11.0, &pose));
  EXPECT_NEAR(pose.translation().x(), 2.0, 1e-12);
  const double yaw = std::atan2(pose.linear()(1, 0), pose.linear()(0, 0));
  EXPECT_NEAR(yaw, 0.25, 1e-12);
  EXPECT_FALSE(o.PoseAt(9.9, &pose));
  EXPECT_FALSE(o.PoseAt(12.1, &pose));
  EXPECT_TRUE(o.moving());
}

TEST(SimWorldTest, PartsBecomePrimitivesInTheObjectFrame) {
  World w = OneCellWorld();
  WorldObject o;
  o.id = 9;
  o.object_class = ObjectClass::kParkedCar;
  o.position_m = Eigen::Vector3d(10, 0, 0.75);
  o.yaw_rad = M_PI / 2;
  o.size_m = Eigen::Vector3d(4.5, 1.8, 1.5);
  o.sessions_mask = 0b101;
  ObjectPart part;
  part.center_m = Eigen::Vector3d(1.0, 0.0, 0.0);  // 1 m ahead of the centre
  part.size_m = Eigen::Vector3d(2, 1, 1);
  part.density_per_m = 0.0;
  o.parts.push_back(part);
  w.objects.push_back(o);
  WorldObject pole;
  pole.id = 10;
  pole.shape = Shape::kCylinder;
  pole.size_m = Eigen::Vector3d(0.2, 0.2, 5);
  w.objects.push_back(pole);
  ASSERT_TRUE(w.Validate().ok()) << w.Validate().message();
  EXPECT_EQ(w.AllSessionsMask(), 0b111u);
  const std::vector<Primitive> prims = w.StaticPrimitives();
  ASSERT_EQ(prims.size(), 2u);
  // Heading +y: "ahead" is +y.
  EXPECT_NEAR(prims[0].pose.translation().x(), 10.0, 1e-12);
  EXPECT_NEAR(prims[0].pose.translation().y(), 1.0, 1e-12);
  EXPECT_EQ(prims[0].sessions_mask, 0b101u);
  EXPECT_EQ(prims[0].object_id, 9u);
  EXPECT_EQ(prims[0].object_class, ObjectClass::kParkedCar);
  EXPECT_NEAR(prims[0].half_size_m.x(), 1.0, 1e-12);
  // No parts: the bounding shape itself.
  EXPECT_EQ(prims[1].shape, Shape::kCylinder);
  EXPECT_NEAR(prims[1].half_size_m.z(), 2.5, 1e-12);
}

TEST(SimWorldTest, ValidateNamesTheProblem) {
  World w = OneCellWorld();
  WorldObject o;
  o.id = 0;
  w.objects.push_back(o);
  EXPECT_FALSE(w.Validate().ok());
  w.objects[0].id = 4;
  w.objects.push_back(w.objects[0]);
  EXPECT_NE(w.Validate().message().find("twice"), std::string::npos);
  w.objects.pop_back();
  w.objects[0].size_m.y() = 0.0;
  EXPECT_FALSE(w.Validate().ok());
  w.objects[0].size_m.y() = 1.0;
  w.objects[0].trajectory = {{2.0, Eigen::Vector3d::Zero(), 0}, {1.0, Eigen::Vector3d::Zero(), 0}};
  EXPECT_FALSE(w.Validate().ok());
  w.session_names.clear();
  EXPECT_FALSE(w.Validate().ok());
}

}  // namespace
}  // namespace sim
}  // namespace multisession_mapper
