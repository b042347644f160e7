// TUM trajectory files: one pose per line, `timestamp tx ty tz qx qy qz qw`, '#' comments.
// The format read by evo (evo_ape / evo_rpe tum ...), so users can check our trajectories with
// the standard tool.
#pragma once

#include <iosfwd>
#include <string>

#include "multisession_mapper/core/status.h"
#include "multisession_mapper/core/types.h"

namespace multisession_mapper {
namespace core {

/// Writes `trajectory` in TUM format (stamps with 9 decimals, translations with 6).
Status WriteTum(std::ostream& out, const Trajectory& trajectory);
Status WriteTumFile(const std::string& path, const Trajectory& trajectory);

/// Parses TUM text. Fails with the line number on a malformed line, a non-finite value or a
/// zero quaternion; stamps must be strictly increasing.
StatusOr<Trajectory> ReadTum(std::istream& in, const std::string& source_name = "<stream>");
StatusOr<Trajectory> ReadTumFile(const std::string& path);

}  // namespace core
}  // namespace multisession_mapper
