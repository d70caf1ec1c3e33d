#pragma once
// A kinematic tree of rigid links with simple collision shapes (boxes and cylinders). The
// simulator describes the excavator with it and writes it to `robot.json`; the mapping stage's
// self-filter reads it back and poses the shapes from the recorded joint states.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <nlohmann/json_fwd.hpp>
#include <string>
#include <vector>

namespace cairn {

struct Shape {
  enum class Kind { Box, Cylinder };
  Kind kind = Kind::Box;
  std::string name;
  Eigen::Isometry3d T_link_shape = Eigen::Isometry3d::Identity();
  /// Box: full side lengths along the shape's x, y, z. Cylinder: (2 r, 2 r, length), axis z.
  Eigen::Vector3d size = Eigen::Vector3d::Ones();

  /// Whether p (shape frame) lies inside the shape grown by `padding` [m].
  [[nodiscard]] bool contains(const Eigen::Vector3d& p, double padding = 0.0) const;
  /// Ray parameter of the first entry into the shape (shape frame; ray origin o, direction d),
  /// or +inf when the ray misses. An origin inside gives 0.
  [[nodiscard]] double intersect(const Eigen::Vector3d& o, const Eigen::Vector3d& d) const;
  /// Radius of the sphere around the shape's origin that contains it.
  [[nodiscard]] double bounding_radius() const;
};

/// The box around `points` (in a link's frame) along their principal axes: how a held object,
/// known only as points, becomes a shape the self-filter pads like the links. InputError when
/// there are no points or one is not finite.
[[nodiscard]] Shape bounding_box_shape(std::string name, const std::vector<Eigen::Vector3d>& points);

struct Link {
  enum class Joint { Fixed, Revolute, Prismatic };
  std::string name;
  int parent = -1;  // index into RobotModel::links; -1 for the root
  Joint joint = Joint::Fixed;
  std::string joint_name;  // key of this joint's value in a joint state
  Eigen::Isometry3d T_parent_joint = Eigen::Isometry3d::Identity();  // joint origin in the parent
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();  // joint axis in the joint frame (unit)
  std::vector<Shape> shapes;
};

/// Joint values by name ([rad] for revolute, [m] for prismatic joints).
struct JointState {
  double time = 0.0;
  std::vector<std::string> names;
  std::vector<double> positions;
  [[nodiscard]] double get(const std::string& name, double fallback = 0.0) const;
  void set(const std::string& name, double value);
};

/// Joint values at time t: linear interpolation between the two neighbouring states (joints by
/// name, clamped at the ends). `states` sorted by time; throws InputError when empty.
[[nodiscard]] JointState interpolate_joints(const std::vector<JointState>& states, double t);

struct RobotModel {
  std::string name;
  std::vector<Link> links;  // parents come before their children; links[0] is the root

  [[nodiscard]] int link_index(const std::string& name) const;  // -1 if absent
  /// T_root_link for every link (joints missing from `q` are at 0).
  [[nodiscard]] std::vector<Eigen::Isometry3d> forward_kinematics(const JointState& q) const;
  /// Names of the non-fixed joints in link order.
  [[nodiscard]] std::vector<std::string> joint_names() const;
  /// Throws InputError when parents are out of order or axes are not unit vectors.
  void validate() const;
};

nlohmann::json to_json(const RobotModel& robot);
/// Throws InputError on missing keys or bad values.
RobotModel robot_from_json(const nlohmann::json& j);
/// Reads `robot.json`; throws InputError naming the file.
RobotModel read_robot_model(const std::string& path);

}  // namespace cairn
