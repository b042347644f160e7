// libFuzzer target: manifest.yaml of a map directory. The input replaces the manifest of a small
// valid map (fuzz_common.h); MapStore::Load must return a Status, never crash. The seeds are
// valid manifests of that map, so mutations keep reaching the parts after the file checks.
#include <cstddef>
#include <cstdint>
#include <string>

#include "fuzz_common.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  namespace msm = multisession_mapper;
  const auto dir = msm::fuzz::FreshMapCopy();
  msm::fuzz::WriteFile(dir / "manifest.yaml",
                       std::string(reinterpret_cast<const char*>(data), size));
  const msm::core::StatusOr<msm::core::MapContents> map = msm::core::MapStore().Load(dir.string());
  if (map.ok()) {
    // A loaded map must be usable: every submap has its points, every pose is finite.
    for (const msm::core::Submap& submap : map.value().submaps) {
      if (!submap.T_map_submap.matrix().allFinite()) __builtin_trap();
    }
  }
  return 0;
}
