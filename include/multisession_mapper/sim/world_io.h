// world.yaml: the simulator's ground-truth description of the world (docs/simulator.md).
// Written as plain text with fixed decimals (byte-identical for the same seed), read back with
// yaml-cpp.
#pragma once

#include <iosfwd>
#include <string>

#include "multisession_mapper/core/status.h"
#include "multisession_mapper/sim/world.h"

namespace multisession_mapper {
namespace sim {

/// Positions and sizes are written with 6 decimals [m], angles with 9 [rad], stamps with 6 [s],
/// terrain heights with 3 [m].
core::Status WriteWorldYaml(std::ostream& out, const World& world);
core::Status WriteWorldYamlFile(const std::string& path, const World& world);

/// Parses and validates a world file; errors name the object and field.
core::StatusOr<World> ReadWorldYaml(const std::string& text);
core::StatusOr<World> ReadWorldYamlFile(const std::string& path);

}  // namespace sim
}  // namespace multisession_mapper
