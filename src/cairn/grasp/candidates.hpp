#pragma once
// Grasp candidates (paper Sec. 5.3, GPD-style) for the angular two-jaw gripper of
// robot/gripper.hpp: a local reference frame per sample point (Eq. 4), rotated in discrete steps,
// the open gripper pushed along its approach until palm or jaws touch the planning cloud, and the
// closing of the coupled jaws simulated on the points to find where they touch the object.
// All geometry in the planning cloud's frame (PlanningCloud::cloud, relative to its origin).
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "cairn/core/kdtree.hpp"
#include "cairn/grasp/config.hpp"
#include "cairn/grasp/planning_cloud.hpp"
#include "cairn/robot/gripper.hpp"

namespace cairn::grasp {

/// Eq. 4: M(p) = sum of n n^T over the normals in the r-ball. Columns: x = the eigenvector of
/// the largest eigenvalue oriented along `normal` (away from the object), z = the smallest
/// (the axis of minimal curvature), y = z × x.
[[nodiscard]] Eigen::Matrix3d local_reference_frame(std::span<const Vec3f> normals, const Vec3d& normal);

/// The object points' (label kObject) shortest horizontal extent: the minor axis of their
/// covariance in the plane across `up` (unit, in that plane).
[[nodiscard]] Eigen::Vector3d minor_horizontal_axis(const PointCloud& cloud, const Eigen::Vector3d& up);

/// A box of the gripper, ready for sweeping points through it along the approach.
struct SweptBox {
  Eigen::Vector3d center, half;
  Eigen::Matrix3d axes;   // columns in G
  Eigen::Vector3d dir;    // axes^T (-x_G): a point's motion in box coordinates per unit advance
  Eigen::Vector2d shadow;  // half extents of the box's projection along x_G on G's (y, z): a
                           // point farther than this from the centre's (y, z) is never touched
};
/// The parts' boxes, each grown by `padding` across the approach (along G's y and z; a box's
/// axes are G's turned about z, so the growth is the padding seen along each box axis).
[[nodiscard]] std::vector<SweptBox> swept_boxes(const std::vector<ConvexPart>& parts, double padding = 0.0);

/// The advance s along +x_G at which the gripper (its boxes, points given in G at the start pose)
/// first touches a point: std::nullopt when a point is inside already (collision at the start),
/// +infinity when nothing is ever touched.
[[nodiscard]] std::optional<double> advance_to_contact(const std::vector<SweptBox>& boxes,
                                                       std::span<const Eigen::Vector3d> points_G);

/// The closing region of a pre-grasp opening, in G: x in (0, L] (the environment's up to a
/// clearance beyond), |y| <= closing_lateral(opening) (pivot, jaw and its thickness), |z| <= H/2.
[[nodiscard]] double closing_lateral(const GripperConfig& gripper, double opening);
/// Centre T * (L/2, 0, 0) of the closing region and the radius around it that holds the region
/// (T: G in the cloud's frame).
[[nodiscard]] Eigen::Vector3d closing_centre(const GripperConfig& gripper, const Eigen::Isometry3d& T);
[[nodiscard]] double closing_reach(const GripperConfig& gripper, double opening);

/// Closing the coupled jaws (one DoF) from `open_angle` on points in G: the jaws swing in until
/// both touch the object, which slides along y between them (the first jaw to touch pushes it).
struct Closing {
  bool closed = false;         // both jaws touch the object
  std::string failure;         // "empty" (nothing between the jaws), "collision_close" (a jaw
                               // sweeps through a non-object point first)
  double angle = 0.0;          // [rad] jaw angle at contact
  double shift = 0.0;          // [m] the object's slide along y_G while closing
  std::array<Eigen::Vector3d, 2> contacts{Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};  // left (y < 0), right: patch centres on the object (G)
  std::array<Eigen::Vector3d, 2> forces{Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};  // unit directions of the jaw forces on the object (G)
  std::array<Eigen::Vector3d, 2> normals{Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};  // mean outward surface normals of the patches (G; 0 if none)
  std::array<int, 2> patch_points{0, 0};
};
/// `clearance`: environment points closer than this to the jaws' swept area (beyond the tips,
/// inside the final faces) count as hit (the ground plane and the map are only this certain).
[[nodiscard]] Closing close_jaws(const GripperConfig& gripper, double open_angle,
                                 std::span<const Eigen::Vector3d> object_G, std::span<const Eigen::Vector3d> normals_G,
                                 std::span<const Eigen::Vector3d> environment_G, double patch, double clearance = 0.0);

/// One collision-checked grasp pose.
struct Candidate {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();  // G in the planning cloud's frame
  double opening = 0.0;  // [m] pre-grasp opening
  Closing closing;
};

struct CandidateCounts {
  std::size_t samples = 0, poses = 0;  // rotations tried
  std::size_t hypotheses = 0;       // pushed to contact, object points in the closing region
  std::size_t collision_free = 0;   // ... and the jaws close on the object without collision
};

/// The object's and the environment's points of a planning cloud near a pose, in G.
struct LocalPoints {
  std::vector<Eigen::Vector3d> object, normals, environment;
};
/// Points of `cloud` among `indices` transformed into G (T: G in the cloud's frame), kept when
/// they lie in the closing region of `opening` (the environment's up to `clearance` beyond the
/// jaws' length).
void gather_local(const PointCloud& cloud, std::span<const std::uint32_t> indices, const Eigen::Isometry3d& T,
                  double opening, const GripperConfig& gripper, LocalPoints& out, double clearance = 0.0);
/// The same points over all of `tree` (indexing cloud.points), without collecting indices first:
/// the region is visited as a few spheres along y_G, so the order differs from the list's.
void gather_local(const PointCloud& cloud, const KdTree& tree, const Eigen::Isometry3d& T, double opening,
                  const GripperConfig& gripper, LocalPoints& out, double clearance = 0.0);

/// Samples, rotates, pushes and closes (Sec. 5.3); `tree` indexes pc.cloud.points. Returns the
/// collision-free candidates in (sample, rotation) order; deterministic for the config's seed.
[[nodiscard]] std::vector<Candidate> generate_candidates(const PlanningCloud& pc, const KdTree& tree,
                                                         const GripperConfig& gripper,
                                                         const GraspConfig& config, CandidateCounts& counts);

}  // namespace cairn::grasp
