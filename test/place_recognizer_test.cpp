#include "multisession_mapper/core/place_recognizer.h"

#include <sstream>

#include <gtest/gtest.h>

#include "place_recognition_test_scans.h"

namespace multisession_mapper {
namespace core {
namespace {

// Session "day1" visits 4 yards (one submap each); session "day2" revisits yards 0 and 2
// (turned around) and visits one new yard. The history votes must point at the right submaps,
// and the new yard must not match.
class PlaceRecognizerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    for (std::uint32_t i = 0; i < 4; ++i) yards_.push_back(msm_pr_test::RandomYard(10 + i));
    StatusOr<PlaceRecognizer> day1 = PlaceRecognizer::Create(config_, "day1", nullptr);
    ASSERT_TRUE(day1.ok()) << day1.status().message();
    for (std::uint32_t submap = 0; submap < 4; ++submap) {
      for (int k = 0; k < 3; ++k) {
        LidarScan scan = msm_pr_test::ScanYard(yards_[submap], 100 * submap + k);
        scan.stamp_s = 1000.0 + 10 * submap + k;
        ASSERT_TRUE(day1.value().AddScan(scan, submap).ok());
      }
    }
    EXPECT_TRUE(day1.value().QueriesCsv().empty()) << "no history: nothing to log";
    StatusOr<DescriptorDatabase> db = day1.value().NewDatabase();
    ASSERT_TRUE(db.ok());
    ASSERT_TRUE(day1.value().AppendTo(&db.value()).ok());
    ASSERT_EQ(db.value().size(), 12u);
    history_ = std::make_shared<const DescriptorDatabase>(std::move(db.value()));
  }

  PlaceRecognizerConfig config_;
  std::vector<msm_pr_test::Yard> yards_;
  std::shared_ptr<const DescriptorDatabase> history_;
};

TEST_F(PlaceRecognizerTest, RevisitsVoteForTheRightHistorySubmaps) {
  StatusOr<PlaceRecognizer> day2 = PlaceRecognizer::Create(config_, "day2", history_);
  ASSERT_TRUE(day2.ok()) << day2.status().message();
  const std::vector<std::pair<std::uint32_t, int>> plan = {{0, 0}, {1, 2}, {2, -1}};
  for (const auto& [submap, yard] : plan) {
    for (int k = 0; k < 3; ++k) {
      const msm_pr_test::Yard place = yard >= 0 ? yards_[yard] : msm_pr_test::RandomYard(99);
      LidarScan scan = msm_pr_test::TurnSensor(msm_pr_test::ScanYard(place, 500 + 10 * submap + k),
                                               2.5 + k);
      scan.stamp_s = 2000.0 + 10 * submap + k;
      ASSERT_TRUE(day2.value().AddScan(scan, submap).ok());
    }
  }
  for (const auto& [submap, yard] : plan) {
    const std::vector<ScanVote> votes = day2.value().VotesOf(submap);
    ASSERT_EQ(votes.size(), 3u);
    for (const ScanVote& vote : votes) {
      if (yard < 0) {
        EXPECT_FALSE(vote.matched) << "a new place must not match";
      } else {
        ASSERT_TRUE(vote.matched) << "submap " << submap;
        EXPECT_EQ(vote.history.session, "day1");
        EXPECT_EQ(vote.history.submap_id, yard);
      }
    }
  }
  EXPECT_EQ(day2.value().query_ms().size(), 9u);
  EXPECT_EQ(day2.value().descriptor_ms().size(), 9u);
  // The log: header plus one row per query, the nearest history scan filled in.
  std::istringstream csv(day2.value().QueriesCsv());
  std::string line;
  std::getline(csv, line);
  EXPECT_EQ(line, "stamp,submap,matched,history_session,history_stamp,distance,top_k");
  int rows = 0;
  while (std::getline(csv, line)) {
    ++rows;
    EXPECT_NE(line.find(",day1,"), std::string::npos) << line;
  }
  EXPECT_EQ(rows, 9);
}

TEST_F(PlaceRecognizerTest, MismatchedDatabaseKindIsRefused) {
  PlaceRecognizerConfig scan_context = config_;
  scan_context.descriptor.kind = DescriptorKind::kScanContext;
  StatusOr<PlaceRecognizer> r = PlaceRecognizer::Create(scan_context, "day2", history_);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("ring_histogram"), std::string::npos);
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
