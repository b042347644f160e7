// FNV-1a 64-bit checksum (Fowler, Noll, Vo), used by the map store's file list and the
// descriptor database's file trailer to detect truncated or corrupted files. Not
// cryptographic: it guards against accidents, not against tampering.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

namespace multisession_mapper {
namespace core {

constexpr std::uint64_t kFnv1a64Offset = 1469598103934665603ull;

/// Continues the checksum `hash` over `size` bytes; start with kFnv1a64Offset.
inline std::uint64_t Fnv1a64(const void* data, std::size_t size,
                             std::uint64_t hash = kFnv1a64Offset) {
  constexpr std::uint64_t kPrime = 1099511628211ull;
  const auto* bytes = static_cast<const unsigned char*>(data);
  for (std::size_t i = 0; i < size; ++i) hash = (hash ^ bytes[i]) * kPrime;
  return hash;
}

inline std::uint64_t Fnv1a64(const std::string& bytes) {
  return Fnv1a64(bytes.data(), bytes.size());
}

}  // namespace core
}  // namespace multisession_mapper
