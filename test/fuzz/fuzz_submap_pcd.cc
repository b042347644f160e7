// libFuzzer target: a submap PCD file. The input replaces submaps/a/0.pcd of a small valid map
// and the manifest's size/checksum of that file are updated, so the bytes reach the PCD reader of
// MapStore::Load, which must return a Status.
#include <cstddef>
#include <cstdint>
#include <sstream>
#include <string>

#include <yaml-cpp/yaml.h>

#include "fuzz_common.h"
#include "multisession_mapper/core/checksum.h"

namespace {

std::string Hex(std::uint64_t v) {
  std::ostringstream out;
  out << std::hex;
  out.width(16);
  out.fill('0');
  out << v;
  return out.str();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  namespace msm = multisession_mapper;
  const std::string bytes(reinterpret_cast<const char*>(data), size);
  const auto dir = msm::fuzz::FreshMapCopy();
  const std::string rel = "submaps/a/0.pcd";
  msm::fuzz::WriteFile(dir / rel, bytes);
  YAML::Node manifest = YAML::Load(msm::fuzz::ReadFile(dir / "manifest.yaml"));
  manifest["files"][rel]["bytes"] = static_cast<std::uint64_t>(size);
  manifest["files"][rel]["fnv1a64"] = Hex(msm::core::Fnv1a64(bytes));
  YAML::Emitter out;
  out << manifest;
  msm::fuzz::WriteFile(dir / "manifest.yaml", std::string(out.c_str()) + "\n");
  const msm::core::StatusOr<msm::core::MapContents> map = msm::core::MapStore().Load(dir.string());
  if (map.ok()) {
    for (const msm::core::Submap& submap : map.value().submaps) {
      for (const Eigen::Vector3d& p : submap.points) {
        if (!p.allFinite()) __builtin_trap();  // the loader promises finite points
      }
    }
  }
  return 0;
}
