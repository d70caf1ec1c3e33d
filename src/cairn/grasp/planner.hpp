#pragma once
// Grasp pose planning (paper Sec. 5) as a sequence of named steps: the planning cloud (5.2),
// candidates (5.3), force closure and robustness (5.4), hierarchical ranking (5.4, Eq. 5-7).
// Inputs and outputs in the map frame.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "cairn/grasp/candidates.hpp"
#include "cairn/grasp/config.hpp"
#include "cairn/grasp/planning_cloud.hpp"
#include "cairn/grasp/ranking.hpp"
#include "cairn/robot/grasp_plan.hpp"

namespace cairn::grasp {

struct Grasp {
  int rank = 0;  // 1 = best
  Eigen::Isometry3d T_map_gripper = Eigen::Isometry3d::Identity();  // at closing (jaws open)
  double opening = 0.0;         // [m] pre-grasp opening
  double closed_opening = 0.0;  // [m] between the tips when both jaws touch
  double contact_angle = 0.0;   // [rad] jaw angle then (< 0: converging)
  double shift = 0.0;           // [m] the object's predicted slide along the closing axis
  Eigen::Vector3d approach = Eigen::Vector3d::UnitX();  // n_approach (map)
  std::array<Eigen::Vector3d, 2> contacts;              // jaw contact patch centres (map)
  Costs costs;
  /// [m] the contacts' midpoint above the object's centroid (along the ground normal): a stone
  /// held below its centroid hangs top-heavy.
  double contact_height = 0.0;
  /// [m] horizontal distance of the centre of mass from the vertical plane through the contact
  /// line: gravity's lever about it.
  double gravity_lever = 0.0;
  /// How far the contact patches face downwards: minus the smaller of their mean outward
  /// normals' components along the ground normal (> 0: both jaws press on the underside of
  /// the stone's bulge, which then cannot slide out downwards without spreading them).
  double undercut = 0.0;
  bool force_closure = false;
  double cone_margin = 0.0;  // [rad]
  double robustness = -1.0;  // share of perturbations in force closure (-1: not evaluated)
};

struct GraspCounts {
  std::size_t samples = 0, poses = 0, hypotheses = 0, collision_free = 0, force_closure = 0;
  std::size_t balanced = 0;  // force closure, the centre of mass near the contact line, jaws not diverging
  std::size_t robust = 0;
};

struct GraspPlanning {
  PlanningCloud cloud;
  std::vector<Grasp> grasps;  // ranked, best first (at most ranking.output)
  /// Every force-closure grasp's costs and the costs of those the ranking selected (the paper's
  /// Fig. 9).
  std::vector<Costs> force_closure_costs, selected_costs;
  /// Every force-closure grasp (same order as force_closure_costs; robustness -1 where the
  /// ranking did not need it): what a study of the grasps' physics outcome draws from.
  std::vector<Grasp> force_closure_grasps;
  GraspCounts counts;
  std::map<std::string, double> timings_ms;  // cloud, candidates, force_closure, ranking, total
};

/// Plans grasps on the object whose model (segment or database cloud, map frame) is `object`.
/// Throws InputError on empty or non-finite inputs, ConfigError on bad settings.
[[nodiscard]] GraspPlanning plan_grasps(const PointCloud& map, const PointCloud& object, const PointCloud* drone,
                                        const GripperConfig& gripper, const GraspConfig& config);

/// The grasp as a plan for execution (approach, lift and place from `base`).
[[nodiscard]] GraspPlan to_grasp_plan(const Grasp& grasp, GraspPlan base);

/// The `cairn grasp` JSON contract (docs/grasp.md): object, grasps (with the gripper's convex
/// parts in the map frame at the pre-grasp opening), counts, timings_ms.
[[nodiscard]] nlohmann::json to_json(const GraspPlanning& planning, const GripperConfig& gripper);

}  // namespace cairn::grasp
