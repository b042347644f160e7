// Wall-clock timing of pipeline stages (steady clock), shared by every module that records
// per-stage seconds in its results and timing records.
#pragma once

#include <chrono>

namespace multisession_mapper {
namespace core {

/// Seconds of steady-clock time since `start`.
inline double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace core
}  // namespace multisession_mapper
