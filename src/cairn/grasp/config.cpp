#include "cairn/grasp/config.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "cairn/core/error.hpp"

namespace cairn::grasp {
namespace {

void require(bool ok, const std::string& key, const std::string& what) { require_config(ok, "grasp", key, what); }

bool all_finite(const std::vector<double>& v) {
  return std::all_of(v.begin(), v.end(), [](double x) { return std::isfinite(x); });
}

void validate(const PlanningCloudConfig& c) {
  require(c.margin_factor >= 0, "cloud.margin_factor", "must be >= 0");
  require(c.voxel > 0 && std::isfinite(c.voxel), "cloud.voxel", "must be > 0");
  require(c.object_distance_voxels > 0, "cloud.object_distance_voxels", "must be > 0");
  require(c.ground_distance > 0, "cloud.ground_distance", "must be > 0");
  require(c.ground_max_tilt_deg >= 0 && c.ground_max_tilt_deg < 90, "cloud.ground_max_tilt_deg", "must be in [0, 90)");
  require(c.normal_radius_voxels >= 1, "cloud.normal_radius_voxels", "must be >= 1");
}

void validate(const CandidateConfig& c) {
  require(c.samples >= 1, "candidates.samples", "must be >= 1");
  require(c.lrf_radius_voxels >= 1, "candidates.lrf_radius_voxels", "must be >= 1");
  for (const auto* list : {&c.rotations_y_deg, &c.rotations_z_deg, &c.rotations_x_deg})
    require(!list->empty() && all_finite(*list), "candidates.rotations_*_deg", "must be non-empty lists of finite angles");
  require(all_finite(c.vertical_yaws_deg), "candidates.vertical_yaws_deg", "must be finite angles");
  require(!c.backoff_voxels.empty() && all_finite(c.backoff_voxels) &&
              std::all_of(c.backoff_voxels.begin(), c.backoff_voxels.end(), [](double b) { return b >= 0; }),
          "candidates.backoff_voxels", "must be a non-empty list of back-offs >= 0");
  require(std::all_of(c.openings.begin(), c.openings.end(), [](double o) { return o > 0 && o <= 1; }),
          "candidates.openings", "must be shares in (0, 1]");
  require(!c.openings.empty() || c.fit_opening, "candidates.openings", "must not be empty without fit_opening");
  require(c.collision_voxels >= 1, "candidates.collision_voxels", "must be >= 1");
  require(c.padding_voxels >= 0, "candidates.padding_voxels", "must be >= 0");
  require(c.clearance_voxels >= 0, "candidates.clearance_voxels", "must be >= 0");
  require(c.start_margin_voxels > c.clearance_voxels, "candidates.start_margin_voxels", "must exceed clearance_voxels");
  require(std::isfinite(c.tip_clearance_voxels) && c.tip_clearance_voxels >= 0.0, "candidates.tip_clearance_voxels",
          "must be >= 0");
  require(c.min_object_points >= 1, "candidates.min_object_points", "must be >= 1");
}

void validate(const ForceClosureConfig& c) {
  require(c.mu >= 0 && std::isfinite(c.mu), "force_closure.mu", "must be >= 0");
  require(c.mu_safety >= 1 && std::isfinite(c.mu_safety), "force_closure.mu_safety", "must be >= 1");
  require(c.patch_voxels > 0, "force_closure.patch_voxels", "must be > 0");
  require(c.perturbations >= 0, "force_closure.perturbations", "must be >= 0");
  require(c.sigma_translation_voxels >= 0 && c.sigma_rotation_deg >= 0 && c.sigma_mu >= 0,
          "force_closure.sigma_*", "must be >= 0");
  require(c.max_shift_voxels >= 0, "force_closure.max_shift_voxels", "must be >= 0");
  require(std::isfinite(c.max_contact_angle_deg), "force_closure.max_contact_angle_deg", "must be finite");
  require(c.max_lever_jaw_heights > 0, "force_closure.max_lever_jaw_heights", "must be > 0");
  require(c.min_robustness >= 0 && c.min_robustness <= 1, "force_closure.min_robustness", "must be in [0, 1]");
}

}  // namespace

void GraspConfig::validate() const {
  grasp::validate(cloud);
  grasp::validate(candidates);
  grasp::validate(force_closure);
  require(ranking.method == "hierarchical" || ranking.method == "closest", "ranking.method",
          "must be 'hierarchical' or 'closest'");
  require(ranking.keep_align >= 1 && ranking.keep_enclose >= 1 && ranking.output >= 1, "ranking.keep_*/output",
          "must be >= 1");
}

}  // namespace cairn::grasp
