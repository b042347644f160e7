#include "multisession_mapper/core/new_object_hold.h"

#include <limits>
#include <vector>

#include <gtest/gtest.h>

namespace multisession_mapper {
namespace core {
namespace {

// Flat ground at z = 0 sampled every 0.2 m over [x0, x1] x [y0, y1].
void AddGround(double x0, double x1, double y0, double y1, PointVector* out) {
  for (double x = x0; x <= x1 + 1e-9; x += 0.2) {
    for (double y = y0; y <= y1 + 1e-9; y += 0.2) out->emplace_back(x, y, 0.0);
  }
}

// The surface of a 4.4 x 1.8 x 1.5 m car standing on the ground with its centre at (cx, cy),
// sampled every 0.2 m (sides, ends and roof; 0.3 m ground clearance).
PointVector Car(double cx, double cy) {
  PointVector car;
  const double hx = 2.2, hy = 0.9;
  for (double z = 0.3; z <= 1.5 + 1e-9; z += 0.2) {
    for (double x = -hx; x <= hx + 1e-9; x += 0.2) {
      car.emplace_back(cx + x, cy - hy, z);
      car.emplace_back(cx + x, cy + hy, z);
    }
    for (double y = -hy + 0.2; y <= hy - 0.2 + 1e-9; y += 0.2) {
      car.emplace_back(cx - hx, cy + y, z);
      car.emplace_back(cx + hx, cy + y, z);
    }
  }
  for (double x = -hx + 0.2; x <= hx - 0.2 + 1e-9; x += 0.2) {
    for (double y = -hy + 0.2; y <= hy - 0.2 + 1e-9; y += 0.2) {
      car.emplace_back(cx + x, cy + y, 1.5);
    }
  }
  return car;
}

int CountHeld(const NewObjectHoldResult& r, std::size_t from, std::size_t to) {
  int n = 0;
  for (std::size_t i = from; i < to; ++i) n += r.held[i];
  return n;
}

// The history measured the ground of a parking lot (its own frame placed away from the map
// origin, to exercise the pose); the new session adds a car standing there, and the ground
// it now measures around a car that left (candidates below the ground tolerance).
TEST(NewObjectHoldTest, ACarWhereTheHistorySawTheGroundIsHeldBackAndTheGroundIsNot) {
  const Pose3 T_map_history = Eigen::Translation3d(50.0, -20.0, 3.0) * Pose3::Identity();
  PointVector history_map;
  AddGround(45.0, 65.0, -25.0, -15.0, &history_map);
  PointVector history_local;
  for (const Eigen::Vector3d& p : history_map) {
    history_local.push_back(T_map_history.inverse() * (p + Eigen::Vector3d(0, 0, 3.0)));
  }
  PointVector candidates = Car(50.0, -20.0);
  for (Eigen::Vector3d& p : candidates) p.z() += 3.0;
  const std::size_t car_points = candidates.size();
  for (double x = 58.0; x <= 60.0; x += 0.2) candidates.emplace_back(x, -20.1, 3.05);  // ground
  std::vector<PlacedPoints> history = {{&history_local, T_map_history}};
  StatusOr<NewObjectHoldResult> r =
      HoldBackNewObjects(NewObjectHoldConfig(), candidates, history, PointVector());
  ASSERT_TRUE(r.ok()) << r.status().message();
  ASSERT_EQ(r.value().held.size(), candidates.size());
  EXPECT_EQ(CountHeld(r.value(), 0, car_points), static_cast<int>(car_points));
  EXPECT_EQ(CountHeld(r.value(), car_points, candidates.size()), 0);
  EXPECT_EQ(r.value().groups_held, 1u);

  NewObjectHoldConfig off;
  off.enabled = false;
  r = HoldBackNewObjects(off, candidates, history, PointVector());
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(CountHeld(r.value(), 0, candidates.size()), 0);
}

// A car the history never saw (no history point in or around its place) completes the map:
// it is added. With the points of a car this merge removed there, it is held back: the
// history saw that place occupied by another object.
TEST(NewObjectHoldTest, ACarWhereTheHistorySawNothingIsAddedUnlessAnObjectWasRemovedThere) {
  PointVector history_points;
  AddGround(30.0, 40.0, -5.0, 5.0, &history_points);  // ground elsewhere
  std::vector<PlacedPoints> history = {{&history_points, Pose3::Identity()}};
  const PointVector candidates = Car(0.0, 0.0);
  StatusOr<NewObjectHoldResult> r =
      HoldBackNewObjects(NewObjectHoldConfig(), candidates, history, PointVector());
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(CountHeld(r.value(), 0, candidates.size()), 0);

  // Without ground points the local ground is the cars' lowest points (0.3 m): the new car's
  // lowest row is then ground, everything above is held.
  PointVector removed = Car(0.3, 0.1);  // the previous occupant, shifted along the slot
  r = HoldBackNewObjects(NewObjectHoldConfig(), candidates, history, removed);
  ASSERT_TRUE(r.ok());
  int above = 0;
  for (std::size_t i = 0; i < candidates.size(); ++i) {
    const bool is_above = candidates[i].z() > 0.3 + NewObjectHoldConfig().ground_tolerance_m;
    above += is_above;
    EXPECT_EQ(r.value().held[i], is_above ? 1 : 0) << i;
  }
  EXPECT_GT(above, 200);
}

// A face of a car the history keeps (its other sides are history points): the new points are
// attached to kept structure and are added. Without the attach test they would be held.
TEST(NewObjectHoldTest, ANewFaceOfAnObjectTheHistoryKeepsIsAdded) {
  PointVector history_points;
  AddGround(-6.0, 6.0, -4.0, 4.0, &history_points);
  PointVector candidates;
  for (const Eigen::Vector3d& p : Car(0.0, 0.0)) {
    (p.y() > 0.85 ? candidates : history_points).push_back(p);  // the +y side is new
  }
  std::vector<PlacedPoints> history = {{&history_points, Pose3::Identity()}};
  StatusOr<NewObjectHoldResult> r =
      HoldBackNewObjects(NewObjectHoldConfig(), candidates, history, PointVector());
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(CountHeld(r.value(), 0, candidates.size()), 0);

  NewObjectHoldConfig loose;
  loose.max_attached_fraction = 1.0;
  r = HoldBackNewObjects(loose, candidates, history, PointVector());
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(CountHeld(r.value(), 0, candidates.size()), static_cast<int>(candidates.size()));
}

// The attach test's reach is exact: a 2 m bar of new points 0.49 m above the ground, and a
// history bar above the ground offset diagonally (in y and z, across the 0.5 m voxels the
// hold looks in) by 0.34 m each way (0.481 m: within attach_radius_m, the bar is added) or by
// 0.36 m (0.509 m: beyond it, held back).
TEST(NewObjectHoldTest, HistoryPointsJustWithinTheAttachRadiusAttach) {
  for (const double offset : {0.34, 0.36}) {
    PointVector history_points;
    AddGround(-3.0, 5.0, -3.0, 3.0, &history_points);
    PointVector candidates;
    for (double x = 0.0; x <= 2.0 + 1e-9; x += 0.2) {
      candidates.emplace_back(x, 0.49, 0.49);
      history_points.emplace_back(x, 0.49 + offset, 0.49 + offset);
    }
    std::vector<PlacedPoints> history = {{&history_points, Pose3::Identity()}};
    StatusOr<NewObjectHoldResult> r =
        HoldBackNewObjects(NewObjectHoldConfig(), candidates, history, PointVector());
    ASSERT_TRUE(r.ok());
    const int expected = offset < 0.35 ? 0 : static_cast<int>(candidates.size());
    EXPECT_EQ(CountHeld(r.value(), 0, candidates.size()), expected) << offset;
  }
}

// New structure that is not of a movable object's shape is added: a 6 m high facade, a 14 m
// long hedge, and a crown floating 2 m above the ground.
TEST(NewObjectHoldTest, StructureOfOtherShapesIsAdded) {
  PointVector history_points;
  AddGround(-10.0, 40.0, -10.0, 10.0, &history_points);
  std::vector<PlacedPoints> history = {{&history_points, Pose3::Identity()}};
  PointVector facade, hedge, crown;
  for (double x = 0.0; x <= 3.0; x += 0.2) {
    for (double z = 0.3; z <= 6.0; z += 0.2) facade.emplace_back(x, 5.0, z);
  }
  for (double x = 10.0; x <= 24.0; x += 0.2) {
    for (double z = 0.3; z <= 1.2; z += 0.2) hedge.emplace_back(x, -5.0, z);
  }
  for (double x = 30.0; x <= 33.0; x += 0.2) {
    for (double y = 0.0; y <= 3.0; y += 0.2) crown.emplace_back(x, y, 2.0 + 0.1 * (x - 30.0));
  }
  for (const PointVector* shape : {&facade, &hedge, &crown}) {
    StatusOr<NewObjectHoldResult> r =
        HoldBackNewObjects(NewObjectHoldConfig(), *shape, history, PointVector());
    ASSERT_TRUE(r.ok());
    EXPECT_EQ(CountHeld(r.value(), 0, shape->size()), 0);
  }
  // The same facade cut to 2 m is of a movable shape and held.
  PointVector low_wall;
  for (const Eigen::Vector3d& p : facade) {
    if (p.z() <= 2.0) low_wall.push_back(p);
  }
  StatusOr<NewObjectHoldResult> r =
      HoldBackNewObjects(NewObjectHoldConfig(), low_wall, history, PointVector());
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(CountHeld(r.value(), 0, low_wall.size()), static_cast<int>(low_wall.size()));
}

// A row of three construction fence panels (3.5 m each, 0.1 m apart, 2 m high: one group,
// 10.7 m long) where the history saw the ground is held back; with max_extent_m below its
// length it passes for structure and is added. A 2 m high row longer than max_extent_m is
// added too.
TEST(NewObjectHoldTest, AFenceRowUpToTheMaxExtentIsHeldBack) {
  PointVector history_points;
  AddGround(-5.0, 30.0, -5.0, 5.0, &history_points);
  std::vector<PlacedPoints> history = {{&history_points, Pose3::Identity()}};
  auto fence_row = [](int panels) {
    PointVector row;
    for (int panel = 0; panel < panels; ++panel) {
      for (double x = 0.0; x <= 3.5 + 1e-9; x += 0.25) {
        for (double z = 0.5; z <= 2.0 + 1e-9; z += 0.25) row.emplace_back(3.6 * panel + x, 0.0, z);
      }
    }
    return row;
  };
  const PointVector three = fence_row(3);
  StatusOr<NewObjectHoldResult> r =
      HoldBackNewObjects(NewObjectHoldConfig(), three, history, PointVector());
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(CountHeld(r.value(), 0, three.size()), static_cast<int>(three.size()));
  EXPECT_EQ(r.value().groups_held, 1u);

  NewObjectHoldConfig short_extent;
  short_extent.max_extent_m = 10.5;
  r = HoldBackNewObjects(short_extent, three, history, PointVector());
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(CountHeld(r.value(), 0, three.size()), 0);

  const PointVector four = fence_row(4);  // 14.3 m
  r = HoldBackNewObjects(NewObjectHoldConfig(), four, history, PointVector());
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(CountHeld(r.value(), 0, four.size()), 0);
}

TEST(NewObjectHoldTest, NonFinitePointsAreAnError) {
  PointVector ground;
  AddGround(-5.0, 5.0, -5.0, 5.0, &ground);
  std::vector<PlacedPoints> history = {{&ground, Pose3::Identity()}};
  PointVector candidates = Car(0.0, 0.0);
  ASSERT_TRUE(HoldBackNewObjects(NewObjectHoldConfig(), candidates, history, PointVector()).ok());
  candidates[3].x() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(HoldBackNewObjects(NewObjectHoldConfig(), candidates, history, PointVector()).ok());
  candidates[3].x() = 0.0;
  ground[7].z() = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(HoldBackNewObjects(NewObjectHoldConfig(), candidates, history, PointVector()).ok());
}

TEST(NewObjectHoldTest, InvalidConfigsAreRejected) {
  EXPECT_TRUE(NewObjectHoldConfig().Validate().ok());
  NewObjectHoldConfig c;
  c.grow_radius_m = 0.0;
  EXPECT_FALSE(c.Validate().ok());
  c = NewObjectHoldConfig();
  c.max_attached_fraction = 1.5;
  EXPECT_FALSE(c.Validate().ok());
  c = NewObjectHoldConfig();
  c.min_points = 0;
  EXPECT_FALSE(c.Validate().ok());
  c = NewObjectHoldConfig();
  c.ground_cell_m = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(c.Validate().ok());
  c = NewObjectHoldConfig();
  c.max_extent_m = 0.0;
  EXPECT_FALSE(c.Validate().ok());
  c.max_extent_m = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(c.Validate().ok());
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
