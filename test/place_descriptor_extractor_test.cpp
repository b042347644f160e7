#include "place_recognition_test_scans.h"  // first: defines PCL_NO_PRECOMPILE

#include <gtest/gtest.h>

#include "multisession_mapper/core/place_descriptor_extractor.h"

namespace multisession_mapper {
namespace core {
namespace {

TEST(PlaceDescriptorExtractorTest, KindNamesRoundTrip) {
  for (DescriptorKind kind : {DescriptorKind::kRingHistogram, DescriptorKind::kScanContext}) {
    DescriptorKind parsed = DescriptorKind::kRingHistogram;
    ASSERT_TRUE(DescriptorKindFromName(DescriptorKindName(kind), &parsed));
    EXPECT_EQ(parsed, kind);
  }
  DescriptorKind parsed = DescriptorKind::kScanContext;
  EXPECT_FALSE(DescriptorKindFromName("locnet", &parsed));
  EXPECT_EQ(parsed, DescriptorKind::kScanContext);  // untouched
}

TEST(PlaceDescriptorExtractorTest, RefusesAnInvalidSelectedConfig) {
  PlaceDescriptorExtractorConfig config;
  config.ring_histogram.range_bins = 0;
  EXPECT_FALSE(PlaceDescriptorExtractor::Create(config).ok());
  config.kind = DescriptorKind::kScanContext;  // the broken ring histogram config is not used
  EXPECT_TRUE(PlaceDescriptorExtractor::Create(config).ok());
}

TEST(PlaceDescriptorExtractorTest, EachKindFillsAMatchingDatabase) {
  const LidarScan scan = msm_pr_test::ScanYard(msm_pr_test::RandomYard(3), 3);
  for (DescriptorKind kind : {DescriptorKind::kRingHistogram, DescriptorKind::kScanContext}) {
    PlaceDescriptorExtractorConfig config;
    config.kind = kind;
    auto extractor = PlaceDescriptorExtractor::Create(config);
    ASSERT_TRUE(extractor.ok()) << extractor.status().message();
    const PlaceDescriptor d = extractor.value().Compute(scan);
    EXPECT_EQ(d.kind, kind);
    EXPECT_EQ(static_cast<int>(d.key.size()), extractor.value().key_dim());
    EXPECT_EQ(d.rows, extractor.value().matrix_rows());
    EXPECT_EQ(d.cols, extractor.value().matrix_cols());
    auto db = extractor.value().CreateDatabase(DescriptorDatabaseConfig());
    ASSERT_TRUE(db.ok()) << db.status().message();
    ASSERT_TRUE(db.value().Insert({{"s00", 1.0, 0}}, {d}).ok());
    const PlaceDescriptor turned = extractor.value().Compute(msm_pr_test::TurnSensor(scan, 2.0));
    auto result = db.value().Query(turned);
    ASSERT_TRUE(result.ok()) << result.status().message();
    EXPECT_TRUE(result.value().matched) << DescriptorKindName(kind);
  }
}

}  // namespace
}  // namespace core
}  // namespace multisession_mapper
