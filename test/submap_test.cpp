#include "multisession_mapper/core/submap.h"

#include <vector>

#include <gtest/gtest.h>

namespace multisession_mapper {
namespace core {
namespace {

Submap WithPoints(int n, bool views) {
  Submap s;
  for (int i = 0; i < n; ++i) {
    s.points.emplace_back(i, 0.0, 0.0);
    if (views) {
      PointViews v;
      v.nearest_scan = static_cast<std::uint32_t>(i);
      v.last_scan = static_cast<std::uint32_t>(10 + i);
      s.views.push_back(v);
    }
  }
  return s;
}

TEST(Submap, DropKeepsEachPointWithItsViews) {
  Submap s = WithPoints(6, true);
  DropSubmapPoints({1, 0, 0, 1, 1, 0}, &s);
  ASSERT_EQ(s.points.size(), 3u);
  ASSERT_EQ(s.views.size(), 3u);
  const int kept[] = {1, 2, 5};
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(s.points[k].x(), kept[k]);
    EXPECT_EQ(s.views[k].nearest_scan, static_cast<std::uint32_t>(kept[k]));
    EXPECT_EQ(s.views[k].last_scan, static_cast<std::uint32_t>(10 + kept[k]));
  }
  // A shorter mask drops nothing beyond its end.
  DropSubmapPoints({1}, &s);
  ASSERT_EQ(s.points.size(), 2u);
  EXPECT_EQ(s.points[0].x(), 2);
  EXPECT_EQ(s.views[1].nearest_scan, 5u);
}

TEST(Submap, DropWithoutViewsLeavesNone) {
  Submap s = WithPoints(4, false);
  DropSubmapPoints({0, 1, 0, 0}, &s);
  EXPECT_EQ(s.points.size(), 3u);
  EXPECT_TRUE(s.views.empty());
}

TEST(Submap, AppendedPointsHaveUnknownViews) {
  Submap s = WithPoints(2, true);
  AppendSubmapPoints({Eigen::Vector3d(7, 7, 7)}, &s);
  ASSERT_EQ(s.points.size(), 3u);
  ASSERT_EQ(s.views.size(), 3u);
  EXPECT_EQ(s.views[1].last_scan, 11u);
  EXPECT_EQ(s.views[2].nearest_scan, PointViews::kUnknownScan);
  EXPECT_EQ(s.views[2].last_scan, PointViews::kUnknownScan);
  // A submap that records no views keeps recording none.
  Submap plain = WithPoints(2, false);
  AppendSubmapPoints({Eigen::Vector3d(1, 2, 3)}, &plain);
  EXPECT_EQ(plain.points.size(), 3u);
  EXPECT_TRUE(plain.views.empty());
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
