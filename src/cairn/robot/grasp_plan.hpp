#pragma once
// The grasp-plan contract between grasp planning (Sec. 5) and whatever executes a plan: the
// simulator's physics today, the machine's arm controller tomorrow. Poses are gripper frames G
// of robot/gripper.hpp (x = approach, y = closing, origin at the palm's front face).
//
// JSON form (the `cairn grasp-trial --plan` file; all fields but T_world_gripper optional;
// defaults as GraspPlan, the place pose defaults to the grasp pose, i.e. put it back):
//   {"T_world_gripper": POSE, "opening": 1.0, "approach_distance": 0.5, "lift_height": 1.0,
//    "T_world_place": POSE, "swing_pivot": [x, y], "target_stone": 3}
// A POSE is either a 4x4 row-major matrix  [[r00, r01, r02, tx], ..., [0, 0, 0, 1]]
// or an object {"position": [x, y, z], "quaternion_wxyz": [w, x, y, z]} (normalised on reading).
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "cairn/robot/gripper.hpp"

namespace cairn {

/// One grasp to execute.
struct GraspPlan {
  Eigen::Isometry3d T_world_gripper = Eigen::Isometry3d::Identity();  // at closing
  double opening = 1.0;            // [m] pre-grasp distance between the jaw tips (gripper.hpp)
  double approach_distance = 0.5;  // [m] the approach starts this far back along -x
  double lift_height = 1.0;        // [m] lifted straight up (world z) after closing
  /// Gripper pose at release; the stone follows rigidly, so the expected stone placement is
  /// T_world_place * T_world_gripper^-1 * (stone at grasp).
  Eigen::Isometry3d T_world_place = Eigen::Isometry3d::Identity();
  /// Swing: when set, the transport rotates about the vertical through this point (an
  /// excavator's cabin axis) instead of moving in a straight line.
  std::optional<Eigen::Vector2d> swing_pivot;
  /// Placing by weight (beyond the paper): when set, the world xy where the stone's centre of
  /// mass is to be set down. The arm weighs the stone while it hangs still after the lift (its
  /// load cell's force and moment give the centre of mass under the gripper) and shifts the
  /// place pose horizontally so that the weighed centre lands there.
  std::optional<Eigen::Vector2d> place_com_xy;
  int target_stone = -1;  // when >= 0, grasping another stone is a failure ("wrong_stone")
};

/// Throws InputError on non-finite or non-rigid poses, an opening outside (closed_gap,
/// max_opening], negative distances.
void validate(const GraspPlan& plan, const GripperConfig& gripper);

/// Throws InputError "`what` is not finite / not a rigid transform".
void require_rigid_pose(const Eigen::Isometry3d& T, const std::string& what);

/// A number for JSON output, rounded to 1e-9 (the text stays stable across platforms).
nlohmann::json rounded_json(double v);

nlohmann::json pose_to_json(const Eigen::Isometry3d& T);
/// Throws InputError naming `what` on malformed input or a non-rigid rotation.
Eigen::Isometry3d pose_from_json(const nlohmann::json& j, const std::string& what);

nlohmann::json to_json(const GraspPlan& plan);
/// Throws InputError naming `source` on malformed input.
GraspPlan grasp_plan_from_json(const nlohmann::json& j, const std::string& source);

}  // namespace cairn
