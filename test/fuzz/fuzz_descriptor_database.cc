// libFuzzer target: the place-recognition database (database/descriptors.bin) through
// DescriptorDatabase::Read. The file ends with an FNV-1a checksum of the preceding bytes; the
// harness rewrites it for the mutated bytes so that mutations reach the parser behind it (the
// checksum check itself is covered by descriptor_database_test). A database that loads is
// queried once.
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <sstream>
#include <string>

#include "multisession_mapper/core/checksum.h"
#include "multisession_mapper/core/descriptor_database.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  namespace core = multisession_mapper::core;
  std::string bytes(reinterpret_cast<const char*>(data), size);
  if (bytes.size() >= 8) {
    const std::uint64_t sum = core::Fnv1a64(bytes.data(), bytes.size() - 8);
    std::memcpy(&bytes[bytes.size() - 8], &sum, 8);  // little-endian host
  }
  std::istringstream in(bytes);
  core::StatusOr<core::DescriptorDatabase> db = core::DescriptorDatabase::Read(
      in, bytes.size(), "fuzz.bin", core::DescriptorDatabaseConfig());
  if (!db.ok() || db.value().kind() != core::DescriptorKind::kRingHistogram) return 0;
  core::PlaceDescriptor query;
  query.kind = core::DescriptorKind::kRingHistogram;
  query.key.assign(static_cast<std::size_t>(db.value().key_dim()), 0.1f);
  core::StatusOr<core::DatabaseQueryResult> result = db.value().Query(query);
  (void)result;
  return 0;
}
