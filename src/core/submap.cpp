#include "multisession_mapper/core/submap.h"

namespace multisession_mapper {
namespace core {

const char* SubmapStateName(SubmapState state) {
  switch (state) {
    case SubmapState::kActive:
      return "active";
    case SubmapState::kFused:
      return "fused";
  }
  return "unknown";
}

}  // namespace core
}  // namespace multisession_mapper
