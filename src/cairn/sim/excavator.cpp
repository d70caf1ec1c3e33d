#include "cairn/sim/excavator.hpp"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <numbers>

#include "cairn/core/error.hpp"
#include "cairn/core/transform.hpp"
#include "cairn/core/units.hpp"

namespace cairn::sim {

Excavator::Excavator(const ExcavatorConfig& config, const GripperConfig& gripper, const Terrain& terrain)
    : config_(config), gripper_(gripper), model_((validate(gripper), make_excavator_model(gripper))) {
  T_world_base0_.linear() = Eigen::AngleAxisd(config.base_yaw_deg * kDeg, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T_world_base0_.translation() =
      Eigen::Vector3d(config.base_x, config.base_y, terrain.height(config.base_x, config.base_y) + config.base_height);
}

JointState Excavator::joints_at(double t) const {
  const ArmPose a = arm_at(t);
  JointState q;
  q.time = t;
  q.set(joints::kCabinYaw, cabin_yaw(t));
  q.set(joints::kBoom, a.boom_deg * kDeg);
  q.set(joints::kStick, a.stick_deg * kDeg);
  q.set(joints::kGripperPitch, a.gripper_pitch_deg * kDeg);
  q.set(joints::kGripperRoll, a.gripper_roll_deg * kDeg);
  set_jaw_opening(q, gripper_, a.gripper_opening);
  return q;
}

ArmPose Excavator::parked() const { return config_.parking; }

ArmPose Excavator::arm_at(double t) const {
  // The latest command at or before t (commands are sorted by time).
  const auto after = std::upper_bound(arm_commands_.begin(), arm_commands_.end(), t,
                                      [](double time, const auto& cmd) { return time < cmd.first; });
  return after == arm_commands_.begin() ? parked() : std::prev(after)->second;
}

void Excavator::move_arm(double t, const ArmPose& pose) {
  const bool finite = std::isfinite(t) && std::isfinite(pose.boom_deg) && std::isfinite(pose.stick_deg) &&
                      std::isfinite(pose.gripper_pitch_deg) && std::isfinite(pose.gripper_roll_deg) &&
                      std::isfinite(pose.gripper_opening);
  if (!finite) throw InputError("move_arm: a non-finite time or joint value");
  if (!arm_commands_.empty() && t < arm_commands_.back().first)
    throw InputError("move_arm: commanded at t = " + std::to_string(t) + " s, before the previous command (" +
                     std::to_string(arm_commands_.back().first) + " s)");
  arm_commands_.emplace_back(t, pose);
}

Eigen::Isometry3d Excavator::T_world_base(double t) const {
  const double w = 2.0 * std::numbers::pi * config_.vibration_frequency * t;
  const double a = config_.vibration_deg * kDeg;
  Eigen::Isometry3d sway = Eigen::Isometry3d::Identity();
  sway.linear() = (Eigen::AngleAxisd(a * std::sin(w), Eigen::Vector3d::UnitX()) *
                   Eigen::AngleAxisd(a * std::sin(1.37 * w + 1.0), Eigen::Vector3d::UnitY()))
                      .toRotationMatrix();
  return T_world_base0_ * sway;
}

double Excavator::cabin_yaw(double t) const {
  const auto& c = config_;
  return c.swing_amplitude_deg * kDeg *
         std::sin(2.0 * std::numbers::pi * t / c.swing_period + c.swing_phase_deg * kDeg);
}

Eigen::Isometry3d Excavator::T_world_cabin(double t) const {
  const double yaw = cabin_yaw(t);
  Eigen::Isometry3d R = Eigen::Isometry3d::Identity();
  R.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return T_world_base(t) * R;
}

Eigen::Isometry3d Excavator::T_cabin_H() const {
  return pure_translation(config_.lidar_x, config_.lidar_h_y, config_.lidar_z);
}

Eigen::Isometry3d Excavator::T_cabin_V() const {
  // Spin axis (sensor z) along the cabin's -y, pointing away from the cabin: the scan fan is the
  // cabin's x-z plane, and the upward-tilted beams look outwards, not across the roof.
  Eigen::Isometry3d T = pure_translation(config_.lidar_x, config_.lidar_v_y, config_.lidar_z);
  T.linear() = Eigen::AngleAxisd(0.5 * std::numbers::pi, Eigen::Vector3d::UnitX()).toRotationMatrix();
  return T;
}

std::vector<Eigen::Isometry3d> Excavator::link_poses(double t) const {
  std::vector<Eigen::Isometry3d> T = model_.forward_kinematics(joints_at(t));
  const Eigen::Isometry3d base = T_world_base(t);
  for (auto& pose : T) pose = base * pose;
  return T;
}

}  // namespace cairn::sim
