#include "cairn/sim/excavator.hpp"

#include <cmath>
#include <numbers>

namespace cairn::sim {

namespace {
constexpr double kDeg = std::numbers::pi / 180.0;

// Machine dimensions [m] (M545-like).
constexpr double kChassisLength = 3.6, kChassisWidth = 2.0, kChassisHeight = 0.8;
constexpr double kLegSize = 0.35;                  // leg cross-section
constexpr double kLegX = 1.9, kLegY = 1.4;         // leg positions from the axis
constexpr double kCabinBack = -1.7, kCabinFront = 0.9, kCabinWidth = 2.2, kCabinHeight = 2.2;
constexpr double kCounterweightLength = 0.8, kCounterweightHeight = 1.2;
constexpr double kBoomPivotX = 1.0, kBoomPivotZ = 0.8;
constexpr double kBoomLength = 4.5, kBoomWidth = 0.5, kBoomHeight = 0.6;
constexpr double kStickLength = 2.8, kStickWidth = 0.4, kStickHeight = 0.45;
constexpr double kRotatorLength = 0.3, kRotatorRadius = 0.2;

Eigen::Isometry3d translation(double x, double y, double z) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(x, y, z);
  return T;
}

Shape box(std::string name, const Eigen::Vector3d& centre, const Eigen::Vector3d& size) {
  return Shape{.kind = Shape::Kind::Box, .name = std::move(name),
               .T_link_shape = translation(centre.x(), centre.y(), centre.z()), .size = size};
}
}  // namespace

RobotModel make_excavator_model(const GripperConfig& g) {
  RobotModel m;
  m.name = "walking_excavator";
  const Eigen::Vector3d minus_y(0, -1, 0);
  // Base: chassis below the swing axis, four legs down to the ground.
  Link base{.name = "base"};
  base.shapes.push_back(box("chassis", {0, 0, -0.5 * kChassisHeight}, {kChassisLength, kChassisWidth, kChassisHeight}));
  int leg = 0;
  for (double sx : {-1.0, 1.0}) {
    for (double sy : {-1.0, 1.0}) {
      base.shapes.push_back(box("leg_" + std::to_string(leg++), {sx * kLegX, sy * kLegY, -0.5 * 1.3},
                                {kLegSize, kLegSize, 1.3}));
    }
  }
  m.links.push_back(std::move(base));
  Link cabin{.name = "cabin", .parent = 0, .joint = Link::Joint::Revolute, .joint_name = joints::kCabinYaw,
             .axis = Eigen::Vector3d::UnitZ()};
  cabin.shapes.push_back(box("cab", {0.5 * (kCabinBack + kCabinFront), 0, 0.5 * kCabinHeight},
                             {kCabinFront - kCabinBack, kCabinWidth, kCabinHeight}));
  cabin.shapes.push_back(box("counterweight", {kCabinBack - 0.5 * kCounterweightLength, 0, 0.5 * kCounterweightHeight},
                             {kCounterweightLength, kCabinWidth, kCounterweightHeight}));
  m.links.push_back(std::move(cabin));
  Link boom{.name = "boom", .parent = 1, .joint = Link::Joint::Revolute, .joint_name = joints::kBoom,
            .T_parent_joint = translation(kBoomPivotX, 0, kBoomPivotZ), .axis = minus_y};
  boom.shapes.push_back(box("boom", {0.5 * kBoomLength, 0, 0}, {kBoomLength, kBoomWidth, kBoomHeight}));
  m.links.push_back(std::move(boom));
  Link stick{.name = "stick", .parent = 2, .joint = Link::Joint::Revolute, .joint_name = joints::kStick,
             .T_parent_joint = translation(kBoomLength, 0, 0), .axis = minus_y};
  stick.shapes.push_back(box("stick", {0.5 * kStickLength, 0, 0}, {kStickLength, kStickWidth, kStickHeight}));
  m.links.push_back(std::move(stick));
  Link tilt{.name = "rotator", .parent = 3, .joint = Link::Joint::Revolute, .joint_name = joints::kGripperPitch,
            .T_parent_joint = translation(kStickLength, 0, 0), .axis = minus_y};
  Shape rotator{.kind = Shape::Kind::Cylinder, .name = "rotator", .T_link_shape = translation(0.5 * kRotatorLength, 0, 0),
                .size = {2 * kRotatorRadius, 2 * kRotatorRadius, kRotatorLength}};
  rotator.T_link_shape.linear() = Eigen::AngleAxisd(0.5 * std::numbers::pi, Eigen::Vector3d::UnitY()).toRotationMatrix();
  tilt.shapes.push_back(rotator);
  m.links.push_back(std::move(tilt));
  // Gripper frame G: origin at the palm's front face, x = approach.
  Link gripper{.name = "gripper", .parent = 4, .joint = Link::Joint::Revolute, .joint_name = joints::kGripperRoll,
               .T_parent_joint = translation(kRotatorLength + g.palm_depth, 0, 0), .axis = Eigen::Vector3d::UnitX()};
  const auto parts = gripper_parts(g, 0.0);
  gripper.shapes.push_back(box("palm", parts[0].center, 2.0 * parts[0].half_extents));
  m.links.push_back(std::move(gripper));
  const Eigen::Vector3d jaw_size(g.jaw_length, g.jaw_thickness, g.jaw_height);
  Link left{.name = "jaw_left", .parent = 5, .joint = Link::Joint::Prismatic, .joint_name = joints::kJawLeft,
            .axis = minus_y};
  left.shapes.push_back(box("jaw_left", {0.5 * g.jaw_length, -0.5 * g.jaw_thickness, 0}, jaw_size));
  m.links.push_back(std::move(left));
  Link right{.name = "jaw_right", .parent = 5, .joint = Link::Joint::Prismatic, .joint_name = joints::kJawRight,
             .axis = Eigen::Vector3d::UnitY()};
  right.shapes.push_back(box("jaw_right", {0.5 * g.jaw_length, 0.5 * g.jaw_thickness, 0}, jaw_size));
  m.links.push_back(std::move(right));
  m.validate();
  return m;
}

Excavator::Excavator(const ExcavatorConfig& config, const GripperConfig& gripper, const Terrain& terrain)
    : config_(config), gripper_(gripper), model_(make_excavator_model(gripper)) {
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
  q.set(joints::kJawLeft, 0.5 * c.gripper_opening);
  q.set(joints::kJawRight, 0.5 * c.gripper_opening);
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
  return translation(config_.lidar_x, config_.lidar_h_y, config_.lidar_z);
}

Eigen::Isometry3d Excavator::T_cabin_V() const {
  // Spin axis (sensor z) along the cabin's -y, pointing away from the cabin: the scan fan is the
  // cabin's x-z plane, and the upward-tilted beams look outwards, not across the roof.
  Eigen::Isometry3d T = translation(config_.lidar_x, config_.lidar_v_y, config_.lidar_z);
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
