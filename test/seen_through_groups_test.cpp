#include "multisession_mapper/core/seen_through_groups.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace multisession_mapper {
namespace core {
namespace {

constexpr double kVoxel = 0.2;
constexpr float kFar = 30.0f;  // nearest range of the voxels below [m]

// Appends one voxel; returns its index.
std::uint32_t AddVoxel(const VoxelKey& key, const Eigen::Vector3d& point_up,
                       std::uint32_t seen_through, std::uint32_t consistent, float nearest_range_m,
                       std::vector<GroupVoxel>* out) {
  GroupVoxel v;
  v.key = key;
  v.point_up = point_up;
  v.seen_through = seen_through;
  v.consistent = consistent;
  v.nearest_range_m = nearest_range_m;
  out->push_back(v);
  return static_cast<std::uint32_t>(out->size() - 1);
}

// Ground voxels (z = 0) over [-4, 4] x [-4, 4] m with the given evidence.
void AddGround(std::uint32_t seen_through, std::uint32_t consistent, std::vector<GroupVoxel>* out) {
  for (int x = -20; x < 20; ++x) {
    for (int y = -20; y < 20; ++y) {
      GroupVoxel v;
      v.key = VoxelKey(x, y, 0);
      v.point_up = Eigen::Vector3d((x + 0.5) * kVoxel, (y + 0.5) * kVoxel, 0.1);
      v.seen_through = seen_through;
      v.consistent = consistent;
      v.nearest_range_m = kFar;
      out->push_back(v);
    }
  }
}

// A car-sized block of voxels (x from x0, 4 m long, 1.8 m wide, 0.4-1.4 m above the ground),
// every voxel with the given evidence. Returns the indices it took.
std::vector<std::uint32_t> AddBlock(int x0, int y0, std::uint32_t seen_through,
                                    std::uint32_t consistent, std::vector<GroupVoxel>* out) {
  std::vector<std::uint32_t> indices;
  for (int x = x0; x < x0 + 20; ++x) {
    for (int y = y0; y < y0 + 9; ++y) {
      for (int z = 2; z < 7; ++z) {
        GroupVoxel v;
        v.key = VoxelKey(x, y, z);
        v.point_up = (v.key.cast<double>() + Eigen::Vector3d::Constant(0.5)) * kVoxel;
        v.seen_through = seen_through;
        v.consistent = consistent;
        v.nearest_range_m = kFar;
        indices.push_back(static_cast<std::uint32_t>(out->size()));
        out->push_back(v);
      }
    }
  }
  return indices;
}

bool Contains(const std::vector<std::uint32_t>& sorted, std::uint32_t i) {
  return std::binary_search(sorted.begin(), sorted.end(), i);
}

TEST(SeenThroughGroups, DropsAGroupSeenThroughOftenAndKeepsOneSeenThroughRarely) {
  std::vector<GroupVoxel> voxels;
  AddGround(0, 10, &voxels);
  // Per voxel, seen through less often than measured (the per-voxel rule keeps both).
  const std::vector<std::uint32_t> trail = AddBlock(-15, -15, 1, 2, &voxels);   // 33 %
  const std::vector<std::uint32_t> parked = AddBlock(-15, 5, 1, 4, &voxels);   // 20 %
  const std::vector<std::uint32_t> drop = SeenThroughGroups({}, voxels);
  EXPECT_EQ(drop.size(), trail.size());
  for (const std::uint32_t i : trail) EXPECT_TRUE(Contains(drop, i)) << i;
  for (const std::uint32_t i : parked) EXPECT_FALSE(Contains(drop, i)) << i;

  // Measured from closer than min_nearest_range_m (20 m): its own checks decide.
  for (const std::uint32_t i : trail) voxels[i].nearest_range_m = 15.0f;
  EXPECT_TRUE(SeenThroughGroups({}, voxels).empty());
}

TEST(SeenThroughGroups, TheGroundNeverFormsGroups) {
  std::vector<GroupVoxel> voxels;
  AddGround(5, 1, &voxels);  // seen through at grazing angles, mostly
  EXPECT_TRUE(SeenThroughGroups({}, voxels).empty());
  SeenThroughGroupsConfig low;
  low.min_height_m = -1.0;  // the ground too
  EXPECT_EQ(SeenThroughGroups(low, voxels).size(), voxels.size());
}

TEST(SeenThroughGroups, TheEvidenceMustBeSpreadOverTheGroup) {
  std::vector<GroupVoxel> voxels;
  AddGround(0, 10, &voxels);
  const std::vector<std::uint32_t> block = AddBlock(-10, -4, 0, 1, &voxels);
  // One voxel seen through as often as the whole block was measured: 50 % of the checks,
  // but 1 voxel of 900.
  voxels[block.front()].seen_through = static_cast<std::uint32_t>(block.size());
  EXPECT_TRUE(SeenThroughGroups({}, voxels).empty());
  SeenThroughGroupsConfig any_spread;
  any_spread.min_seen_voxel_fraction = 0.0;
  EXPECT_EQ(SeenThroughGroups(any_spread, voxels).size(), block.size());
}

TEST(SeenThroughGroups, GroupsAreJudgedApartAndSmallOnesAreLeft) {
  std::vector<GroupVoxel> voxels;
  AddGround(0, 10, &voxels);
  const std::vector<std::uint32_t> seen = AddBlock(-15, -15, 3, 1, &voxels);
  const std::vector<std::uint32_t> measured = AddBlock(-15, -5, 0, 3, &voxels);  // 0.2 m apart
  const std::vector<std::uint32_t> drop = SeenThroughGroups({}, voxels);
  EXPECT_EQ(drop.size(), seen.size());
  for (const std::uint32_t i : measured) EXPECT_FALSE(Contains(drop, i)) << i;

  // Two voxels, seen through every time: below min_voxels (3).
  std::vector<GroupVoxel> pair;
  AddGround(0, 10, &pair);
  for (int z : {3, 4}) {
    const VoxelKey key(0, 0, z);
    AddVoxel(key, (key.cast<double>() + Eigen::Vector3d::Constant(0.5)) * kVoxel, 5, 0, kFar,
             &pair);
  }
  EXPECT_TRUE(SeenThroughGroups({}, pair).empty());
  SeenThroughGroupsConfig two;
  two.min_voxels = 2;
  EXPECT_EQ(SeenThroughGroups(two, pair).size(), 2u);
}

// One ring's streak on the side of a car seen from afar: a single layer of voxels 1 m above
// the ground, beyond the measured ground (its own lowest voxels are its fine local ground).
TEST(SeenThroughGroups, AStreakWithoutGroundOfItsOwnFormsAGroupByTheCoarseGround) {
  std::vector<GroupVoxel> voxels;
  AddGround(0, 10, &voxels);
  std::vector<std::uint32_t> streak;
  for (int x = 25; x < 39; ++x) {  // 5-7.8 m; the ground ends at 4 m, in the next 4 m cell
    streak.push_back(AddVoxel(VoxelKey(x, 0, 5), Eigen::Vector3d((x + 0.5) * kVoxel, 0.1, 1.0),
                              2, 2, kFar, &voxels));
  }
  EXPECT_EQ(SeenThroughGroups({}, voxels), streak);
  SeenThroughGroupsConfig fine_only;
  fine_only.coarse_min_height_m = 1.0;  // 0.9 m above the coarse ground: not enough
  fine_only.plane_min_height_m = 0.0;   // and no ground plane
  EXPECT_TRUE(SeenThroughGroups(fine_only, voxels).empty());
}

// The same streak 30 m out on a slope (z = 0.05 x), 1 m above the ground there, far beyond the
// coarse cells of the measured ground (which ends at 4 m): only the ground plane, fitted to the
// near ground, reaches it.
TEST(SeenThroughGroups, AGroundPlaneReachesAStreakFarFromAnyMeasuredGround) {
  std::vector<GroupVoxel> voxels;
  AddGround(0, 10, &voxels);
  for (GroupVoxel& v : voxels) v.point_up.z() += 0.05 * v.point_up.x();
  std::vector<std::uint32_t> streak;
  for (int x = 150; x < 165; ++x) {  // 30-33 m, beyond plane_fit_max_range_m: not fitted
    const double px = (x + 0.5) * kVoxel;
    streak.push_back(AddVoxel(VoxelKey(x, 0, 12), Eigen::Vector3d(px, 0.1, 0.05 * px + 1.0), 2,
                              2, 40.0f, &voxels));
  }
  EXPECT_EQ(SeenThroughGroups({}, voxels), streak);
  SeenThroughGroupsConfig no_plane;
  no_plane.plane_min_height_m = 0.0;
  EXPECT_TRUE(SeenThroughGroups(no_plane, voxels).empty());
  SeenThroughGroupsConfig high;
  high.plane_min_height_m = 1.2;  // the streak is 1 m above the plane
  EXPECT_TRUE(SeenThroughGroups(high, voxels).empty());
}

// Ground measured along one strip one voxel wide fixes no plane: its points 0.1 m apart
// across it, 2 cm lower on one side (noise), would tilt a fitted plane by 0.2 down to the
// side, 6 m below the ground 30 m away, and the streak there (as high as the strip) would
// stand 6 m above that "ground" and go.
TEST(SeenThroughGroups, GroundAlongALineFitsNoPlane) {
  std::vector<GroupVoxel> voxels;
  for (int x = -50; x < 50; ++x) {
    AddVoxel(VoxelKey(x, 0, 0),
             Eigen::Vector3d((x + 0.5) * kVoxel, x % 2 ? 0.05 : 0.15, x % 2 ? 0.12 : 0.10), 0, 10,
             kFar, &voxels);
  }
  for (int y = 150; y < 165; ++y) {  // 30-33 m to the side of the line
    AddVoxel(VoxelKey(0, y, 0), Eigen::Vector3d(0.1, (y + 0.5) * kVoxel, 0.11), 2, 2, 40.0f,
             &voxels);
  }
  EXPECT_TRUE(SeenThroughGroups({}, voxels).empty());
}

// A group no check reached (beyond the check range) has no evidence either way: kept, also
// when the spread condition asks for nothing.
TEST(SeenThroughGroups, AGroupNoCheckReachedIsKept) {
  std::vector<GroupVoxel> voxels;
  AddGround(0, 10, &voxels);
  AddBlock(-15, -15, 0, 0, &voxels);
  SeenThroughGroupsConfig any_spread;
  any_spread.min_seen_voxel_fraction = 0.0;
  EXPECT_TRUE(SeenThroughGroups(any_spread, voxels).empty());
}

TEST(SeenThroughGroups, OffMeansNothingIsDropped) {
  std::vector<GroupVoxel> voxels;
  AddGround(0, 10, &voxels);
  AddBlock(-15, -15, 5, 0, &voxels);
  SeenThroughGroupsConfig off;
  off.min_seen_through_ratio = 0.0;
  EXPECT_TRUE(SeenThroughGroups(off, voxels).empty());
  EXPECT_FALSE(SeenThroughGroups({}, voxels).empty());
}

TEST(SeenThroughGroups, ValidateNamesTheBadValue) {
  EXPECT_TRUE(SeenThroughGroupsConfig{}.Validate().ok());
  SeenThroughGroupsConfig c;
  c.min_seen_through_ratio = 1.0;
  EXPECT_NE(c.Validate().message().find("in_session_dynamics.group_min_seen_through_ratio"),
            std::string::npos);
  c = {};
  c.min_seen_voxel_fraction = 1.5;
  EXPECT_NE(c.Validate().message().find("group_min_seen_voxel_fraction"), std::string::npos);
  c = {};
  c.min_voxels = 0;
  EXPECT_NE(c.Validate().message().find("group_min_voxels"), std::string::npos);
  c = {};
  c.ground_cell_m = 0.0;
  EXPECT_NE(c.Validate().message().find("group_ground_cell_m"), std::string::npos);
  c = {};
  c.min_height_m = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NE(c.Validate().message().find("group_min_height_m"), std::string::npos);
  c = {};
  c.coarse_min_height_m = std::numeric_limits<double>::infinity();
  EXPECT_NE(c.Validate().message().find("group_coarse_min_height_m"), std::string::npos);
  c = {};
  c.min_nearest_range_m = -1.0;
  EXPECT_NE(c.Validate().message().find("group_min_nearest_range_m"), std::string::npos);
  c = {};
  c.plane_min_height_m = -0.1;
  EXPECT_NE(c.Validate().message().find("group_plane_min_height_m"), std::string::npos);
  c = {};
  c.plane_fit_max_range_m = 0.0;
  EXPECT_NE(c.Validate().message().find("group_plane_fit_max_range_m"), std::string::npos);
  c = {};
  c.coarse_ground_cell_m = -1.0;
  EXPECT_NE(c.Validate().message().find("group_coarse_ground_cell_m"), std::string::npos);
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
