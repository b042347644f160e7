#include "multisession_mapper/core/map_update.h"

#include <string>

#include <gtest/gtest.h>

namespace multisession_mapper {
namespace core {
namespace {

// A map of `n` sessions s00, s01, ... whose merged sessions (all but the first) have their
// records in memory, as after a merge in a long-lived process (the nodelets).
MapContents MapWithRecords(int n) {
  MapContents map;
  for (int i = 0; i < n; ++i) {
    SessionRecord record;
    record.name = "s0" + std::to_string(i);
    map.sessions.push_back(record);
    map.files["loops/" + record.name + ".csv"] = "kind\n";
    map.files["changes/" + record.name + ".yaml"] = "points_removed: 1\n";
    if (i == 0) continue;
    map.files["place_recognition/" + record.name + ".csv"] = "query\n";
    map.clouds["dynamics/" + record.name + "_removed.pcd"] = {Eigen::Vector3d(1, 2, 3)};
    map.clouds["dynamics/" + record.name + "_mended.pcd"] = {Eigen::Vector3d(4, 5, 6)};
  }
  return map;
}

TEST(RetireSessionRecords, KeepsTheRecordsOfTheLastSessionsOnly) {
  MapContents map = MapWithRecords(5);
  RetireSessionRecords(2, &map);
  for (const std::string name : {"s00", "s01", "s02"}) {
    for (const std::string& rel : SessionRecordFiles(name)) {
      EXPECT_EQ(map.files.count(rel) + map.clouds.count(rel), 0u) << rel;
      EXPECT_EQ(map.retired_files.count(rel), 1u) << rel;
    }
  }
  for (const std::string name : {"s03", "s04"}) {
    EXPECT_EQ(map.files.count("place_recognition/" + name + ".csv"), 1u) << name;
    EXPECT_EQ(map.clouds.count("dynamics/" + name + "_removed.pcd"), 1u) << name;
    EXPECT_EQ(map.clouds.count("dynamics/" + name + "_mended.pcd"), 1u) << name;
    for (const std::string& rel : SessionRecordFiles(name)) {
      EXPECT_EQ(map.retired_files.count(rel), 0u) << rel;
    }
  }
  // Change logs and loops of every session stay.
  for (int i = 0; i < 5; ++i) {
    const std::string name = "s0" + std::to_string(i);
    EXPECT_EQ(map.files.count("changes/" + name + ".yaml"), 1u) << name;
    EXPECT_EQ(map.files.count("loops/" + name + ".csv"), 1u) << name;
  }
}

TEST(RetireSessionRecords, ZeroOrAShortMapRetiresNothing) {
  MapContents all = MapWithRecords(5);
  RetireSessionRecords(0, &all);
  EXPECT_TRUE(all.retired_files.empty());
  EXPECT_EQ(all.clouds.size(), 8u);
  MapContents short_map = MapWithRecords(3);
  RetireSessionRecords(3, &short_map);
  EXPECT_TRUE(short_map.retired_files.empty());
  EXPECT_EQ(short_map.clouds.size(), 4u);
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
