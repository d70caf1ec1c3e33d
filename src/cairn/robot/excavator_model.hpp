#pragma once
// The walking excavator's geometry (a Menzi Muck M545-like machine, paper Sec. 3): its kinematic
// tree and collision shapes, with the gripper's palm and jaws taken from robot/gripper.hpp. The
// simulator poses it to ray-cast the LiDARs and writes it to `robot.json`; the mapping stage's
// self-filter reads it back and pads the same shapes.
#include <string>

#include "cairn/core/robot_model.hpp"
#include "cairn/robot/gripper.hpp"

namespace cairn {

/// Joint names of the excavator model.
namespace joints {
inline const std::string kCabinYaw = "cabin_yaw", kBoom = "boom", kStick = "stick",
                         kGripperPitch = "gripper_pitch", kGripperRoll = "gripper_roll",
                         kJawLeft = "jaw_left", kJawRight = "jaw_right";
}

/// The link whose frame is the gripper frame G (robot/gripper.hpp): what the gripper holds moves
/// with it.
inline const std::string kGripperLink = "gripper";

/// The excavator's kinematic tree and collision shapes (base with chassis and legs, cabin with
/// counterweight, boom, stick, rotator, gripper palm and jaws). Joint axes: cabin_yaw about base z;
/// boom, stick and gripper_pitch about -y (positive raises); gripper_roll about the approach x;
/// jaw_left / jaw_right revolute about their pivots (value = the jaw angle of gripper.hpp, the
/// same for both: positive opens).
RobotModel make_excavator_model(const GripperConfig& gripper);

/// Sets both jaw joints of `q` to the jaw angle of the given opening.
void set_jaw_opening(JointState& q, const GripperConfig& gripper, double opening);

}  // namespace cairn
