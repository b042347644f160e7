#include "multisession_mapper/ros/parameter_mapping.h"

namespace multisession_mapper {
namespace ros_params {

// Each list names a dynamic_reconfigure field and the core field it drives; the same list
// generates both directions, so they cannot disagree.
#define MSM_TO_CFG(name, field) out.name = field;
#define MSM_TO_CORE(name, field) field = in.name;

#define MSM_SCAN_MATCHING_FIELDS(F)                                          \
  F(input_filter_min_range_m, o.input_filter.min_range_m)                    \
  F(input_filter_max_range_m, o.input_filter.max_range_m)                    \
  F(odometry_map_voxel_size_m, o.map_voxel_size_m)                           \
  F(odometry_registration_voxel_size_m, o.registration_voxel_size_m)         \
  F(odometry_high_point_min_height_m, o.high_point_min_height_m)             \
  F(odometry_high_point_max_normal_z, o.high_point_max_normal_z)             \
  F(odometry_map_ground_min_depth_m, o.map_ground_min_depth_m)               \
  F(odometry_map_ground_min_normal_z, o.map_ground_min_normal_z)             \
  F(odometry_max_scan_gap_s, o.max_scan_gap_s)                               \
  F(odometry_motion_prior_weight, o.motion_prior_weight)

#define MSM_SUBMAP_MANAGER_FIELDS(F)                                                        \
  F(submap_max_translation_m, s.submaps.max_translation_m)                                  \
  F(submap_max_rotation_rad, s.submaps.max_rotation_rad)                                    \
  F(submap_voxel_size_m, s.submaps.voxel_size_m)                                            \
  F(submap_max_point_range_m, s.submaps.max_point_range_m)                                  \
  F(submap_break_on_jump_m, s.submaps.break_on_jump_m)                                      \
  F(submap_robust_height, s.submaps.robust_height)                                          \
  F(in_session_dynamics_enabled, s.submaps.dynamic_filter.enabled)                          \
  F(in_session_dynamics_margin_base_m, s.submaps.dynamic_filter.margin_base_m)              \
  F(in_session_dynamics_margin_per_m, s.submaps.dynamic_filter.margin_per_m)                \
  F(in_session_dynamics_max_check_range_m, s.submaps.dynamic_filter.max_check_range_m)      \
  F(in_session_dynamics_near_range_m, s.submaps.dynamic_filter.near_range_m)                \
  F(in_session_dynamics_check_every_n_scans, s.submaps.dynamic_filter.check_every_n_scans)  \
  F(in_session_dynamics_min_seen_through, s.submaps.dynamic_filter.min_seen_through)        \
  F(in_session_dynamics_min_seen_through_ratio,                                             \
    s.submaps.dynamic_filter.min_seen_through_ratio)                                        \
  F(in_session_dynamics_min_consecutive_seen_through,                                       \
    s.submaps.dynamic_filter.min_consecutive_seen_through)                                  \
  F(in_session_dynamics_tail_m, s.submaps.dynamic_filter.tail_m)                            \
  F(in_session_dynamics_grow_depth, s.submaps.dynamic_filter.grow_depth)                    \
  F(in_session_dynamics_grow_max_scan_gap, s.submaps.dynamic_filter.grow_max_scan_gap)      \
  F(in_session_dynamics_grow_over_measured_ground,                                          \
    s.submaps.dynamic_filter.grow_over_measured_ground)                                     \
  F(in_session_dynamics_drop_residue_under_removed,                                         \
    s.submaps.dynamic_filter.drop_residue_under_removed)                                    \
  F(in_session_dynamics_residue_min_rise_m, s.submaps.dynamic_filter.residue_min_rise_m)    \
  F(in_session_dynamics_past_checks, s.submaps.dynamic_filter.past_checks)                  \
  F(in_session_dynamics_past_check_stride, s.submaps.dynamic_filter.past_check_stride)      \
  F(in_session_dynamics_group_min_seen_through_ratio,                                           \
    s.submaps.dynamic_filter.groups.min_seen_through_ratio)                                 \
  F(in_session_dynamics_group_min_seen_voxel_fraction,                                      \
    s.submaps.dynamic_filter.groups.min_seen_voxel_fraction)                                \
  F(in_session_dynamics_group_min_voxels, s.submaps.dynamic_filter.groups.min_voxels)       \
  F(in_session_dynamics_group_min_height_m, s.submaps.dynamic_filter.groups.min_height_m)   \
  F(in_session_dynamics_group_ground_cell_m, s.submaps.dynamic_filter.groups.ground_cell_m) \
  F(in_session_dynamics_group_coarse_ground_cell_m,                                         \
    s.submaps.dynamic_filter.groups.coarse_ground_cell_m)                                   \
  F(in_session_dynamics_group_coarse_min_height_m,                                          \
    s.submaps.dynamic_filter.groups.coarse_min_height_m)                                    \
  F(in_session_dynamics_group_min_nearest_range_m,                                          \
    s.submaps.dynamic_filter.groups.min_nearest_range_m)                                    \
  F(in_session_dynamics_group_plane_min_height_m,                                           \
    s.submaps.dynamic_filter.groups.plane_min_height_m)                                     \
  F(in_session_dynamics_group_plane_fit_max_range_m,                                        \
    s.submaps.dynamic_filter.groups.plane_fit_max_range_m)                                  \
  F(in_session_dynamics_no_return_free_range_m,                                             \
    s.submaps.dynamic_filter.range_image.no_return_free_range_m)                            \
  F(in_session_dynamics_angular_uncertainty_rad,                                            \
    s.submaps.dynamic_filter.range_image.angular_uncertainty_rad)                           \
  F(in_session_dynamics_edge_guard_columns,                                                 \
    s.submaps.dynamic_filter.range_image.edge_guard_columns)                                \
  F(intra_session_pairs_enabled, s.intra_pairs.enabled)                                     \
  F(intra_session_pairs_neighbours, s.intra_pairs.neighbours)                               \
  F(intra_session_pairs_min_pass_incidence_rad, s.intra_pairs.min_pass_incidence_rad)       \
  F(intra_session_pairs_min_cluster_coarse_fraction,                                        \
    s.intra_pairs.min_cluster_coarse_fraction)                                              \
  F(intra_session_pairs_own_ground_max_gap_m, s.intra_pairs.own_ground_max_gap_m)           \
  F(intra_session_pairs_changed_objects_enabled, s.intra_pairs.changed_objects_enabled)     \
  F(intra_session_pairs_far_range_m, s.intra_pairs.far_range_m)                             \
  F(intra_loops_enabled, s.intra_loops.enabled)                                             \
  F(intra_loops_search_radius_m, s.intra_loops.search_radius_m)                             \
  F(intra_loops_min_id_gap, s.intra_loops.min_id_gap)                                       \
  F(intra_loops_max_candidates, s.intra_loops.max_candidates)                               \
  F(intra_loops_overlap_distance_m, s.intra_loops.registration.overlap_distance_m)          \
  F(intra_loops_min_overlap_ratio, s.intra_loops.registration.min_overlap_ratio)            \
  F(intra_loops_max_correction_m, s.intra_loops.registration.max_correction_m)              \
  F(intra_loops_max_correction_rad, s.intra_loops.registration.max_correction_rad)          \
  F(intra_loops_loop_sigma_translation_m, s.intra_loops.registration.loop_sigma_translation_m) \
  F(intra_loops_loop_sigma_rotation_rad, s.intra_loops.registration.loop_sigma_rotation_rad)   \
  F(pose_graph_loop_kernel_scale, s.pose_graph.loop_kernel_scale)                           \
  F(pose_graph_loop_outlier_chi2, s.pose_graph.loop_outlier_chi2)                           \
  F(pose_graph_odometry_sigma_translation_m, s.odometry_sigma_translation_m)                \
  F(pose_graph_odometry_sigma_translation_per_m, s.odometry_sigma_translation_per_m)        \
  F(pose_graph_odometry_sigma_rotation_rad, s.odometry_sigma_rotation_rad)                  \
  F(pose_graph_vertical_priors, s.vertical_structure.enabled)                               \
  F(pose_graph_vertical_sigma_rad, s.vertical_structure.sigma_rad)                         \
  F(pose_graph_vertical_min_height_m, s.vertical_structure.min_height_m)                   \
  F(pose_graph_vertical_min_wall_points, s.vertical_structure.min_wall_points)

#define MSM_PLACE_RECOGNITION_FIELDS(F)                                                  \
  F(place_recognition_d_alpha_ring_histogram, p.database.d_alpha_ring_histogram)         \
  F(place_recognition_d_alpha_scan_context, p.database.d_alpha_scan_context)             \
  F(place_recognition_search_eps, p.database.search_eps)                                 \
  F(place_recognition_log_neighbours, p.log_neighbours)                                  \
  F(inter_session_gamma, m.voting.gamma)                                                 \
  F(inter_session_top_n, m.voting.top_n)                                                 \
  F(inter_session_min_matched_scans, m.voting.min_matched_scans)                         \
  F(inter_session_neighbour_distance_m, m.neighbour_distance_m)

#define MSM_MAP_MERGING_FIELDS(F)                                                             \
  F(inter_session_overlap_distance_m, g.matching.registration.fine.overlap_distance_m)        \
  F(inter_session_min_overlap_ratio, g.matching.registration.fine.min_overlap_ratio)          \
  F(inter_session_consistency_max_translation_m, g.matching.consistency.max_translation_m)    \
  F(inter_session_consistency_max_rotation_rad, g.matching.consistency.max_rotation_rad)      \
  F(inter_session_consistency_min_group_size, g.matching.consistency.min_group_size)          \
  F(inter_session_consistency_min_secondary_submaps,                                          \
    g.matching.consistency.min_secondary_submaps)                                             \
  F(inter_session_consistency_secondary_translation_per_m,                                    \
    g.matching.consistency.secondary_translation_per_m)                                       \
  F(inter_session_consistency_secondary_rotation_per_m,                                       \
    g.matching.consistency.secondary_rotation_per_m)                                          \
  F(inter_session_consistency_same_submap_translation_m,                                      \
    g.matching.consistency.same_submap_translation_m)                                         \
  F(inter_session_consistency_same_submap_rotation_rad,                                       \
    g.matching.consistency.same_submap_rotation_rad)                                          \
  F(inter_session_consistency_neighbour_path_m, g.matching.consistency.neighbour_path_m)      \
  F(inter_session_sequence_max_gap_submaps, g.matching.sequence.max_gap_submaps)              \
  F(inter_session_sequence_chain, g.matching.sequence.chain)                                  \
  F(inter_session_sequence_max_candidates, g.matching.sequence.max_candidates)                \
  F(inter_session_sequence_search_radius_m, g.matching.sequence.search_radius_m)              \
  F(inter_session_guided_candidates, g.matching.guided_candidates)                            \
  F(inter_session_loop_sigma_translation_m, g.inter_sigma_translation_m)                      \
  F(inter_session_loop_sigma_rotation_rad, g.inter_sigma_rotation_rad)                        \
  F(registration_coarse_voxel_m, g.matching.registration.coarse_voxel_m)                      \
  F(registration_ransac_inlier_distance_m, g.matching.registration.ransac_inlier_distance_m)  \
  F(registration_min_ransac_inliers, g.matching.registration.min_ransac_inliers)              \
  F(registration_max_tilt_rad, g.matching.registration.max_tilt_rad)                          \
  F(registration_structure_overlap_distance_m,                                                \
    g.matching.registration.structure_overlap_distance_m)                                     \
  F(registration_min_structure_overlap_ratio,                                                 \
    g.matching.registration.min_structure_overlap_ratio)                                      \
  F(proximity_loops_enabled, g.proximity.enabled)                                             \
  F(proximity_loops_search_radius_m, g.proximity.search_radius_m)                             \
  F(proximity_loops_max_candidates, g.proximity.max_candidates)                               \
  F(proximity_loops_overlap_distance_m, g.proximity.registration.overlap_distance_m)          \
  F(proximity_loops_min_overlap_ratio, g.proximity.registration.min_overlap_ratio)            \
  F(proximity_loops_max_correction_m, g.proximity.registration.max_correction_m)              \
  F(proximity_loops_max_correction_rad, g.proximity.registration.max_correction_rad)          \
  F(low_dynamics_seed_distance_m, g.dynamics.seed_distance_m)                                 \
  F(low_dynamics_grow_radius_m, g.dynamics.grow_radius_m)                                     \
  F(low_dynamics_grow_max_normal_angle_rad, g.dynamics.grow_max_normal_angle_rad)             \
  F(low_dynamics_voxel_size_m, g.dynamics.voxel_size_m)                                       \
  F(low_dynamics_height_guard_enabled, g.dynamics.height_guard_enabled)                       \
  F(low_dynamics_height_guard_m, g.dynamics.height_guard_m)                                   \
  F(low_dynamics_max_object_bottom_m, g.dynamics.max_object_bottom_m)                         \
  F(low_dynamics_far_range_m, g.dynamics.far_range_m)                                         \
  F(low_dynamics_far_ground_cell_m, g.dynamics.far_ground_cell_m)                             \
  F(low_dynamics_far_max_bottom_m, g.dynamics.far_max_bottom_m)                               \
  F(low_dynamics_bottom_extension_radius_m, g.dynamics.bottom_extension_radius_m)             \
  F(low_dynamics_bottom_min_height_m, g.dynamics.bottom_min_height_m)                         \
  F(low_dynamics_bottom_max_drop_m, g.dynamics.bottom_max_drop_m)                             \
  F(low_dynamics_changed_objects_enabled, g.dynamics.changed_objects_enabled)                 \
  F(low_dynamics_changed_compare_range_m, g.dynamics.changed_compare_range_m)                 \
  F(low_dynamics_changed_surface_distance_m, g.dynamics.changed_surface_distance_m)           \
  F(low_dynamics_changed_min_fraction, g.dynamics.changed_min_fraction)                       \
  F(low_dynamics_changed_partner_min_fraction, g.dynamics.changed_partner_min_fraction)       \
  F(low_dynamics_changed_end_min_compared, g.dynamics.changed_end_min_compared)               \
  F(low_dynamics_changed_end_min_fraction, g.dynamics.changed_end_min_fraction)               \
  F(low_dynamics_changed_same_max_fraction, g.dynamics.changed_same_max_fraction)             \
  F(low_dynamics_low_residue_min_ground_points, g.dynamics.low_residue_min_ground_points)     \
  F(low_dynamics_low_residue_radius_m, g.dynamics.low_residue_radius_m)                       \
  F(low_dynamics_low_residue_partner_distance_m, g.dynamics.low_residue_partner_distance_m)   \
  F(low_dynamics_low_residue_range_m, g.dynamics.low_residue_range_m)                         \
  F(low_dynamics_low_residue_max_own_neighbours, g.dynamics.low_residue_max_own_neighbours)   \
  F(low_dynamics_low_residue_blob_radius_m, g.dynamics.low_residue_blob_radius_m)             \
  F(map_update_fuse_min_overlap_ratio, g.fusion.min_overlap_ratio)                            \
  F(map_update_fuse_overlap_distance_m, g.fusion.overlap_distance_m)                          \
  F(map_update_fuse_voxel_m, g.fusion.voxel_m)                                                \
  F(map_update_fuse_fine_voxel_m, g.fusion.fine_voxel_m)                                      \
  F(map_update_fuse_fine_below_m, g.fusion.fine_below_m)                                      \
  F(map_update_fuse_fine_above_m, g.fusion.fine_above_m)                                      \
  F(map_update_max_dynamic_fraction, g.fusion.max_dynamic_fraction)                          \
  F(map_update_propagate_radius_m, g.fusion.propagate_radius_m)                              \
  F(map_update_hold_new_objects, g.fusion.hold.enabled)                                       \
  F(map_update_hold_grow_radius_m, g.fusion.hold.grow_radius_m)                               \
  F(map_update_hold_max_extent_m, g.fusion.hold.max_extent_m)                                 \
  F(map_update_hold_max_attached_fraction, g.fusion.hold.max_attached_fraction)               \
  F(map_update_hold_min_seen_points, g.fusion.hold.min_seen_points)

ScanMatchingConfig ToScanMatchingConfig(const core::OdometryConfig& o) {
  ScanMatchingConfig out = ScanMatchingConfig::__getDefault__();
  MSM_SCAN_MATCHING_FIELDS(MSM_TO_CFG)
  return out;
}

void ApplyScanMatchingConfig(const ScanMatchingConfig& in, core::OdometryConfig* odometry) {
  core::OdometryConfig& o = *odometry;
  MSM_SCAN_MATCHING_FIELDS(MSM_TO_CORE)
}

SubmapManagerConfig ToSubmapManagerConfig(const core::SessionMapperConfig& s) {
  SubmapManagerConfig out = SubmapManagerConfig::__getDefault__();
  MSM_SUBMAP_MANAGER_FIELDS(MSM_TO_CFG)
  return out;
}

void ApplySubmapManagerConfig(const SubmapManagerConfig& in, core::SessionMapperConfig* session) {
  core::SessionMapperConfig& s = *session;
  MSM_SUBMAP_MANAGER_FIELDS(MSM_TO_CORE)
}

PlaceRecognitionConfig ToPlaceRecognitionConfig(const core::PlaceRecognizerConfig& p,
                                                const core::InterSessionMatcherConfig& m) {
  PlaceRecognitionConfig out = PlaceRecognitionConfig::__getDefault__();
  MSM_PLACE_RECOGNITION_FIELDS(MSM_TO_CFG)
  return out;
}

void ApplyPlaceRecognitionConfig(const PlaceRecognitionConfig& in,
                                 core::PlaceRecognizerConfig* recognizer,
                                 core::InterSessionMatcherConfig* matching) {
  core::PlaceRecognizerConfig& p = *recognizer;
  core::InterSessionMatcherConfig& m = *matching;
  MSM_PLACE_RECOGNITION_FIELDS(MSM_TO_CORE)
}

MapMergingConfig ToMapMergingConfig(const core::SessionMergerConfig& g) {
  MapMergingConfig out = MapMergingConfig::__getDefault__();
  MSM_MAP_MERGING_FIELDS(MSM_TO_CFG)
  return out;
}

void ApplyMapMergingConfig(const MapMergingConfig& in, core::SessionMergerConfig* merge) {
  core::SessionMergerConfig& g = *merge;
  MSM_MAP_MERGING_FIELDS(MSM_TO_CORE)
}

}  // namespace ros_params
}  // namespace multisession_mapper
