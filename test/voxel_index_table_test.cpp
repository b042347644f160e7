#include "multisession_mapper/core/voxel_index_table.h"

#include <cstdint>
#include <random>
#include <unordered_map>

#include <gtest/gtest.h>

namespace multisession_mapper {
namespace core {
namespace {

TEST(VoxelIndexTable, EmptyTableFindsNothing) {
  VoxelIndexTable table;
  EXPECT_TRUE(table.empty());
  EXPECT_EQ(table.Find(VoxelKey(0, 0, 0)), VoxelIndexTable::kEmpty);
}

TEST(VoxelIndexTable, FirstInsertWinsAndLaterCallsFindIt) {
  VoxelIndexTable table;
  const auto a = table.FindOrInsert(VoxelKey(1, -2, 3), 7);
  EXPECT_TRUE(a.second);
  EXPECT_EQ(a.first, 7u);
  const auto b = table.FindOrInsert(VoxelKey(1, -2, 3), 9);
  EXPECT_FALSE(b.second);
  EXPECT_EQ(b.first, 7u);
  EXPECT_EQ(table.size(), 1u);
  EXPECT_EQ(table.Find(VoxelKey(1, -2, 3)), 7u);
  EXPECT_EQ(table.Find(VoxelKey(-2, 1, 3)), VoxelIndexTable::kEmpty);
}

// Agrees with std::unordered_map over many growths, on a dense block of neighbouring voxels
// (the submap builder's case, where a weak hash would pile up) and on scattered keys with
// negative and large coordinates, including keys that differ only above bit 21 (the mixing
// wraps them into the same hash input; the full key must still tell them apart).
TEST(VoxelIndexTable, MatchesUnorderedMap) {
  VoxelIndexTable table;
  VoxelMap<std::uint32_t> reference;
  auto insert = [&](const VoxelKey& key) {
    const auto expected = reference.emplace(key, static_cast<std::uint32_t>(reference.size()));
    const auto got = table.FindOrInsert(key, static_cast<std::uint32_t>(table.size()));
    ASSERT_EQ(got.second, expected.second);
    ASSERT_EQ(got.first, expected.first->second);
  };
  for (int x = -20; x < 20; ++x)
    for (int y = -20; y < 20; ++y)
      for (int z = -5; z < 5; ++z) insert(VoxelKey(x, y, z));
  std::mt19937 rng(3);
  std::uniform_int_distribution<int> coord(-3000000, 3000000);
  for (int i = 0; i < 50000; ++i) insert(VoxelKey(coord(rng), coord(rng), coord(rng) % 100));
  insert(VoxelKey(5, 5, 5));
  insert(VoxelKey(5 + (1 << 21), 5, 5));
  insert(VoxelKey(5, 5 - (1 << 21), 5));
  EXPECT_EQ(table.size(), reference.size());
  for (const auto& entry : reference) ASSERT_EQ(table.Find(entry.first), entry.second);
  for (int i = 0; i < 1000; ++i) {
    const VoxelKey absent(coord(rng), coord(rng), 1000 + i);  // z outside the inserted range
    ASSERT_EQ(table.Find(absent), VoxelIndexTable::kEmpty);
  }
}

TEST(VoxelIndexTable, ReserveKeepsTheEntries) {
  VoxelIndexTable table;
  for (int i = 0; i < 100; ++i) table.FindOrInsert(VoxelKey(i, -i, 7), static_cast<std::uint32_t>(i));
  table.Reserve(100000);
  EXPECT_EQ(table.size(), 100u);
  for (int i = 0; i < 100; ++i) ASSERT_EQ(table.Find(VoxelKey(i, -i, 7)), static_cast<std::uint32_t>(i));
  EXPECT_EQ(table.Find(VoxelKey(100, -100, 7)), VoxelIndexTable::kEmpty);
}

TEST(VoxelIndexTable, ReleaseEmptiesAndTheTableIsReusable) {
  VoxelIndexTable table;
  for (int i = 0; i < 5000; ++i) table.FindOrInsert(VoxelKey(i, 0, 0), static_cast<std::uint32_t>(i));
  table.Release();
  EXPECT_TRUE(table.empty());
  EXPECT_EQ(table.Find(VoxelKey(3, 0, 0)), VoxelIndexTable::kEmpty);
  EXPECT_TRUE(table.FindOrInsert(VoxelKey(3, 0, 0), 42).second);
  EXPECT_EQ(table.Find(VoxelKey(3, 0, 0)), 42u);
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
