#pragma once
// Two-jaw angular gripper of the excavator (paper Sec. 5): a palm and two jaws, each approximated
// by a convex polyhedron (here: boxes given by their 8 corners). One geometry for every stage:
// the simulator draws it into the LiDAR scans and grasps with it in MuJoCo, the self-filter pads
// it, and grasp planning checks collisions with it.
//
// Gripper frame G (GPD's hand frame):
//   x = approach direction (from the palm towards the object),
//   y = closing direction (the jaws move along -y / +y towards each other),
//   z = x × y.
// The origin lies at the centre of the palm's front face. The jaws extend from x = 0 to
// x = jaw_length; their inner faces lie at y = ±opening/2. The tool centre point (TCP) is at
// x = tcp_depth on the x-axis.
#include <Eigen/Core>
#include <string>
#include <vector>

namespace cairn {

struct GripperConfig {
  double palm_depth = 0.35;      // [m] along x (behind the origin: x in [-palm_depth, 0])
  double palm_width = 1.50;      // [m] along y
  double palm_height = 0.50;     // [m] along z
  double jaw_length = 0.80;      // [m] along x
  double jaw_thickness = 0.10;   // [m] along y
  double jaw_height = 0.45;      // [m] along z
  double max_opening = 1.20;     // [m] largest distance between the jaws' inner faces
  double tcp_depth = 0.50;       // [m] TCP on the x-axis
  double closing_force = 60e3;   // [N] hydraulic closing force of each jaw

  template <class V>
  void visit(V& v) {
    v("palm_depth", palm_depth, "[m] palm size along the approach axis x");
    v("palm_width", palm_width, "[m] palm size along the closing axis y");
    v("palm_height", palm_height, "[m] palm size along z");
    v("jaw_length", jaw_length, "[m] jaw length along the approach axis");
    v("jaw_thickness", jaw_thickness, "[m] jaw thickness along the closing axis");
    v("jaw_height", jaw_height, "[m] jaw size along z");
    v("max_opening", max_opening, "[m] largest distance between the jaws' inner faces");
    v("tcp_depth", tcp_depth, "[m] tool centre point on the approach axis");
    v("closing_force", closing_force, "[N] closing force of each jaw");
  }
};

/// One convex part of the gripper: its corner points in the gripper frame G.
struct ConvexPart {
  std::string name;                       // "palm", "jaw_left" (y < 0), "jaw_right" (y > 0)
  std::vector<Eigen::Vector3d> vertices;  // corners (boxes: 8)
  Eigen::Vector3d center = Eigen::Vector3d::Zero();        // box centre in G
  Eigen::Vector3d half_extents = Eigen::Vector3d::Zero();  // box half sizes along G's axes
};

/// Palm and the two jaws at the given opening (distance between the inner faces, clamped to
/// [0, max_opening]), in the gripper frame G.
std::vector<ConvexPart> gripper_parts(const GripperConfig& config, double opening);

}  // namespace cairn
