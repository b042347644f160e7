// The configuration of the whole pipeline as one YAML file (cfg/default.yaml documents every
// key with its unit). The offline runner reads it with --config; the nodelets load the same file
// as their initial parameters, so online and offline runs match. Unknown keys are errors: a
// typo must not silently leave a default in place.
#pragma once

#include <string>

#include "multisession_mapper/core/place_recognizer.h"
#include "multisession_mapper/core/session_mapper.h"
#include "multisession_mapper/core/session_merger.h"
#include "multisession_mapper/core/status.h"

namespace multisession_mapper {
namespace core {

struct PipelineConfig {
  SessionMapperConfig session;
  PlaceRecognizerConfig place_recognition;
  SessionMergerConfig merge;

  Status Validate() const {
    Status s = session.Validate();
    if (s.ok()) s = place_recognition.Validate();
    return s.ok() ? merge.Validate() : s;
  }
};

/// Overrides the defaults with the keys present in `yaml_text`. `source` names the file in
/// errors.
StatusOr<PipelineConfig> PipelineConfigFromYaml(const std::string& yaml_text,
                                                const std::string& source);
StatusOr<PipelineConfig> LoadPipelineConfig(const std::string& path);

/// Every key with its current value (the manifest records it with the map).
std::string PipelineConfigToYaml(const PipelineConfig& config);

}  // namespace core
}  // namespace multisession_mapper
