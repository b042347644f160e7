// libFuzzer target: a whole map directory. The input is a container of files
// (`=== <relative path>\n<content>` sections, fuzz_common.h) written into an empty folder; the
// harness appends the manifest's `files:` list (sizes and checksums of the files actually
// written, unless the input's manifest has its own), so mutations of any file reach its parser
// instead of stopping at the checksum check. MapStore::Load must return a Status; the trajectory
// files are also read with ReadTumFile.
#include <cstddef>
#include <cstdint>
#include <sstream>
#include <string>

#include "fuzz_common.h"
#include "multisession_mapper/core/checksum.h"
#include "multisession_mapper/core/trajectory_io.h"

namespace {

// Only plain relative paths of at most three short components are written.
bool PlainRelativePath(const std::string& path) {
  if (path.empty() || path.size() > 100 || path.front() == '/') return false;
  std::stringstream parts(path);
  std::string part;
  int count = 0;
  while (std::getline(parts, part, '/')) {
    if (part.empty() || part == "." || part == ".." || ++count > 3) return false;
    for (char c : part) {
      if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.')) {
        return false;
      }
    }
  }
  return path.back() != '/';
}

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
  namespace fs = std::filesystem;
  const fs::path dir = msm::fuzz::ScratchDir() / "dir_map";
  std::error_code ec;
  for (const char* suffix : {"", ".new", ".old"}) fs::remove_all(dir.string() + suffix, ec);
  fs::create_directories(dir);
  std::string manifest;
  std::string file_list = "files:\n";
  int written = 0;
  for (const auto& [rel, content] :
       msm::fuzz::SplitContainer(std::string(reinterpret_cast<const char*>(data), size))) {
    if (!PlainRelativePath(rel) || ++written > 64) continue;
    if (rel == "manifest.yaml") {
      manifest = content;
      continue;
    }
    if (fs::exists(dir / rel, ec) || (fs::exists((dir / rel).parent_path(), ec) &&
                                      !fs::is_directory((dir / rel).parent_path(), ec))) {
      continue;
    }
    msm::fuzz::WriteFile(dir / rel, content);
    file_list += "  " + rel + ": {bytes: " + std::to_string(content.size()) + ", fnv1a64: " +
                 Hex(msm::core::Fnv1a64(content)) + "}\n";
  }
  if (manifest.find("\nfiles:") == std::string::npos && manifest.rfind("files:", 0) != 0) {
    if (!manifest.empty() && manifest.back() != '\n') manifest += '\n';
    manifest += file_list;
  }
  msm::fuzz::WriteFile(dir / "manifest.yaml", manifest);
  const msm::core::StatusOr<msm::core::MapContents> map = msm::core::MapStore().Load(dir.string());
  (void)map;
  for (const auto& entry : fs::directory_iterator(dir / "trajectories", ec)) {
    const msm::core::StatusOr<msm::core::Trajectory> t =
        msm::core::ReadTumFile(entry.path().string());
    (void)t;
  }
  return 0;
}
