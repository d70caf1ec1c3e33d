#pragma once
// The excavator's two-jaw angular gripper (paper Sec. 5): "Both jaws are mechanically connected
// and are moved by the same hydraulic actuator, giving one DoF. The jaws are mounted on the base
// part of the gripper that we will further reference to as palm." The one definition of its
// geometry: the physics (sim/physics), the excavator's link shapes (robot/excavator_model, which
// the LiDAR model ray-casts and the self-filter pads) and grasp planning all build from it.
//
// Gripper frame G (GPD's hand frame):
//   x = approach direction (from the palm towards the object),
//   y = closing direction (the jaws swing towards each other across y),
//   z = x × y (the jaws' pivot axes are parallel to z).
// The origin lies at the centre of the palm's front face (x = 0); the palm fills x in
// [-palm_depth, 0]. Each jaw pivots about a hinge on the palm's front face at y = ∓hinge_spacing/2
// (left: y < 0). At jaw angle 0 both jaws point straight along +x; a positive angle swings the
// tips outwards (opens), a negative one inwards. Both jaws always share one angle (coupled).
// A jaw is a box in its hinge frame J (x along the jaw, hinge at the origin, z = G's z): from
// the hinge to the tip (x in [0, jaw_length]), its inner face through the hinge (the jaw's
// thickness lies outwards), jaw_height along z.
//
// The opening (what the grasp plan commands and the wire-draw encoder of the paper's Sec. 6.3
// reports, converted) is the distance between the two jaws' inner tip edges.
//
// Defaults fit 0.5-1 m^3 boulders (0.9-1.6 m across their shortest horizontal extent on the
// scenarios' stones, mostly 1.0-1.2 m): the pivots sit 1.4 m apart, so most stones are held by jaws that converge
// towards their tips and touch the stone below its widest section, cradling it (diverging jaws
// touch a rounded stone above it and squeeze it out: with pivots 0.8 m apart the centred grasp
// held 0 of 7 exp1 stones, with 1.4 m 5 of 14; docs/simulator-physics.md). The tips open to
// 2.55 m (35 deg) and reach 1 m down. These are this project's assumptions: the paper gives no
// dimensions.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <string>
#include <vector>

namespace cairn {

struct GripperConfig {
  double palm_depth = 0.40;      // [m] along x (behind the origin: x in [-palm_depth, 0])
  double palm_width = 1.60;      // [m] along y
  double palm_height = 0.60;     // [m] along z
  double hinge_spacing = 1.40;   // [m] distance between the two jaw pivots (along y)
  double jaw_length = 1.00;      // [m] pivot to tip
  double jaw_thickness = 0.12;   // [m] across the jaw (outwards from its inner face)
  double jaw_height = 0.50;      // [m] along z
  double max_jaw_angle_deg = 35.0;  // [deg] fully open (tips 2.55 m apart at the defaults)
  double closed_gap = 0.01;      // [m] fully closed, the tips stop this far apart
  double tcp_depth = 0.60;       // [m] tool centre point on the x-axis
  double closing_force = 60e3;   // [N] hydraulic closing force of each jaw, at its tip

  template <class V>
  void visit(V& v) {
    v("palm_depth", palm_depth, "[m] palm size along the approach axis x");
    v("palm_width", palm_width, "[m] palm size along the closing axis y");
    v("palm_height", palm_height, "[m] palm size along z");
    v("hinge_spacing", hinge_spacing, "[m] distance between the jaw pivots on the palm's face");
    v("jaw_length", jaw_length, "[m] jaw length from pivot to tip");
    v("jaw_thickness", jaw_thickness, "[m] jaw thickness (outwards from its inner face)");
    v("jaw_height", jaw_height, "[m] jaw size along z");
    v("max_jaw_angle_deg", max_jaw_angle_deg, "[deg] jaw angle fully open (0: jaws parallel)");
    v("closed_gap", closed_gap, "[m] distance between the tips fully closed");
    v("tcp_depth", tcp_depth, "[m] tool centre point on the approach axis");
    v("closing_force", closing_force, "[N] closing force of each jaw at its tip");
  }
};

/// Throws ConfigError naming the first invalid field (the hinges must lie on the palm, the open
/// tips must not meet, ...).
void validate(const GripperConfig& config);

enum class JawSide { Left, Right };  // left: y < 0

/// Distance between the inner tip edges at jaw angle `angle` [rad] (not clamped).
double opening_at(const GripperConfig& config, double angle);
/// Jaw angle [rad] whose opening is `opening`, clamped to [min_jaw_angle, max_jaw_angle].
double jaw_angle_for(const GripperConfig& config, double opening);
/// Fully closed (tips closed_gap apart) and fully open jaw angles [rad], and the largest opening.
double min_jaw_angle(const GripperConfig& config);
double max_jaw_angle(const GripperConfig& config);
double max_opening(const GripperConfig& config);
/// Hydraulic torque on each jaw's pivot [N m]: closing_force at the tip.
double closing_torque(const GripperConfig& config);

/// The hinge frame J of one jaw at jaw angle `angle`, in G.
Eigen::Isometry3d T_gripper_jaw(const GripperConfig& config, JawSide side, double angle);
/// Pivot axis of a jaw in its hinge frame: a positive angle about it opens the jaw.
Eigen::Vector3d jaw_axis(JawSide side);

/// One convex part of the gripper: a box, its corner points and centre/half sizes in the frame
/// it is given in, with the box's axes (`axes`, columns) in that frame.
struct ConvexPart {
  std::string name;                       // "palm", "jaw_left" (y < 0), "jaw_right" (y > 0)
  std::vector<Eigen::Vector3d> vertices;  // corners (8)
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  Eigen::Vector3d half_extents = Eigen::Vector3d::Zero();  // along the box's axes
  Eigen::Matrix3d axes = Eigen::Matrix3d::Identity();

  /// Whether p (same frame) lies inside the box grown by `padding`.
  [[nodiscard]] bool contains(const Eigen::Vector3d& p, double padding = 0.0) const;
};

/// The palm in G.
ConvexPart palm_part(const GripperConfig& config);
/// A jaw in its own hinge frame J (independent of the angle).
ConvexPart jaw_part(const GripperConfig& config, JawSide side);
/// Palm and the two jaws at the given opening (clamped to the jaw range), in G.
std::vector<ConvexPart> gripper_parts(const GripperConfig& config, double opening);

/// The jaws' inner faces at one jaw angle, in G's xy-plane: y = ∓(hinge_spacing/2 + x tan(angle))
/// from the pivots (x = 0) to the tips (x = reach), precomputed for evaluation point by point.
struct JawLines {
  double half_spacing = 0.0, length = 0.0, height = 0.0;  // [m] pivots, jaw length and height
  double tan_angle = 0.0, reach = 0.0;                    // tan(angle), length * cos(angle)
  [[nodiscard]] double left(double x) const { return -half_spacing - x * tan_angle; }
  [[nodiscard]] double right(double x) const { return half_spacing + x * tan_angle; }
  /// Between the inner faces, in front of the palm, within the jaws' reach and height.
  [[nodiscard]] bool encloses(const Eigen::Vector3d& p_G) const {
    return p_G.x() > 0.0 && p_G.x() <= reach && std::abs(p_G.z()) <= 0.5 * height && p_G.y() > left(p_G.x()) &&
           p_G.y() < right(p_G.x());
  }
};
[[nodiscard]] JawLines jaw_lines(const GripperConfig& config, double angle);

/// Closing region at the given opening, in G: the points a closing grasp could enclose —
/// between the jaws' inner faces, in front of the palm, within the jaws' height.
[[nodiscard]] bool in_closing_region(const GripperConfig& config, double opening, const Eigen::Vector3d& p_G);

}  // namespace cairn
