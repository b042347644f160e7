// Computes the configured kind of per-scan place descriptor (issue 6): the LocNet-style ring
// histograms (default) or Scan Context, so that the offline runner and the nodelet select the
// descriptor with one configuration field and create a matching database.
#pragma once

#include <optional>

#include "multisession_mapper/core/descriptor_database.h"
#include "multisession_mapper/core/place_descriptor.h"
#include "multisession_mapper/core/ring_histogram_descriptor.h"
#include "multisession_mapper/core/scan_context_descriptor.h"
#include "multisession_mapper/core/status.h"
#include "multisession_mapper/core/types.h"

namespace multisession_mapper {
namespace core {

struct PlaceDescriptorExtractorConfig {
  /// Which descriptor ("ring_histogram" / "scan_context" in files, see DescriptorKindName).
  DescriptorKind kind = DescriptorKind::kRingHistogram;
  RingHistogramDescriptorConfig ring_histogram;
  ScanContextConfig scan_context;

  /// OK when the selected kind's configuration is valid.
  Status Validate() const;
};

class PlaceDescriptorExtractor {
 public:
  static StatusOr<PlaceDescriptorExtractor> Create(const PlaceDescriptorExtractorConfig& config);

  /// Descriptor of one scan in the sensor frame (de-skewed, input-filtered).
  PlaceDescriptor Compute(const LidarScan& scan) const;

  /// An empty database for this extractor's descriptors (kind and sizes set from it).
  StatusOr<DescriptorDatabase> CreateDatabase(const DescriptorDatabaseConfig& config) const;

  DescriptorKind kind() const { return config_.kind; }
  int key_dim() const;
  int matrix_rows() const;  ///< 0 for ring histograms
  int matrix_cols() const;  ///< 0 for ring histograms
  const PlaceDescriptorExtractorConfig& config() const { return config_; }

 private:
  explicit PlaceDescriptorExtractor(const PlaceDescriptorExtractorConfig& config)
      : config_(config) {}
  PlaceDescriptorExtractorConfig config_;
  std::optional<RingHistogramDescriptor> ring_histogram_;
  std::optional<ScanContextDescriptor> scan_context_;
};

}  // namespace core
}  // namespace multisession_mapper
