#pragma once
// JSON forms of grasp plans and trial results (the `cairn grasp-trial` file formats).
//
// A pose is either a 4x4 row-major matrix  [[r00, r01, r02, tx], ..., [0, 0, 0, 1]]
// or an object {"position": [x, y, z], "quaternion_wxyz": [w, x, y, z]} (normalised on reading).
//
// Grasp plan (all fields but T_world_gripper optional; defaults as GraspPlan, the place pose
// defaults to the grasp pose, i.e. put it back where it was):
//   {"T_world_gripper": POSE, "opening": 1.0, "approach_distance": 0.5, "lift_height": 1.0,
//    "T_world_place": POSE, "swing_pivot": [x, y], "target_stone": 3}
#include <nlohmann/json.hpp>
#include <string>

#include "cairn/sim/physics/physics.hpp"

namespace cairn::sim {

nlohmann::json pose_to_json(const Eigen::Isometry3d& T);
/// Throws InputError naming `what` on malformed input or a non-rigid rotation.
Eigen::Isometry3d pose_from_json(const nlohmann::json& j, const std::string& what);

nlohmann::json to_json(const GraspPlan& plan);
/// Throws InputError naming `source` on malformed input.
GraspPlan grasp_plan_from_json(const nlohmann::json& j, const std::string& source);

nlohmann::json to_json(const GraspTrialResult& result);
nlohmann::json to_json(const SettleResult& result);
nlohmann::json to_json(const SiteSettleResult& result);

}  // namespace cairn::sim
