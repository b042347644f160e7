#include "multisession_mapper/core/dynamic_propagation.h"

#include <set>
#include <vector>

#include <gtest/gtest.h>

namespace multisession_mapper {
namespace core {
namespace {

// A car's side seen closely in one submap (0.2 m samples, found dynamic there) and sparsely
// from far away in another submap with its own frame, next to a wall 0.6 m behind it.
TEST(DynamicPropagationTest, FarCopiesOfADynamicObjectAreFoundInOtherSubmaps) {
  PointVector near_submap, far_submap;
  std::set<std::uint32_t> near_dynamic;
  for (double x = 0.0; x <= 4.0 + 1e-9; x += 0.2) {
    for (double z = 0.4; z <= 1.4 + 1e-9; z += 0.2) {
      near_dynamic.insert(static_cast<std::uint32_t>(near_submap.size()));
      near_submap.emplace_back(x, 5.0, z);        // the car's side (map frame = submap frame)
      near_submap.emplace_back(x, 5.6, z + 1.0);  // the wall above and behind: static
    }
  }
  // The far submap's frame: 30 m away and turned; its points are the same surfaces sampled
  // every 0.5 m with 0.05 m of alignment error, plus the wall.
  const Pose3 T_map_far = Eigen::Translation3d(30.0, -4.0, 0.2) *
                          Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ());
  std::vector<int> far_is_car;
  for (double x = 0.1; x <= 3.9; x += 0.5) {
    for (double z = 0.5; z <= 1.3; z += 0.4) {
      far_submap.push_back(T_map_far.inverse() * Eigen::Vector3d(x + 0.05, 5.03, z));
      far_is_car.push_back(1);
      far_submap.push_back(T_map_far.inverse() * Eigen::Vector3d(x, 5.6, z + 1.0));
      far_is_car.push_back(0);
    }
  }
  std::vector<MarkedCloud> clouds(2);
  clouds[0] = {&near_submap, Pose3::Identity(), &near_dynamic};
  clouds[1] = {&far_submap, T_map_far, nullptr};
  auto found = FindCopiesOfMarked(0.2, 2, clouds);
  ASSERT_TRUE(found.ok()) << found.status().message();
  EXPECT_TRUE(found.value()[0].empty());  // the near submap's wall is not a copy
  int car = 0, wall = 0;
  for (std::uint32_t k : found.value()[1]) (far_is_car[k] ? car : wall)++;
  int cars_total = 0;
  for (int c : far_is_car) cars_total += c;
  EXPECT_EQ(car, cars_total);
  EXPECT_EQ(wall, 0);
  // Indices in order, none repeated.
  for (std::size_t i = 1; i < found.value()[1].size(); ++i) {
    EXPECT_LT(found.value()[1][i - 1], found.value()[1][i]);
  }
}

TEST(DynamicPropagationTest, MarkedPointsAreNotReportedAgainAndNothingMarkedFindsNothing) {
  PointVector a = {{0.0, 0.0, 0.0}, {0.1, 0.0, 0.0}, {5.0, 0.0, 0.0}};
  std::set<std::uint32_t> marked = {0};
  std::vector<MarkedCloud> clouds = {{&a, Pose3::Identity(), &marked}};
  auto found = FindCopiesOfMarked(0.2, 1, clouds);
  ASSERT_TRUE(found.ok());
  EXPECT_EQ(found.value()[0], std::vector<std::uint32_t>({1}));

  clouds[0].marked = nullptr;
  found = FindCopiesOfMarked(0.2, 1, clouds);
  ASSERT_TRUE(found.ok());
  EXPECT_TRUE(found.value()[0].empty());
}

TEST(DynamicPropagationTest, RejectsABadRadiusAndAMissingCloud) {
  PointVector a = {{0.0, 0.0, 0.0}};
  std::vector<MarkedCloud> clouds = {{&a, Pose3::Identity(), nullptr}};
  EXPECT_FALSE(FindCopiesOfMarked(0.0, 1, clouds).ok());
  EXPECT_FALSE(FindCopiesOfMarked(-1.0, 1, clouds).ok());
  clouds.push_back({nullptr, Pose3::Identity(), nullptr});
  EXPECT_FALSE(FindCopiesOfMarked(0.2, 1, clouds).ok());
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
