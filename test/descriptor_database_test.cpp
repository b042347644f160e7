#include "place_recognition_test_scans.h"  // first: defines PCL_NO_PRECOMPILE

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include <gtest/gtest.h>

#include "multisession_mapper/core/descriptor_database.h"
#include "multisession_mapper/core/ring_histogram_descriptor.h"
#include "multisession_mapper/core/scan_context_descriptor.h"

namespace multisession_mapper {
namespace core {
namespace {

constexpr int kDim = 64;

std::string TmpPath(const std::string& name) {
  std::filesystem::create_directories(MSM_TEST_TMP_DIR);
  return std::string(MSM_TEST_TMP_DIR) + "/descriptor_database_test_" + name;
}

PlaceDescriptor RandomDescriptor(std::mt19937* rng) {
  std::uniform_real_distribution<float> u(0.0f, 0.2f);
  PlaceDescriptor d;
  d.key.resize(kDim);
  for (float& v : d.key) v = u(*rng);
  return d;
}

struct Fixture {
  std::vector<DatabaseEntry> entries;
  std::vector<PlaceDescriptor> descriptors;
};

Fixture RandomFixture(int count, std::uint32_t seed) {
  std::mt19937 rng(seed);
  Fixture f;
  for (int i = 0; i < count; ++i) {
    f.entries.push_back({i < count / 2 ? "s00" : "s01", 100.0 + 0.1 * i, i / 10});
    f.descriptors.push_back(RandomDescriptor(&rng));
  }
  return f;
}

DescriptorDatabase MakeRingDatabase(const Fixture& f, DescriptorDatabaseConfig config = {}) {
  auto db = DescriptorDatabase::Create(config, DescriptorKind::kRingHistogram, kDim);
  EXPECT_TRUE(db.ok()) << db.status().message();
  DescriptorDatabase out = std::move(db).value();
  EXPECT_TRUE(out.Insert(f.entries, f.descriptors).ok());
  return out;
}

double BruteForceNearest(const Fixture& f, const PlaceDescriptor& q, std::size_t* index) {
  double best = 1e30;
  for (std::size_t i = 0; i < f.descriptors.size(); ++i) {
    const double d = msm_pr_test::L2(q.key, f.descriptors[i].key);
    if (d < best) {
      best = d;
      *index = i;
    }
  }
  return best;
}

TEST(DescriptorDatabaseTest, EmptyDatabaseHasNoMatch) {
  auto db = DescriptorDatabase::Create({}, DescriptorKind::kRingHistogram, kDim);
  ASSERT_TRUE(db.ok());
  std::mt19937 rng(1);
  auto result = db.value().Query(RandomDescriptor(&rng));
  ASSERT_TRUE(result.ok());
  EXPECT_FALSE(result.value().matched);
  EXPECT_TRUE(result.value().neighbors.empty());
}

using SearchMode = DescriptorDatabaseConfig::SearchMode;
class DescriptorDatabaseExactnessTest : public ::testing::TestWithParam<SearchMode> {};

// The kd-tree indexes a 16-D projection of these 64-D vectors; the answer must still be the
// brute-force one: always in kExact mode, within d_alpha in kExactWithinDAlpha mode. With a
// large kd-tree approximation (search_eps 10; the exact modes search with 0 by construction)
// the approximate mode's re-ranked candidates must still hold a near copy of a stored vector.
TEST_P(DescriptorDatabaseExactnessTest, QueryMatchesBruteForceAndAppliesDAlpha) {
  const bool exact_beyond = GetParam() == SearchMode::kExact;
  const Fixture f = RandomFixture(2000, 2);
  DescriptorDatabaseConfig config;
  config.d_alpha_ring_histogram = 0.05;
  config.search_eps = 10.0;
  config.search_mode = GetParam();
  const DescriptorDatabase db = MakeRingDatabase(f, config);
  EXPECT_EQ(db.size(), 2000u);
  std::mt19937 rng(3);
  std::normal_distribution<float> noise(0.0f, 0.002f);
  for (int t = 0; t < 50; ++t) {
    // Half the queries are noisy copies of stored scans (match), half are new places.
    PlaceDescriptor q = RandomDescriptor(&rng);
    if (t % 2 == 0) {
      q = f.descriptors[static_cast<std::size_t>(t * 37)];
      for (float& v : q.key) v += noise(rng);
    }
    std::size_t expected = 0;
    const double best = BruteForceNearest(f, q, &expected);
    auto result = db.Query(q);
    ASSERT_TRUE(result.ok());
    const DatabaseQueryResult& r = result.value();
    ASSERT_EQ(r.neighbors.size(), 5u);
    if (GetParam() == SearchMode::kApproximate) {
      // Only the 64 projected candidates are compared: never better than the truth, and a
      // near copy of a stored vector is found.
      EXPECT_FALSE(r.exact);
      EXPECT_GE(r.neighbors[0].distance, best - 1e-4);
      if (t % 2 == 0) {
        EXPECT_EQ(r.neighbors[0].index, expected);
      }
      continue;
    }
    EXPECT_TRUE(r.exact);
    if (exact_beyond || best <= 0.05) {
      EXPECT_EQ(r.neighbors[0].index, expected);
      EXPECT_NEAR(r.neighbors[0].distance, best, 1e-4);
    } else {
      EXPECT_GE(r.neighbors[0].distance, best - 1e-4);  // approximate, never below the truth
    }
    for (std::size_t i = 1; i < r.neighbors.size(); ++i) {
      EXPECT_LE(r.neighbors[i - 1].distance, r.neighbors[i].distance);
    }
    EXPECT_EQ(r.matched, best <= 0.05) << "distance " << best;
    if (t % 2 == 0) {
      EXPECT_TRUE(r.matched);
      EXPECT_EQ(db.entry(r.neighbors[0].index).stamp_s, f.entries[t * 37].stamp_s);
    } else {
      EXPECT_FALSE(r.matched);  // random places are ~0.5 apart
    }
  }
}
INSTANTIATE_TEST_SUITE_P(SearchModes, DescriptorDatabaseExactnessTest,
                         ::testing::Values(SearchMode::kApproximate,
                                           SearchMode::kExactWithinDAlpha, SearchMode::kExact));

TEST(DescriptorDatabaseTest, RefusesABadSearchEps) {
  for (double eps : {-0.5, std::nan(""), 1000.0}) {
    DescriptorDatabaseConfig config;
    config.search_eps = eps;
    const Status status = config.Validate();
    EXPECT_FALSE(status.ok()) << eps;
    EXPECT_NE(status.message().find("search_eps"), std::string::npos) << status.message();
  }
  DescriptorDatabaseConfig config;
  config.search_eps = 0.0;
  EXPECT_TRUE(config.Validate().ok());
}

TEST(DescriptorDatabaseTest, RefusesWrongDescriptors) {
  const Fixture f = RandomFixture(10, 4);
  DescriptorDatabase db = MakeRingDatabase(f);
  PlaceDescriptor wrong_size;
  wrong_size.key.resize(kDim + 1);
  EXPECT_FALSE(db.Query(wrong_size).ok());
  PlaceDescriptor wrong_kind = f.descriptors[0];
  wrong_kind.kind = DescriptorKind::kScanContext;
  EXPECT_FALSE(db.Query(wrong_kind).ok());
  PlaceDescriptor nan = f.descriptors[0];
  nan.key[3] = std::nanf("");
  EXPECT_FALSE(db.Insert({{"s02", 1.0, 0}}, {nan}).ok());
  EXPECT_FALSE(db.Insert({{"s02", 1.0, 0}}, {}).ok());
  EXPECT_EQ(db.size(), 10u);  // nothing added by refused inserts
}

TEST(DescriptorDatabaseTest, SaveLoadRoundTripGivesIdenticalResults) {
  const Fixture f = RandomFixture(3000, 5);
  DescriptorDatabase db = MakeRingDatabase(f);
  // Extend with a second batch (a merged session) before saving.
  const Fixture more = RandomFixture(500, 6);
  std::vector<DatabaseEntry> entries = more.entries;
  for (DatabaseEntry& e : entries) e.session = "session with spaces";
  ASSERT_TRUE(db.Insert(entries, more.descriptors).ok());
  const std::string path = TmpPath("roundtrip.bin");
  ASSERT_TRUE(db.Save(path).ok());
  auto loaded = DescriptorDatabase::Load(path, DescriptorDatabaseConfig());
  ASSERT_TRUE(loaded.ok()) << loaded.status().message();
  const DescriptorDatabase& copy = loaded.value();
  ASSERT_EQ(copy.size(), db.size());
  EXPECT_EQ(copy.kind(), DescriptorKind::kRingHistogram);
  EXPECT_EQ(copy.key_dim(), kDim);
  for (std::size_t i = 0; i < db.size(); i += 97) {
    EXPECT_EQ(copy.entry(i).session, db.entry(i).session);
    EXPECT_EQ(copy.entry(i).stamp_s, db.entry(i).stamp_s);
    EXPECT_EQ(copy.entry(i).submap_id, db.entry(i).submap_id);
  }
  std::mt19937 rng(7);
  for (int t = 0; t < 100; ++t) {
    const PlaceDescriptor q = RandomDescriptor(&rng);
    const DatabaseQueryResult a = db.Query(q).value();
    const DatabaseQueryResult b = copy.Query(q).value();
    EXPECT_EQ(a.matched, b.matched);
    ASSERT_EQ(a.neighbors.size(), b.neighbors.size());
    for (std::size_t i = 0; i < a.neighbors.size(); ++i) {
      EXPECT_EQ(a.neighbors[i].index, b.neighbors[i].index);
      EXPECT_EQ(a.neighbors[i].distance, b.neighbors[i].distance);
    }
  }
}

std::vector<char> ReadAll(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::vector<char>(std::istreambuf_iterator<char>(in), {});
}
void WriteAll(const std::string& path, const std::vector<char>& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

TEST(DescriptorDatabaseTest, WriteToAStreamGivesTheBytesOfTheFile) {
  const DescriptorDatabase db = MakeRingDatabase(RandomFixture(50, 5));
  const std::string path = TmpPath("stream_vs_file.bin");
  ASSERT_TRUE(db.Save(path).ok());
  std::ifstream in(path, std::ios::binary);
  std::stringstream file_bytes;
  file_bytes << in.rdbuf();
  std::ostringstream stream_bytes;
  ASSERT_TRUE(db.Write(stream_bytes).ok());
  EXPECT_EQ(stream_bytes.str(), file_bytes.str());
  EXPECT_FALSE(stream_bytes.str().empty());
}

TEST(DescriptorDatabaseTest, CorruptOrTruncatedFilesAreRefusedWithTheFileName) {
  const std::string good = TmpPath("good.bin");
  ASSERT_TRUE(MakeRingDatabase(RandomFixture(200, 8)).Save(good).ok());
  const std::vector<char> bytes = ReadAll(good);
  ASSERT_GT(bytes.size(), 1000u);

  const auto expect_refused = [](const std::string& path, const std::string& problem) {
    auto loaded = DescriptorDatabase::Load(path, DescriptorDatabaseConfig());
    ASSERT_FALSE(loaded.ok()) << problem;
    const std::string& message = loaded.status().message();
    EXPECT_NE(message.find(path), std::string::npos) << message;
    EXPECT_NE(message.find(problem), std::string::npos) << message;
  };

  // One flipped bit in a descriptor value: header 40 bytes, session table 2 x 7 bytes, then
  // entries of 4 + 4 + 8 + 4 * kDim bytes with the key at +16.
  std::vector<char> flipped = bytes;
  flipped[40 + 14 + 50 * (16 + 4 * kDim) + 16 + 10] ^= 0x10;
  const std::string flipped_path = TmpPath("flipped.bin");
  WriteAll(flipped_path, flipped);
  expect_refused(flipped_path, "checksum");

  // Cut at several places, including inside the header.
  for (std::size_t cut : {std::size_t{0}, std::size_t{5}, std::size_t{30}, bytes.size() / 3,
                          bytes.size() - 4}) {
    const std::string path = TmpPath("truncated_" + std::to_string(cut) + ".bin");
    WriteAll(path, std::vector<char>(bytes.begin(), bytes.begin() + cut));
    expect_refused(path, "truncated");
  }

  // Bad magic number.
  std::vector<char> magic = bytes;
  magic[0] = 'X';
  const std::string magic_path = TmpPath("magic.bin");
  WriteAll(magic_path, magic);
  expect_refused(magic_path, "magic");

  // Unknown format version (offset 8).
  std::vector<char> version = bytes;
  version[8] = 9;
  const std::string version_path = TmpPath("version.bin");
  WriteAll(version_path, version);
  expect_refused(version_path, "version");

  // An absurd entry count (offset 32) must not allocate: refused before reading entries.
  std::vector<char> huge = bytes;
  const std::uint64_t count = 1ull << 60;
  std::memcpy(huge.data() + 32, &count, sizeof(count));
  const std::string huge_path = TmpPath("huge.bin");
  WriteAll(huge_path, huge);
  expect_refused(huge_path, "entries");

  // An absurd key dimension (offset 16).
  std::vector<char> dim = bytes;
  const std::uint32_t big_dim = 0xFFFFFFF0u;
  std::memcpy(dim.data() + 16, &big_dim, sizeof(big_dim));
  const std::string dim_path = TmpPath("dim.bin");
  WriteAll(dim_path, dim);
  expect_refused(dim_path, "corrupt header");

  // Missing file.
  expect_refused(TmpPath("does_not_exist.bin"), "cannot read");
}

TEST(DescriptorDatabaseTest, ScanContextDatabaseReranksAndGivesYaw) {
  auto sc_or = ScanContextDescriptor::Create(ScanContextConfig());
  ASSERT_TRUE(sc_or.ok());
  const ScanContextDescriptor& sc = sc_or.value();
  std::vector<LidarScan> scans;
  std::vector<DatabaseEntry> entries;
  std::vector<PlaceDescriptor> descriptors;
  for (std::uint32_t seed = 10; seed < 22; ++seed) {
    scans.push_back(msm_pr_test::ScanYard(msm_pr_test::RandomYard(seed), seed));
    entries.push_back({"s00", double(seed), static_cast<int>(seed)});
    descriptors.push_back(sc.Compute(scans.back()));
  }
  auto db_or = DescriptorDatabase::Create({}, DescriptorKind::kScanContext, 20, 20, 60);
  ASSERT_TRUE(db_or.ok()) << db_or.status().message();
  DescriptorDatabase db = std::move(db_or).value();
  ASSERT_TRUE(db.Insert(entries, descriptors).ok());
  const std::string path = TmpPath("scan_context.bin");
  ASSERT_TRUE(db.Save(path).ok());
  auto loaded = DescriptorDatabase::Load(path, DescriptorDatabaseConfig());
  ASSERT_TRUE(loaded.ok()) << loaded.status().message();
  EXPECT_EQ(loaded.value().kind(), DescriptorKind::kScanContext);
  for (std::size_t i = 0; i < scans.size(); i += 3) {
    const double yaw = 0.5 + 0.8 * static_cast<double>(i);
    const PlaceDescriptor q = sc.Compute(msm_pr_test::TurnSensor(scans[i], yaw));
    for (const DescriptorDatabase* d : {&db, &loaded.value()}) {
      const DatabaseQueryResult r = d->Query(q).value();
      ASSERT_FALSE(r.neighbors.empty());
      EXPECT_TRUE(r.matched);
      EXPECT_EQ(r.neighbors[0].index, i);
      EXPECT_LE(std::fabs(std::remainder(r.neighbors[0].yaw_rad - yaw, 2 * M_PI)),
                2 * M_PI / 60);
    }
  }
}

// Random Scan Contexts (20 x 60) with their ring keys (row means): enough entries for a deep
// ring-key tree.
Fixture RandomScanContextFixture(int count, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  Fixture f;
  for (int i = 0; i < count; ++i) {
    PlaceDescriptor d;
    d.kind = DescriptorKind::kScanContext;
    d.rows = 20;
    d.cols = 60;
    d.matrix.resize(20 * 60);
    for (float& v : d.matrix) v = u(rng) < 0.7f ? u(rng) : 0.0f;
    d.key.assign(20, 0.0f);
    for (int r = 0; r < 20; ++r) {
      for (int c = 0; c < 60; ++c) d.key[r] += d.matrix[r * 60 + c] / 60.0f;
    }
    f.entries.push_back({"s00", double(i), i / 10});
    f.descriptors.push_back(d);
  }
  return f;
}

// search_eps approximates only the ring histogram's projected tree: a Scan Context query
// returns the same neighbours with any eps. Control: on a ring-histogram database of the same
// size the same eps does change some answers, so the comparison can see it.
TEST(DescriptorDatabaseTest, SearchEpsApproximatesOnlyTheRingHistogramTree) {
  DescriptorDatabaseConfig exact_tree;
  exact_tree.search_eps = 0.0;
  DescriptorDatabaseConfig loose_tree;
  loose_tree.search_eps = 100.0;
  const Fixture sc = RandomScanContextFixture(3000, 5);
  const Fixture rh = RandomFixture(3000, 5);
  std::vector<DescriptorDatabase> sc_dbs, rh_dbs;
  for (const DescriptorDatabaseConfig& config : {exact_tree, loose_tree}) {
    auto db = DescriptorDatabase::Create(config, DescriptorKind::kScanContext, 20, 20, 60);
    ASSERT_TRUE(db.ok()) << db.status().message();
    sc_dbs.push_back(std::move(db).value());
    ASSERT_TRUE(sc_dbs.back().Insert(sc.entries, sc.descriptors).ok());
    rh_dbs.push_back(MakeRingDatabase(rh, config));
  }
  const Fixture sc_queries = RandomScanContextFixture(40, 6);
  const Fixture rh_queries = RandomFixture(40, 6);
  int rh_different = 0;
  for (std::size_t q = 0; q < 40; ++q) {
    const DatabaseQueryResult a = sc_dbs[0].Query(sc_queries.descriptors[q]).value();
    const DatabaseQueryResult b = sc_dbs[1].Query(sc_queries.descriptors[q]).value();
    ASSERT_EQ(a.neighbors.size(), b.neighbors.size());
    for (std::size_t i = 0; i < a.neighbors.size(); ++i) {
      EXPECT_EQ(a.neighbors[i].index, b.neighbors[i].index) << "query " << q;
      EXPECT_EQ(a.neighbors[i].distance, b.neighbors[i].distance) << "query " << q;
    }
    const DatabaseQueryResult c = rh_dbs[0].Query(rh_queries.descriptors[q]).value();
    const DatabaseQueryResult d = rh_dbs[1].Query(rh_queries.descriptors[q]).value();
    ASSERT_FALSE(c.neighbors.empty());
    ASSERT_FALSE(d.neighbors.empty());
    if (c.neighbors[0].index != d.neighbors[0].index) ++rh_different;
  }
  EXPECT_GT(rh_different, 0);
}

TEST(DescriptorDatabaseTest, RingHistogramDatabaseFindsTheSamePlaceDrivenBackwards) {
  auto rh_or = RingHistogramDescriptor::Create(RingHistogramDescriptorConfig());
  ASSERT_TRUE(rh_or.ok());
  const RingHistogramDescriptor& rh = rh_or.value();
  std::vector<LidarScan> scans;
  std::vector<DatabaseEntry> entries;
  std::vector<PlaceDescriptor> descriptors;
  for (std::uint32_t seed = 30; seed < 42; ++seed) {
    scans.push_back(msm_pr_test::ScanYard(msm_pr_test::RandomYard(seed), seed));
    entries.push_back({"s00", double(seed), static_cast<int>(seed)});
    descriptors.push_back(rh.Compute(scans.back()));
  }
  auto db_or = DescriptorDatabase::Create({}, DescriptorKind::kRingHistogram, rh.dimension());
  ASSERT_TRUE(db_or.ok());
  DescriptorDatabase db = std::move(db_or).value();
  ASSERT_TRUE(db.Insert(entries, descriptors).ok());
  for (std::size_t i = 0; i < scans.size(); ++i) {
    // Opposite heading, fresh sensor noise.
    LidarScan backwards = msm_pr_test::ScanYard(msm_pr_test::RandomYard(30 + i), 1000 + i);
    const DatabaseQueryResult r = db.Query(rh.Compute(msm_pr_test::TurnSensor(backwards, M_PI)))
                                      .value();
    EXPECT_TRUE(r.matched) << "distance " << r.neighbors[0].distance;
    EXPECT_EQ(r.neighbors[0].index, i);
  }
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
