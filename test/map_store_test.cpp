#include "multisession_mapper/core/map_store.h"

#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "multisession_mapper/core/se3.h"

namespace multisession_mapper {
namespace core {
namespace {
namespace fs = std::filesystem;

std::string TempDir(const std::string& name) {
  const fs::path dir = fs::path(MSM_TEST_TMP_DIR) / "map_store_test" / name;
  fs::remove_all(dir);
  fs::remove_all(dir.string() + ".new");
  fs::remove_all(dir.string() + ".old");
  fs::create_directories(dir.parent_path());
  return dir.string();
}

MapContents MakeMap(int sessions, int seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-20.0, 20.0);
  MapContents map;
  std::int64_t node = 0;
  for (int s = 0; s < sessions; ++s) {
    SessionRecord record;
    record.name = "s0" + std::to_string(s);
    record.bag = record.name + ".bag";
    record.scans = 30;
    record.duration_s = 3.0;
    record.merged_at = "2026-11-21T00:00:00Z";
    map.sessions.push_back(record);
    Trajectory trajectory;
    for (int m = 0; m < 3; ++m) {
      Submap submap;
      submap.session = record.name;
      submap.id = m;
      submap.T_map_submap = se3::FromXyzRpy(u(rng), u(rng), 0.1, 0.01, -0.02, u(rng) * 0.1);
      for (int k = 0; k < 10; ++k) {
        SubmapScanRecord scan;
        scan.stamp_s = 1e9 + s * 86400 + m + 0.1 * k;
        scan.T_submap_sensor = se3::FromXyzRpy(0.5 * k, 0, 0, 0, 0, 0.01 * k);
        submap.scans.push_back(scan);
        StampedPose sp;
        sp.stamp_s = scan.stamp_s;
        sp.pose = submap.T_map_submap * scan.T_submap_sensor;
        trajectory.push_back(sp);
      }
      for (int p = 0; p < 500; ++p) submap.points.emplace_back(u(rng), u(rng), u(rng) * 0.1);
      if (s == 0) {  // the first session records its points' views, the second does not
        for (int p = 0; p < 500; ++p) {
          PointViews v;
          if (p % 7 != 0) {  // every 7th unknown (e.g. a point a merge added)
            v.nearest_scan = static_cast<std::uint32_t>(p % 10);
            v.last_scan = static_cast<std::uint32_t>((p / 10) % 10);
          }
          submap.views.push_back(v);
        }
      }
      submap.length_m = 4.5;
      map.graph.SetNodePose(node, submap.T_map_submap);
      if (node == 0) map.graph.SetFixed(0, true);
      if (m > 0) {
        PoseGraphEdge e;
        e.from = node - 1;
        e.to = node;
        e.T_from_to = se3::Between(map.graph.NodePose(node - 1), submap.T_map_submap);
        EXPECT_TRUE(map.graph.AddEdge(e).ok());
      }
      ++node;
      map.submaps.push_back(submap);
    }
    map.trajectories[record.name] = trajectory;
    map.files["loops/" + record.name + ".csv"] = "kind,current_session\nintra," + record.name + "\n";
  }
  map.parameters_yaml = "submap:\n  max_translation_m: 20.0\n";
  return map;
}

void ExpectSameMap(const MapContents& a, const MapContents& b) {
  ASSERT_EQ(a.sessions.size(), b.sessions.size());
  for (std::size_t i = 0; i < a.sessions.size(); ++i) {
    EXPECT_EQ(a.sessions[i].name, b.sessions[i].name);
    EXPECT_EQ(a.sessions[i].scans, b.sessions[i].scans);
  }
  ASSERT_EQ(a.submaps.size(), b.submaps.size());
  for (std::size_t i = 0; i < a.submaps.size(); ++i) {
    EXPECT_EQ(a.submaps[i].session, b.submaps[i].session);
    EXPECT_EQ(a.submaps[i].id, b.submaps[i].id);
    EXPECT_TRUE(a.submaps[i].T_map_submap.isApprox(b.submaps[i].T_map_submap, 1e-9));
    ASSERT_EQ(a.submaps[i].points.size(), b.submaps[i].points.size());
    for (std::size_t p = 0; p < a.submaps[i].points.size(); ++p) {
      // PCD stores float32.
      EXPECT_LT((a.submaps[i].points[p] - b.submaps[i].points[p]).norm(), 1e-5);
    }
    ASSERT_EQ(a.submaps[i].views.size(), b.submaps[i].views.size());
    for (std::size_t p = 0; p < a.submaps[i].views.size(); ++p) {
      EXPECT_EQ(a.submaps[i].views[p].nearest_scan, b.submaps[i].views[p].nearest_scan);
      EXPECT_EQ(a.submaps[i].views[p].last_scan, b.submaps[i].views[p].last_scan);
    }
    ASSERT_EQ(a.submaps[i].scans.size(), b.submaps[i].scans.size());
    for (std::size_t k = 0; k < a.submaps[i].scans.size(); ++k) {
      EXPECT_NEAR(a.submaps[i].scans[k].stamp_s, b.submaps[i].scans[k].stamp_s, 1e-6);
      EXPECT_TRUE(a.submaps[i].scans[k].T_submap_sensor.isApprox(
          b.submaps[i].scans[k].T_submap_sensor, 1e-9));
    }
  }
  EXPECT_EQ(a.graph.nodes().size(), b.graph.nodes().size());
  EXPECT_EQ(a.graph.edges().size(), b.graph.edges().size());
  EXPECT_EQ(a.trajectories.size(), b.trajectories.size());
}

TEST(MapStore, RoundTrip) {
  const std::string dir = TempDir("round_trip");
  const MapContents map = MakeMap(2, 1);
  MapStore store;
  ASSERT_TRUE(store.Save(map, dir).ok());
  StatusOr<MapContents> loaded = store.Load(dir);
  ASSERT_TRUE(loaded.ok()) << loaded.status().message();
  ExpectSameMap(map, loaded.value());
  EXPECT_NE(loaded.value().parameters_yaml.find("max_translation_m"), std::string::npos);
  EXPECT_TRUE(fs::exists(fs::path(dir) / "loops/s00.csv"));
  EXPECT_FALSE(fs::exists(dir + ".new"));
  EXPECT_FALSE(fs::exists(dir + ".old"));
}

// The submaps are written on several threads: the files (manifest included) are the same
// byte for byte as with one.
TEST(MapStore, WriteThreadsDoNotChangeTheFiles) {
  MapContents map = MakeMap(2, 5);
  ASSERT_GE(map.submaps.size(), 4u);
  // The first submap much larger than the others: with several threads it is written last,
  // so a manifest in the writers' completion order would differ from one in submap order.
  Submap& large = map.submaps.front();
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> u(-20.0, 20.0);
  while (large.points.size() < 300000) {
    large.points.emplace_back(u(rng), u(rng), u(rng));
    if (!large.views.empty()) large.views.push_back(large.views[large.points.size() % 500]);
  }
  std::map<std::string, std::string> reference;
  for (const int threads : {1, 2, 4}) {
    const std::string dir = TempDir("write_threads_" + std::to_string(threads));
    MapStoreConfig config;
    config.write_threads = threads;
    ASSERT_TRUE(MapStore(config).Save(map, dir).ok());
    std::map<std::string, std::string> files;
    for (const auto& entry : fs::recursive_directory_iterator(dir)) {
      if (!entry.is_regular_file()) continue;
      std::ifstream in(entry.path(), std::ios::binary);
      std::ostringstream bytes;
      bytes << in.rdbuf();
      files[fs::relative(entry.path(), dir).string()] = bytes.str();
    }
    EXPECT_GT(files.count("manifest.yaml"), 0u);
    if (reference.empty()) {
      reference = files;
    } else {
      EXPECT_TRUE(files == reference) << threads << " write threads";
    }
    StatusOr<MapContents> loaded = MapStore().Load(dir);
    ASSERT_TRUE(loaded.ok()) << loaded.status().message();
    ExpectSameMap(map, loaded.value());
  }
}

TEST(MapStore, RoundTripKeepsTheViewsOfEachPoint) {
  const MapContents map = MakeMap(2, 3);
  ASSERT_EQ(map.submaps[0].views.size(), map.submaps[0].points.size());
  ASSERT_TRUE(map.submaps[3].views.empty());
  const std::string dir = TempDir("views");
  ASSERT_TRUE(MapStore().Save(map, dir).ok());
  StatusOr<MapContents> loaded = MapStore().Load(dir);
  ASSERT_TRUE(loaded.ok()) << loaded.status().message();
  ExpectSameMap(map, loaded.value());  // views included, unknown ones too
  EXPECT_TRUE(loaded.value().submaps[3].views.empty());
}

TEST(MapStore, ViewOfAScanTheSubmapDoesNotHaveNamesTheFile) {
  MapContents map = MakeMap(1, 5);
  map.submaps[2].views[17].last_scan = 10;  // the submap has scans 0 .. 9
  const std::string dir = TempDir("bad_view");
  ASSERT_TRUE(MapStore().Save(map, dir).ok());
  StatusOr<MapContents> loaded = MapStore().Load(dir);
  ASSERT_FALSE(loaded.ok());
  EXPECT_NE(loaded.status().message().find("submaps/s00/2.pcd"), std::string::npos)
      << loaded.status().message();
  EXPECT_NE(loaded.status().message().find("scan index 10"), std::string::npos)
      << loaded.status().message();
}

TEST(MapStore, UnchangedSubmapsAreHardLinkedAndExtraFilesCarriedOver) {
  const std::string dir = TempDir("links");
  MapStore store;
  ASSERT_TRUE(store.Save(MakeMap(1, 2), dir).ok());
  struct stat before;
  ASSERT_EQ(::stat((dir + "/submaps/s00/0.pcd").c_str(), &before), 0);
  StatusOr<MapContents> loaded = store.Load(dir);
  ASSERT_TRUE(loaded.ok());
  MapContents next = loaded.value();
  next.files.clear();  // not re-supplied: must be carried over from the old map
  next.submaps[1].points.emplace_back(1, 2, 3);
  next.clean_submaps.erase(SubmapKey("s00", 1));
  ASSERT_TRUE(store.Save(next, dir).ok());
  struct stat after;
  ASSERT_EQ(::stat((dir + "/submaps/s00/0.pcd").c_str(), &after), 0);
  EXPECT_EQ(before.st_ino, after.st_ino) << "an unchanged submap was rewritten";
  EXPECT_TRUE(fs::exists(fs::path(dir) / "loops/s00.csv"));
  StatusOr<MapContents> reloaded = store.Load(dir);
  ASSERT_TRUE(reloaded.ok()) << reloaded.status().message();
  EXPECT_EQ(reloaded.value().submaps[1].points.size(), 501u);
}

TEST(MapStore, RetiredFilesAreNotCarriedOver) {
  const std::string dir = TempDir("retired");
  MapStore store;
  MapContents map = MakeMap(2, 3);
  map.files["place_recognition/s01.csv"] = "query\n";
  map.clouds["dynamics/s01_removed.pcd"] = {Eigen::Vector3d(1, 2, 3)};
  ASSERT_TRUE(store.Save(map, dir).ok());
  ASSERT_TRUE(fs::exists(fs::path(dir) / "place_recognition/s01.csv"));
  ASSERT_TRUE(fs::exists(fs::path(dir) / "dynamics/s01_removed.pcd"));
  StatusOr<MapContents> loaded = store.Load(dir);
  ASSERT_TRUE(loaded.ok()) << loaded.status().message();
  MapContents next = loaded.value();
  next.files.clear();  // everything else is carried over from the old map
  next.retired_files = {"place_recognition/s01.csv", "dynamics/s01_removed.pcd"};
  ASSERT_TRUE(store.Save(next, dir).ok());
  EXPECT_FALSE(fs::exists(fs::path(dir) / "place_recognition/s01.csv"));
  EXPECT_FALSE(fs::exists(fs::path(dir) / "dynamics/s01_removed.pcd"));
  EXPECT_TRUE(fs::exists(fs::path(dir) / "loops/s00.csv"));
  StatusOr<MapContents> reloaded = store.Load(dir);  // the manifest no longer lists them
  ASSERT_TRUE(reloaded.ok()) << reloaded.status().message();
  ExpectSameMap(loaded.value(), reloaded.value());
}

// A crash after any number of written files leaves the old map loadable and unchanged.
TEST(MapStore, CrashAtEveryStepLeavesOldOrNewMap) {
  const std::string dir = TempDir("crash");
  const MapContents old_map = MakeMap(1, 3);
  const MapContents new_map = MakeMap(2, 4);
  int steps_with_old = 0;
  for (int abort_after = 1; abort_after < 40; ++abort_after) {
    fs::remove_all(dir);
    ASSERT_TRUE(MapStore().Save(old_map, dir).ok());
    MapStoreConfig crashing;
    crashing.test_abort_after_files = abort_after;
    const Status crashed = MapStore(crashing).Save(new_map, dir);
    StatusOr<MapContents> loaded = MapStore().Load(dir);
    ASSERT_TRUE(loaded.ok()) << "after abort at " << abort_after << ": "
                             << loaded.status().message();
    if (crashed.ok()) {
      ExpectSameMap(new_map, loaded.value());
      break;  // the save completed before the hook fired: every crash point was covered
    }
    if (loaded.value().sessions.size() == 1) {
      ExpectSameMap(old_map, loaded.value());
      ++steps_with_old;
    } else {
      ExpectSameMap(new_map, loaded.value());  // crashed after the swap's first rename
    }
  }
  EXPECT_GT(steps_with_old, 5);
}

TEST(MapStore, InterruptedSwapIsFinishedOnLoad) {
  const std::string dir = TempDir("swap");
  ASSERT_TRUE(MapStore().Save(MakeMap(1, 5), dir).ok());
  const MapContents new_map = MakeMap(2, 6);
  ASSERT_TRUE(MapStore().Save(new_map, dir + "_staging").ok());
  // State right after the first rename of the swap: old map aside, new one complete.
  fs::rename(dir, dir + ".old");
  fs::rename(dir + "_staging", dir + ".new");
  StatusOr<MapContents> loaded = MapStore().Load(dir);
  ASSERT_TRUE(loaded.ok()) << loaded.status().message();
  ExpectSameMap(new_map, loaded.value());
  EXPECT_FALSE(fs::exists(dir + ".old"));
}

class CorruptMap : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = TempDir("corrupt");
    ASSERT_TRUE(MapStore().Save(MakeMap(1, 7), dir_).ok());
  }
  std::string Error() {
    StatusOr<MapContents> loaded = MapStore().Load(dir_);
    EXPECT_FALSE(loaded.ok());
    return loaded.ok() ? "" : loaded.status().message();
  }
  std::string dir_;
};

TEST_F(CorruptMap, FlippedByteInSubmapNamesTheFile) {
  std::fstream f(dir_ + "/submaps/s00/1.pcd", std::ios::in | std::ios::out | std::ios::binary);
  f.seekp(-5, std::ios::end);
  f.put('\x7f');
  f.close();
  const std::string error = Error();
  EXPECT_NE(error.find("submaps/s00/1.pcd"), std::string::npos) << error;
  EXPECT_NE(error.find("corrupt"), std::string::npos) << error;
}

TEST_F(CorruptMap, TruncatedGraphNamesTheFile) {
  fs::resize_file(dir_ + "/graph.g2o", 10);
  const std::string error = Error();
  EXPECT_NE(error.find("graph.g2o"), std::string::npos) << error;
  EXPECT_NE(error.find("truncated"), std::string::npos) << error;
}

TEST_F(CorruptMap, MissingTrajectoryNamesTheFile) {
  fs::remove(dir_ + "/trajectories/s00.tum");
  EXPECT_NE(Error().find("trajectories/s00.tum"), std::string::npos);
}

TEST_F(CorruptMap, GarbageManifest) {
  std::ofstream(dir_ + "/manifest.yaml") << "{[}: not yaml at all\n\t\x01";
  EXPECT_NE(Error().find("manifest.yaml"), std::string::npos);
}

TEST_F(CorruptMap, FutureFormatVersion) {
  std::ofstream(dir_ + "/manifest.yaml") << "format_version: 99\nfiles: {}\n";
  EXPECT_NE(Error().find("format_version 99"), std::string::npos);
}

TEST_F(CorruptMap, PathTraversalInManifestIsRefused) {
  std::ofstream(dir_ + "/manifest.yaml")
      << "format_version: 1\nfiles:\n  ../../etc/passwd: {bytes: 1, fnv1a64: '0'}\n";
  EXPECT_NE(Error().find("unsafe"), std::string::npos);
}

TEST(MapStore, MissingMapIsAClearError) {
  StatusOr<MapContents> loaded = MapStore().Load(TempDir("nothing_here"));
  ASSERT_FALSE(loaded.ok());
  EXPECT_NE(loaded.status().message().find("no map"), std::string::npos);
}

TEST(MapStore, UnsafeSessionNameIsRefusedOnSave) {
  MapContents map = MakeMap(1, 8);
  map.submaps[0].session = "../escape";
  EXPECT_FALSE(MapStore().Save(map, TempDir("unsafe")).ok());
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
