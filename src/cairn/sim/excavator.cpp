#include "cairn/sim/excavator.hpp"

#include <cmath>
#include <numbers>

#include "cairn/core/transform.hpp"
#include "cairn/core/units.hpp"

namespace cairn::sim {

namespace {

}  // namespace

Excavator::Excavator(const ExcavatorConfig& config, const GripperConfig& gripper, const Terrain& terrain)
    : config_(config), gripper_(gripper), model_((validate(gripper), make_excavator_model(gripper))) {
  T_world_base0_.linear() = Eigen::AngleAxisd(config.base_yaw_deg * kDeg, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T_world_base0_.translation() =
      Eigen::Vector3d(config.base_x, config.base_y, terrain.height(config.base_x, config.base_y) + config.base_height);
}

JointState Excavator::joints_at(double t) const {
  const auto& c = config_;
  JointState q;
  q.time = t;
  q.set(joints::kCabinYaw, cabin_yaw(t));
  q.set(joints::kBoom, c.boom_deg * kDeg);
  q.set(joints::kStick, c.stick_deg * kDeg);
  q.set(joints::kGripperPitch, c.gripper_pitch_deg * kDeg);
  q.set(joints::kGripperRoll, c.gripper_roll_deg * kDeg);
  set_jaw_opening(q, gripper_, c.gripper_opening);
  return q;
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
