#include "cairn/objects/config.hpp"

#include "cairn/core/error.hpp"

namespace cairn {
namespace {
void require(bool ok, const std::string& key, const std::string& what) { require_config(ok, "objects", key, what); }
}  // namespace

void ObjectsConfig::validate() const {
  const auto& g = grasp_removal;
  require(g.method == "object_voxels" || g.method == "sphere", "grasp_removal.method",
          "must be object_voxels or sphere");
  require(g.R_obj > 0, "grasp_removal.R_obj", "must be > 0");
  require(g.distance > 0, "grasp_removal.distance", "must be > 0");
  const auto& r = realign;
  require(r.crop_margin >= 0, "realign.crop_margin", "must be >= 0");
  require(r.coarse_distance > 0 && r.fine_distance > 0, "realign.coarse_distance/fine_distance", "must be > 0");
  require(r.max_iterations >= 1, "realign.max_iterations", "must be >= 1");
  require(r.inlier_distance > 0, "realign.inlier_distance", "must be > 0");
  require(r.min_fitness >= 0 && r.min_fitness <= 1, "realign.min_fitness", "must be in [0, 1]");
  require(r.max_rmse > 0, "realign.max_rmse", "must be > 0");
  require(r.search_radius >= 0, "realign.search_radius", "must be >= 0");
  require(r.search_min_fitness > 0 && r.search_min_fitness <= 1, "realign.search_min_fitness", "must be in (0, 1]");
  require(r.search_max_rmse > 0, "realign.search_max_rmse", "must be > 0");
  require(r.max_direct_translation > 0 && r.max_direct_rotation_deg > 0, "realign.max_direct_*", "must be > 0");
  const auto& a = association;
  require(a.overlap_distance > 0, "association.overlap_distance", "must be > 0");
  require(a.min_overlap > 0 && a.min_overlap <= 1, "association.min_overlap", "must be in (0, 1]");
  require(a.min_support >= 0 && a.min_support <= 1, "association.min_support", "must be in [0, 1]");
  require(a.search_radius >= 0, "association.search_radius", "must be >= 0");
  require(a.min_fitness > 0 && a.min_fitness <= 1, "association.min_fitness", "must be in (0, 1]");
  require(a.max_rmse > 0, "association.max_rmse", "must be > 0");
  require(a.yaw_seeds >= 1, "association.yaw_seeds", "must be >= 1");
  require(a.in_view_radius > 0, "association.in_view_radius", "must be > 0");
  require(a.in_view_min_points >= 1, "association.in_view_min_points", "must be >= 1");
  require(a.min_segment_points >= 1, "association.min_segment_points", "must be >= 1");
  require(a.distinct_rotation_deg > 0, "association.distinct_rotation_deg", "must be > 0");
  require(a.ambiguity_margin >= 0, "association.ambiguity_margin", "must be >= 0");
  support.validate();
}

}  // namespace cairn
