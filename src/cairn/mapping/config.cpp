#include "cairn/mapping/config.hpp"

#include <string>

#include "cairn/core/error.hpp"

namespace cairn {
namespace {
void require(bool ok, const std::string& key, const std::string& what) { require_config(ok, "mapping", key, what); }
}  // namespace

void MappingConfig::validate() const {
  require(m >= 1, "m", "must be >= 1");
  require(d_poses >= 0.0, "d_poses", "must be >= 0");
  require(max_pair_gap > 0.0, "max_pair_gap", "must be > 0");
  require(self_filter.padding >= 0.0, "self_filter.padding", "must be >= 0");
  require(self_filter.time_slots >= 1, "self_filter.time_slots", "must be >= 1");
  require(deskew.slot > 0.0, "deskew.slot", "must be > 0");
  require(scan_matching.source_voxel > 0.0, "scan_matching.source_voxel", "must be > 0");
  require(scan_matching.submap_voxel > 0.0, "scan_matching.submap_voxel", "must be > 0");
  require(scan_matching.submap_every >= 1, "scan_matching.submap_every", "must be >= 1");
  require(scan_matching.submap_latency >= 1, "scan_matching.submap_latency", "must be >= 1");
  require(scan_matching.normal_k >= 3, "scan_matching.normal_k", "must be >= 3");
  require(scan_matching.residual_sigma > 0.0, "scan_matching.residual_sigma", "must be > 0");
  require(scan_matching.info_scale > 0.0, "scan_matching.info_scale", "must be > 0");
  require(scan_matching.loop_info_scale > 0.0, "scan_matching.loop_info_scale", "must be > 0");
  require(scan_matching.min_sigma_translation > 0.0, "scan_matching.min_sigma_translation", "must be > 0");
  require(scan_matching.min_sigma_rotation_deg > 0.0, "scan_matching.min_sigma_rotation_deg", "must be > 0");
  scan_matching.icp.validate();
  const auto& g = pose_graph;
  require(g.odometry_sigma_translation > 0.0, "pose_graph.odometry_sigma_translation", "must be > 0");
  require(g.odometry_sigma_rotation_deg > 0.0, "pose_graph.odometry_sigma_rotation_deg", "must be > 0");
  require(g.odometry_translation_rate >= 0.0, "pose_graph.odometry_translation_rate", "must be >= 0");
  require(g.odometry_rotation_rate_deg >= 0.0, "pose_graph.odometry_rotation_rate_deg", "must be >= 0");
  require(g.prior_sigma_translation > 0.0, "pose_graph.prior_sigma_translation", "must be > 0");
  require(g.prior_sigma_roll_pitch_deg > 0.0, "pose_graph.prior_sigma_roll_pitch_deg", "must be > 0");
  require(g.prior_sigma_yaw_deg > 0.0, "pose_graph.prior_sigma_yaw_deg", "must be > 0");
  require(g.window >= 1, "pose_graph.window", "must be >= 1");
  require(g.window_iterations >= 0, "pose_graph.window_iterations", "must be >= 0");
  require(g.final_iterations >= 0, "pose_graph.final_iterations", "must be >= 0");
  require(local_map.R_map > 0.0, "local_map.R_map", "must be > 0");
  require(local_map.voxel.res_voxel > 0.0, "local_map.voxel.res_voxel", "must be > 0");
  require(local_map.voxel.n_min >= 1, "local_map.voxel.n_min", "must be >= 1");
  require(local_map.smoothing_radius >= 0.0, "local_map.smoothing_radius", "must be >= 0");
  require(local_map.smoothing_block >= 0.0 &&
              (local_map.smoothing_radius == 0.0 || local_map.smoothing_block <= local_map.smoothing_radius),
          "local_map.smoothing_block", "must be in [0, smoothing_radius]");
  require(local_map.crop_every >= 1, "local_map.crop_every", "must be >= 1");
}

}  // namespace cairn
