// The per-scan place descriptor shared by the two descriptor modules and the database.
// A descriptor has a `key` (the vector indexed by the kd-tree) and, for kinds that re-rank the
// kd-tree's candidates with a finer distance, a row-major `matrix`:
//  - kRingHistogram (ring_histogram_descriptor.h): key = the whole descriptor, matrix empty;
//    the distance is the Euclidean distance between keys.
//  - kScanContext (scan_context_descriptor.h): key = ring key (one value per ring), matrix =
//    the rings x sectors Scan Context; the distance is the column-shift distance.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace multisession_mapper {
namespace core {

enum class DescriptorKind : std::uint32_t {
  kRingHistogram = 1,  ///< LocNet-style rotation-invariant ring histograms (default)
  kScanContext = 2,    ///< Scan Context (Kim & Kim, IROS 2018)
};

/// "ring_histogram" / "scan_context" (the names used in configuration files).
inline const char* DescriptorKindName(DescriptorKind kind) {
  switch (kind) {
    case DescriptorKind::kRingHistogram:
      return "ring_histogram";
    case DescriptorKind::kScanContext:
      return "scan_context";
  }
  return "unknown";
}

/// Inverse of DescriptorKindName; false for an unknown name.
inline bool DescriptorKindFromName(const std::string& name, DescriptorKind* kind) {
  if (name == "ring_histogram") {
    *kind = DescriptorKind::kRingHistogram;
  } else if (name == "scan_context") {
    *kind = DescriptorKind::kScanContext;
  } else {
    return false;
  }
  return true;
}

struct PlaceDescriptor {
  DescriptorKind kind = DescriptorKind::kRingHistogram;
  std::vector<float> key;     ///< indexed by the kd-tree
  std::vector<float> matrix;  ///< row-major rows x cols; empty for kRingHistogram
  int rows = 0;
  int cols = 0;
};

}  // namespace core
}  // namespace multisession_mapper
