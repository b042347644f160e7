#include "multisession_mapper/core/pipeline_config.h"

#include <fstream>
#include <sstream>
#include <type_traits>
#include <variant>
#include <vector>

#include <yaml-cpp/yaml.h>

namespace multisession_mapper {
namespace core {
namespace {

// A descriptor kind is written by its name (DescriptorKindName).
using Field = std::variant<double*, int*, bool*, DescriptorKind*>;
struct Key {
  const char* section;
  const char* name;
  Field field;
};

// The one table of keys: reading, writing and the shipped YAML all follow it.
std::vector<Key> Keys(PipelineConfig* c) {
  SessionMapperConfig& s = c->session;
  InSessionDynamicFilterConfig& d = s.submaps.dynamic_filter;
  SubmapRegistrationConfig& r = s.intra_loops.registration;
  PlaceRecognizerConfig& p = c->place_recognition;
  SessionMergerConfig& m = c->merge;
  return {
      {"input_filter", "min_range_m", &s.odometry.input_filter.min_range_m},
      {"input_filter", "max_range_m", &s.odometry.input_filter.max_range_m},
      {"odometry", "map_voxel_size_m", &s.odometry.map_voxel_size_m},
      {"odometry", "registration_voxel_size_m", &s.odometry.registration_voxel_size_m},
      {"odometry", "max_scan_gap_s", &s.odometry.max_scan_gap_s},
      {"odometry", "deskew_enabled", &s.odometry.deskew.enabled},
      {"odometry", "velocity_window_scans", &s.odometry.velocity_window_scans},
      {"odometry", "rotation_window_scans", &s.odometry.rotation_window_scans},
      {"odometry", "refine_deskew", &s.odometry.refine_deskew},
      {"odometry", "use_scan_normals", &s.odometry.use_scan_normals},
      {"odometry", "high_point_min_height_m", &s.odometry.high_point_min_height_m},
      {"odometry", "high_point_max_normal_z", &s.odometry.high_point_max_normal_z},
      {"odometry", "map_ground_min_depth_m", &s.odometry.map_ground_min_depth_m},
      {"odometry", "map_ground_min_normal_z", &s.odometry.map_ground_min_normal_z},
      {"odometry", "correspondence_sigma_factor", &s.odometry.correspondence_sigma_factor},
      {"odometry", "kernel_sigma_factor", &s.odometry.kernel_sigma_factor},
      {"odometry", "motion_prior_weight", &s.odometry.motion_prior_weight},
      {"odometry", "motion_prior_release_ratio", &s.odometry.motion_prior_release_ratio},
      {"odometry", "turn_hypothesis_step_rad_s", &s.odometry.turn_hypothesis_step_rad_s},
      {"odometry", "turn_hypothesis_margin", &s.odometry.turn_hypothesis_margin},
      {"odometry", "turn_hypothesis_trigger", &s.odometry.turn_hypothesis_trigger},
      {"odometry", "turn_hypothesis_window_scans", &s.odometry.turn_hypothesis_window_scans},
      {"odometry", "turn_hypothesis_in_turns", &s.odometry.turn_hypothesis_in_turns},
      {"odometry", "turn_hypothesis_on_release", &s.odometry.turn_hypothesis_on_release},
      {"odometry", "turn_hypothesis_levels", &s.odometry.turn_hypothesis_levels},
      {"odometry", "icp_max_iterations", &s.odometry.icp.max_iterations},
      {"odometry", "icp_convergence_translation_m", &s.odometry.icp.convergence_translation_m},
      {"odometry", "icp_convergence_rotation_rad", &s.odometry.icp.convergence_rotation_rad},
      {"odometry", "judge_convergence_translation_m",
       &s.odometry.judge_convergence_translation_m},
      {"odometry", "judge_convergence_rotation_rad", &s.odometry.judge_convergence_rotation_rad},
      {"odometry", "judge_max_iterations", &s.odometry.judge_max_iterations},
      {"odometry", "icp_reassociate_translation_m", &s.odometry.icp.reassociate_translation_m},
      {"odometry", "icp_reassociate_rotation_rad", &s.odometry.icp.reassociate_rotation_rad},
      {"odometry", "icp_search_threads", &s.odometry.icp.search_threads},
      {"odometry", "local_map_voxel_size_m", &s.odometry.local_map.voxel_size_m},
      {"odometry", "local_map_max_points_per_voxel", &s.odometry.local_map.max_points_per_voxel},
      {"odometry", "local_map_max_distance_m", &s.odometry.local_map.max_distance_m},
      {"submap", "max_translation_m", &s.submaps.max_translation_m},
      {"submap", "max_rotation_rad", &s.submaps.max_rotation_rad},
      {"submap", "voxel_size_m", &s.submaps.voxel_size_m},
      {"submap", "max_point_range_m", &s.submaps.max_point_range_m},
      {"submap", "break_on_jump_m", &s.submaps.break_on_jump_m},
      {"submap", "robust_height", &s.submaps.robust_height},
      {"in_session_dynamics", "enabled", &d.enabled},
      {"in_session_dynamics", "margin_base_m", &d.margin_base_m},
      {"in_session_dynamics", "margin_per_m", &d.margin_per_m},
      {"in_session_dynamics", "max_check_range_m", &d.max_check_range_m},
      {"in_session_dynamics", "near_range_m", &d.near_range_m},
      {"in_session_dynamics", "check_every_n_scans", &d.check_every_n_scans},
      {"in_session_dynamics", "min_seen_through", &d.min_seen_through},
      {"in_session_dynamics", "min_seen_through_ratio", &d.min_seen_through_ratio},
      {"in_session_dynamics", "min_consecutive_seen_through", &d.min_consecutive_seen_through},
      {"in_session_dynamics", "tail_m", &d.tail_m},
      {"in_session_dynamics", "grow_depth", &d.grow_depth},
      {"in_session_dynamics", "grow_max_scan_gap", &d.grow_max_scan_gap},
      {"in_session_dynamics", "grow_over_measured_ground", &d.grow_over_measured_ground},
      {"in_session_dynamics", "drop_residue_under_removed", &d.drop_residue_under_removed},
      {"in_session_dynamics", "residue_min_rise_m", &d.residue_min_rise_m},
      {"in_session_dynamics", "past_checks", &d.past_checks},
      {"in_session_dynamics", "past_check_stride", &d.past_check_stride},
      {"in_session_dynamics", "group_min_seen_through_ratio", &d.groups.min_seen_through_ratio},
      {"in_session_dynamics", "group_min_seen_voxel_fraction", &d.groups.min_seen_voxel_fraction},
      {"in_session_dynamics", "group_min_voxels", &d.groups.min_voxels},
      {"in_session_dynamics", "group_min_height_m", &d.groups.min_height_m},
      {"in_session_dynamics", "group_ground_cell_m", &d.groups.ground_cell_m},
      {"in_session_dynamics", "group_coarse_ground_cell_m", &d.groups.coarse_ground_cell_m},
      {"in_session_dynamics", "group_coarse_min_height_m", &d.groups.coarse_min_height_m},
      {"in_session_dynamics", "group_min_nearest_range_m", &d.groups.min_nearest_range_m},
      {"in_session_dynamics", "group_plane_min_height_m", &d.groups.plane_min_height_m},
      {"in_session_dynamics", "group_plane_fit_max_range_m", &d.groups.plane_fit_max_range_m},
      {"in_session_dynamics", "no_return_free_range_m", &d.range_image.no_return_free_range_m},
      {"in_session_dynamics", "angular_uncertainty_rad", &d.range_image.angular_uncertainty_rad},
      {"in_session_dynamics", "edge_guard_columns", &d.range_image.edge_guard_columns},
      {"in_session_dynamics", "check_threads", &d.check_threads},
      {"intra_session_pairs", "enabled", &s.intra_pairs.enabled},
      {"intra_session_pairs", "neighbours", &s.intra_pairs.neighbours},
      {"intra_session_pairs", "max_dynamic_fraction", &s.intra_pairs.max_dynamic_fraction},
      {"intra_session_pairs", "num_threads", &s.intra_pairs.num_threads},
      {"intra_session_pairs", "during_session", &s.intra_pairs.during_session},
      {"intra_session_pairs", "rays_from_viewing_scans", &s.intra_pairs.rays_from_viewing_scans},
      {"intra_session_pairs", "min_pass_incidence_rad", &s.intra_pairs.min_pass_incidence_rad},
      {"intra_session_pairs", "min_cluster_coarse_fraction",
       &s.intra_pairs.min_cluster_coarse_fraction},
      {"intra_session_pairs", "own_ground_max_gap_m", &s.intra_pairs.own_ground_max_gap_m},
      {"intra_session_pairs", "changed_objects_enabled", &s.intra_pairs.changed_objects_enabled},
      {"intra_session_pairs", "far_range_m", &s.intra_pairs.far_range_m},
      {"intra_loops", "enabled", &s.intra_loops.enabled},
      {"intra_loops", "search_radius_m", &s.intra_loops.search_radius_m},
      {"intra_loops", "min_id_gap", &s.intra_loops.min_id_gap},
      {"intra_loops", "max_candidates", &s.intra_loops.max_candidates},
      {"intra_loops", "overlap_distance_m", &r.overlap_distance_m},
      {"intra_loops", "min_overlap_ratio", &r.min_overlap_ratio},
      {"intra_loops", "max_correction_m", &r.max_correction_m},
      {"intra_loops", "max_correction_rad", &r.max_correction_rad},
      {"intra_loops", "loop_sigma_translation_m", &r.loop_sigma_translation_m},
      {"intra_loops", "loop_sigma_rotation_rad", &r.loop_sigma_rotation_rad},
      {"pose_graph", "loop_kernel_scale", &s.pose_graph.loop_kernel_scale},
      {"pose_graph", "loop_outlier_chi2", &s.pose_graph.loop_outlier_chi2},
      {"pose_graph", "odometry_sigma_translation_m", &s.odometry_sigma_translation_m},
      {"pose_graph", "odometry_sigma_translation_per_m", &s.odometry_sigma_translation_per_m},
      {"pose_graph", "odometry_sigma_rotation_rad", &s.odometry_sigma_rotation_rad},
      {"pose_graph", "vertical_priors", &s.vertical_structure.enabled},
      {"pose_graph", "vertical_sigma_rad", &s.vertical_structure.sigma_rad},
      {"pose_graph", "vertical_threads", &s.vertical_structure.threads},
      {"pose_graph", "vertical_min_height_m", &s.vertical_structure.min_height_m},
      {"pose_graph", "vertical_min_wall_points", &s.vertical_structure.min_wall_points},
      {"frame_anchor", "enabled", &s.frame_anchor.enabled},
      {"frame_anchor", "scans", &s.frame_anchor.scans},
      {"frame_anchor", "reference_radius_m", &s.frame_anchor.reference_radius_m},
      {"frame_anchor", "max_correction_m", &s.frame_anchor.max_correction_m},
      {"frame_anchor", "max_correction_rad", &s.frame_anchor.max_correction_rad},
      {"frame_anchor", "min_correction_rad", &s.frame_anchor.min_correction_rad},
      {"place_recognition", "descriptor", &p.descriptor.kind},
      {"place_recognition", "d_alpha_ring_histogram", &p.database.d_alpha_ring_histogram},
      {"place_recognition", "d_alpha_scan_context", &p.database.d_alpha_scan_context},
      {"place_recognition", "search_eps", &p.database.search_eps},
      {"place_recognition", "log_neighbours", &p.log_neighbours},
      {"inter_session", "gamma", &m.matching.voting.gamma},
      {"inter_session", "top_n", &m.matching.voting.top_n},
      {"inter_session", "min_matched_scans", &m.matching.voting.min_matched_scans},
      {"inter_session", "neighbour_distance_m", &m.matching.neighbour_distance_m},
      {"inter_session", "overlap_distance_m", &m.matching.registration.fine.overlap_distance_m},
      {"inter_session", "min_overlap_ratio", &m.matching.registration.fine.min_overlap_ratio},
      {"inter_session", "consistency_max_translation_m", &m.matching.consistency.max_translation_m},
      {"inter_session", "consistency_max_rotation_rad", &m.matching.consistency.max_rotation_rad},
      {"inter_session", "consistency_min_group_size", &m.matching.consistency.min_group_size},
      {"inter_session", "consistency_min_secondary_submaps",
       &m.matching.consistency.min_secondary_submaps},
      {"inter_session", "consistency_secondary_translation_per_m",
       &m.matching.consistency.secondary_translation_per_m},
      {"inter_session", "consistency_secondary_rotation_per_m",
       &m.matching.consistency.secondary_rotation_per_m},
      {"inter_session", "consistency_same_submap_translation_m",
       &m.matching.consistency.same_submap_translation_m},
      {"inter_session", "consistency_same_submap_rotation_rad",
       &m.matching.consistency.same_submap_rotation_rad},
      {"inter_session", "consistency_neighbour_path_m",
       &m.matching.consistency.neighbour_path_m},
      {"inter_session", "sequence_max_gap_submaps", &m.matching.sequence.max_gap_submaps},
      {"inter_session", "sequence_chain", &m.matching.sequence.chain},
      {"inter_session", "sequence_max_candidates", &m.matching.sequence.max_candidates},
      {"inter_session", "sequence_search_radius_m", &m.matching.sequence.search_radius_m},
      {"inter_session", "guided_candidates", &m.matching.guided_candidates},
      {"inter_session", "loop_sigma_translation_m", &m.inter_sigma_translation_m},
      {"inter_session", "loop_sigma_rotation_rad", &m.inter_sigma_rotation_rad},
      {"registration", "coarse_voxel_m", &m.matching.registration.coarse_voxel_m},
      {"registration", "ransac_inlier_distance_m",
       &m.matching.registration.ransac_inlier_distance_m},
      {"registration", "min_ransac_inliers", &m.matching.registration.min_ransac_inliers},
      {"registration", "max_tilt_rad", &m.matching.registration.max_tilt_rad},
      {"registration", "structure_overlap_distance_m",
       &m.matching.registration.structure_overlap_distance_m},
      {"registration", "min_structure_overlap_ratio",
       &m.matching.registration.min_structure_overlap_ratio},
      {"proximity_loops", "enabled", &m.proximity.enabled},
      {"proximity_loops", "search_radius_m", &m.proximity.search_radius_m},
      {"proximity_loops", "max_candidates", &m.proximity.max_candidates},
      {"proximity_loops", "overlap_distance_m", &m.proximity.registration.overlap_distance_m},
      {"proximity_loops", "min_overlap_ratio", &m.proximity.registration.min_overlap_ratio},
      {"proximity_loops", "max_correction_m", &m.proximity.registration.max_correction_m},
      {"proximity_loops", "max_correction_rad", &m.proximity.registration.max_correction_rad},
      {"low_dynamics", "seed_distance_m", &m.dynamics.seed_distance_m},
      {"low_dynamics", "grow_radius_m", &m.dynamics.grow_radius_m},
      {"low_dynamics", "grow_max_normal_angle_rad", &m.dynamics.grow_max_normal_angle_rad},
      {"low_dynamics", "voxel_size_m", &m.dynamics.voxel_size_m},
      {"low_dynamics", "free_column_depth_m", &m.dynamics.free_column_depth_m},
      {"low_dynamics", "column_clearance_m", &m.dynamics.column_clearance_m},
      {"low_dynamics", "height_guard_enabled", &m.dynamics.height_guard_enabled},
      {"low_dynamics", "height_guard_m", &m.dynamics.height_guard_m},
      {"low_dynamics", "guard_object_height_m", &m.dynamics.guard_object_height_m},
      {"low_dynamics", "max_object_bottom_m", &m.dynamics.max_object_bottom_m},
      {"low_dynamics", "max_range_m", &m.dynamics.max_range_m},
      {"low_dynamics", "far_range_m", &m.dynamics.far_range_m},
      {"low_dynamics", "far_ground_cell_m", &m.dynamics.far_ground_cell_m},
      {"low_dynamics", "far_max_bottom_m", &m.dynamics.far_max_bottom_m},
      {"low_dynamics", "min_passing_rays", &m.dynamics.min_passing_rays},
      {"low_dynamics", "min_cluster_points", &m.dynamics.min_cluster_points},
      {"low_dynamics", "ground_tolerance_m", &m.dynamics.ground_tolerance_m},
      {"low_dynamics", "own_ground_max_gap_m", &m.dynamics.own_ground_max_gap_m},
      {"low_dynamics", "rays_from_viewing_scans", &m.dynamics.rays_from_viewing_scans},
      {"low_dynamics", "min_pass_incidence_rad", &m.dynamics.min_pass_incidence_rad},
      {"low_dynamics", "min_cluster_coarse_fraction", &m.dynamics.min_cluster_coarse_fraction},
      {"low_dynamics", "bottom_extension_radius_m", &m.dynamics.bottom_extension_radius_m},
      {"low_dynamics", "bottom_min_height_m", &m.dynamics.bottom_min_height_m},
      {"low_dynamics", "bottom_max_drop_m", &m.dynamics.bottom_max_drop_m},
      {"low_dynamics", "changed_objects_enabled", &m.dynamics.changed_objects_enabled},
      {"low_dynamics", "changed_compare_range_m", &m.dynamics.changed_compare_range_m},
      {"low_dynamics", "changed_surface_distance_m", &m.dynamics.changed_surface_distance_m},
      {"low_dynamics", "changed_min_fraction", &m.dynamics.changed_min_fraction},
      {"low_dynamics", "changed_partner_min_fraction", &m.dynamics.changed_partner_min_fraction},
      {"low_dynamics", "changed_end_min_compared", &m.dynamics.changed_end_min_compared},
      {"low_dynamics", "changed_end_min_fraction", &m.dynamics.changed_end_min_fraction},
      {"low_dynamics", "changed_end_min_cos", &m.dynamics.changed_end_min_cos},
      {"low_dynamics", "changed_same_max_fraction", &m.dynamics.changed_same_max_fraction},
      {"low_dynamics", "low_residue_min_ground_points",
       &m.dynamics.low_residue_min_ground_points},
      {"low_dynamics", "low_residue_radius_m", &m.dynamics.low_residue_radius_m},
      {"low_dynamics", "low_residue_partner_distance_m",
       &m.dynamics.low_residue_partner_distance_m},
      {"low_dynamics", "low_residue_range_m", &m.dynamics.low_residue_range_m},
      {"low_dynamics", "low_residue_max_own_neighbours",
       &m.dynamics.low_residue_max_own_neighbours},
      {"low_dynamics", "low_residue_blob_radius_m", &m.dynamics.low_residue_blob_radius_m},
      {"map_update", "fuse_min_overlap_ratio", &m.fusion.min_overlap_ratio},
      {"map_update", "fuse_overlap_distance_m", &m.fusion.overlap_distance_m},
      {"map_update", "fuse_voxel_m", &m.fusion.voxel_m},
      {"map_update", "fuse_fine_voxel_m", &m.fusion.fine_voxel_m},
      {"map_update", "fuse_fine_below_m", &m.fusion.fine_below_m},
      {"map_update", "fuse_fine_above_m", &m.fusion.fine_above_m},
      {"map_update", "max_dynamic_fraction", &m.fusion.max_dynamic_fraction},
      {"map_update", "propagate_radius_m", &m.fusion.propagate_radius_m},
      {"map_update", "record_sessions", &m.fusion.record_sessions},
      {"map_update", "hold_new_objects", &m.fusion.hold.enabled},
      {"map_update", "hold_grow_radius_m", &m.fusion.hold.grow_radius_m},
      {"map_update", "hold_max_extent_m", &m.fusion.hold.max_extent_m},
      {"map_update", "hold_max_attached_fraction", &m.fusion.hold.max_attached_fraction},
      {"map_update", "hold_min_seen_points", &m.fusion.hold.min_seen_points},
      {"map_update", "num_threads", &m.num_threads},
  };
}

}  // namespace

StatusOr<PipelineConfig> PipelineConfigFromYaml(const std::string& yaml_text,
                                                const std::string& source) {
  PipelineConfig config;
  try {
    const YAML::Node root = YAML::Load(yaml_text);
    if (root.IsNull()) return config;
    if (!root.IsMap()) return Status::Error(source + ": the configuration must be a YAML mapping");
    std::vector<Key> keys = Keys(&config);
    for (auto section = root.begin(); section != root.end(); ++section) {
      const std::string section_name = section->first.as<std::string>();
      if (!section->second.IsMap()) {
        return Status::Error(source + ": section '" + section_name + "' must be a mapping");
      }
      for (auto entry = section->second.begin(); entry != section->second.end(); ++entry) {
        const std::string name = entry->first.as<std::string>();
        bool known = false;
        for (Key& key : keys) {
          if (section_name != key.section || name != key.name) continue;
          known = true;
          bool named = true;
          try {
            std::visit([&](auto* field) {
              using T = std::remove_pointer_t<decltype(field)>;
              if constexpr (std::is_same_v<T, DescriptorKind>) {
                named = DescriptorKindFromName(entry->second.as<std::string>(), field);
              } else {
                *field = entry->second.as<T>();
              }
            }, key.field);
          } catch (const YAML::Exception&) {
            return Status::Error(source + ": " + section_name + "." + name +
                                 " has a value of the wrong type");
          }
          if (!named) {
            return Status::Error(source + ": " + section_name + "." + name +
                                 " must be ring_histogram or scan_context");
          }
        }
        if (!known) {
          return Status::Error(source + ": unknown key '" + section_name + "." + name + "'");
        }
      }
    }
  } catch (const YAML::Exception& e) {
    return Status::Error(source + ": not valid YAML (" + e.what() + ")");
  }
  // The session's pair detection compares submaps as the merge does.
  config.session.intra_pairs.detection = config.merge.dynamics;
  Status valid = config.Validate();
  if (!valid.ok()) return Status::Error(source + ": " + valid.message());
  return config;
}

StatusOr<PipelineConfig> LoadPipelineConfig(const std::string& path) {
  std::ifstream in(path);
  if (!in) return Status::Error("cannot open configuration file '" + path + "'");
  std::stringstream text;
  text << in.rdbuf();
  return PipelineConfigFromYaml(text.str(), path);
}

std::string PipelineConfigToYaml(const PipelineConfig& config) {
  PipelineConfig copy = config;
  YAML::Emitter out;
  out << YAML::BeginMap;
  std::string open_section;
  for (const Key& key : Keys(&copy)) {
    if (open_section != key.section) {
      if (!open_section.empty()) out << YAML::EndMap;
      out << YAML::Key << key.section << YAML::Value << YAML::BeginMap;
      open_section = key.section;
    }
    out << YAML::Key << key.name << YAML::Value;
    std::visit([&](auto* field) {
      if constexpr (std::is_same_v<std::remove_pointer_t<decltype(field)>, DescriptorKind>) {
        out << DescriptorKindName(*field);
      } else {
        out << *field;
      }
    }, key.field);
  }
  if (!open_section.empty()) out << YAML::EndMap;
  out << YAML::EndMap;
  return out.c_str();
}

}  // namespace core
}  // namespace multisession_mapper
