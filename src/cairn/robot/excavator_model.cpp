#include "cairn/robot/excavator_model.hpp"

#include <numbers>

#include "cairn/core/transform.hpp"

namespace cairn {

namespace {
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


/// A gripper part (a box) as a link shape.
Shape part_shape(const ConvexPart& p) {
  Shape s{.kind = Shape::Kind::Box, .name = p.name, .T_link_shape = Eigen::Isometry3d::Identity(),
          .size = 2.0 * p.half_extents};
  s.T_link_shape.linear() = p.axes;
  s.T_link_shape.translation() = p.center;
  return s;
}

Shape box(std::string name, const Eigen::Vector3d& centre, const Eigen::Vector3d& size) {
  return Shape{.kind = Shape::Kind::Box, .name = std::move(name),
               .T_link_shape = pure_translation(centre.x(), centre.y(), centre.z()), .size = size};
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
            .T_parent_joint = pure_translation(kBoomPivotX, 0, kBoomPivotZ), .axis = minus_y};
  boom.shapes.push_back(box("boom", {0.5 * kBoomLength, 0, 0}, {kBoomLength, kBoomWidth, kBoomHeight}));
  m.links.push_back(std::move(boom));
  Link stick{.name = "stick", .parent = 2, .joint = Link::Joint::Revolute, .joint_name = joints::kStick,
             .T_parent_joint = pure_translation(kBoomLength, 0, 0), .axis = minus_y};
  stick.shapes.push_back(box("stick", {0.5 * kStickLength, 0, 0}, {kStickLength, kStickWidth, kStickHeight}));
  m.links.push_back(std::move(stick));
  Link tilt{.name = "rotator", .parent = 3, .joint = Link::Joint::Revolute, .joint_name = joints::kGripperPitch,
            .T_parent_joint = pure_translation(kStickLength, 0, 0), .axis = minus_y};
  Shape rotator{.kind = Shape::Kind::Cylinder, .name = "rotator", .T_link_shape = pure_translation(0.5 * kRotatorLength, 0, 0),
                .size = {2 * kRotatorRadius, 2 * kRotatorRadius, kRotatorLength}};
  rotator.T_link_shape.linear() = Eigen::AngleAxisd(0.5 * std::numbers::pi, Eigen::Vector3d::UnitY()).toRotationMatrix();
  tilt.shapes.push_back(rotator);
  m.links.push_back(std::move(tilt));
  // Gripper frame G: origin at the palm's front face, x = approach; the jaws pivot on it.
  Link gripper{.name = kGripperLink, .parent = 4, .joint = Link::Joint::Revolute, .joint_name = joints::kGripperRoll,
               .T_parent_joint = pure_translation(kRotatorLength + g.palm_depth, 0, 0), .axis = Eigen::Vector3d::UnitX()};
  gripper.shapes.push_back(part_shape(palm_part(g)));
  m.links.push_back(std::move(gripper));
  for (const JawSide side : {JawSide::Left, JawSide::Right}) {
    const ConvexPart jaw = jaw_part(g, side);
    Link link{.name = jaw.name, .parent = 5, .joint = Link::Joint::Revolute,
              .joint_name = side == JawSide::Left ? joints::kJawLeft : joints::kJawRight,
              .T_parent_joint = T_gripper_jaw(g, side, 0.0), .axis = jaw_axis(side)};
    link.shapes.push_back(part_shape(jaw));
    m.links.push_back(std::move(link));
  }
  m.validate();
  return m;
}

void set_jaw_opening(JointState& q, const GripperConfig& gripper, double opening) {
  const double angle = jaw_angle_for(gripper, opening);
  q.set(joints::kJawLeft, angle);
  q.set(joints::kJawRight, angle);
}

}  // namespace cairn
