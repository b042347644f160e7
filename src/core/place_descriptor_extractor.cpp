#include "multisession_mapper/core/place_descriptor_extractor.h"

#include <string>

namespace multisession_mapper {
namespace core {

Status PlaceDescriptorExtractorConfig::Validate() const {
  switch (kind) {
    case DescriptorKind::kRingHistogram:
      return ring_histogram.Validate();
    case DescriptorKind::kScanContext:
      return scan_context.Validate();
  }
  return Status::Error("place_descriptor.kind: unknown descriptor kind " +
                       std::to_string(static_cast<std::uint32_t>(kind)));
}

StatusOr<PlaceDescriptorExtractor> PlaceDescriptorExtractor::Create(
    const PlaceDescriptorExtractorConfig& config) {
  Status status = config.Validate();
  if (!status.ok()) return status;
  PlaceDescriptorExtractor extractor(config);
  if (config.kind == DescriptorKind::kRingHistogram) {
    extractor.ring_histogram_.emplace(
        RingHistogramDescriptor::Create(config.ring_histogram).value());
  } else {
    extractor.scan_context_.emplace(ScanContextDescriptor::Create(config.scan_context).value());
  }
  return extractor;
}

PlaceDescriptor PlaceDescriptorExtractor::Compute(const LidarScan& scan) const {
  return ring_histogram_ ? ring_histogram_->Compute(scan) : scan_context_->Compute(scan);
}

int PlaceDescriptorExtractor::key_dim() const {
  return ring_histogram_ ? ring_histogram_->dimension() : config_.scan_context.num_rings;
}
int PlaceDescriptorExtractor::matrix_rows() const {
  return ring_histogram_ ? 0 : config_.scan_context.num_rings;
}
int PlaceDescriptorExtractor::matrix_cols() const {
  return ring_histogram_ ? 0 : config_.scan_context.num_sectors;
}

StatusOr<DescriptorDatabase> PlaceDescriptorExtractor::CreateDatabase(
    const DescriptorDatabaseConfig& config) const {
  DescriptorDatabaseConfig with_sizes = config;
  with_sizes.scan_context = config_.scan_context;  // compare Scan Contexts as they were built
  return DescriptorDatabase::Create(with_sizes, kind(), key_dim(), matrix_rows(), matrix_cols());
}

}  // namespace core
}  // namespace multisession_mapper
