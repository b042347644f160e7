// dynamic_reconfigure configs <-> core config structs, one function pair per nodelet. The
// nodelets load cfg/default.yaml (or the file in their `config` parameter) with
// core::LoadPipelineConfig, turn it into their dynamic_reconfigure config with To*Config (the
// initial values the user sees in rqt_reconfigure), and map every change back with Apply*.
// Parameters that exist only on the ROS side (e.g. MapMerging's idle_finish_s) keep their .cfg
// defaults in To*Config and are read by the nodelet itself.
// test/parameter_mapping_test.cpp checks that every .cfg default equals cfg/default.yaml and
// that every parameter round-trips through the core struct.
#pragma once

#include <multisession_mapper/MapMergingConfig.h>
#include <multisession_mapper/PlaceRecognitionConfig.h>
#include <multisession_mapper/ScanMatchingConfig.h>
#include <multisession_mapper/SubmapManagerConfig.h>

#include "multisession_mapper/core/inter_session_matcher.h"
#include "multisession_mapper/core/odometry.h"
#include "multisession_mapper/core/place_recognizer.h"
#include "multisession_mapper/core/session_mapper.h"
#include "multisession_mapper/core/session_merger.h"

namespace multisession_mapper {
namespace ros_params {

ScanMatchingConfig ToScanMatchingConfig(const core::OdometryConfig& odometry);
void ApplyScanMatchingConfig(const ScanMatchingConfig& config, core::OdometryConfig* odometry);

SubmapManagerConfig ToSubmapManagerConfig(const core::SessionMapperConfig& session);
void ApplySubmapManagerConfig(const SubmapManagerConfig& config,
                              core::SessionMapperConfig* session);

PlaceRecognitionConfig ToPlaceRecognitionConfig(const core::PlaceRecognizerConfig& recognizer,
                                                const core::InterSessionMatcherConfig& matching);
void ApplyPlaceRecognitionConfig(const PlaceRecognitionConfig& config,
                                 core::PlaceRecognizerConfig* recognizer,
                                 core::InterSessionMatcherConfig* matching);

/// The voting part (matching.voting, matching.neighbour_distance_m) belongs to
/// PlaceRecognitionConfig and is neither read nor written here.
MapMergingConfig ToMapMergingConfig(const core::SessionMergerConfig& merge);
void ApplyMapMergingConfig(const MapMergingConfig& config, core::SessionMergerConfig* merge);

}  // namespace ros_params
}  // namespace multisession_mapper
