#pragma once
// Internal: the MuJoCo model of a site (MJCF generated in memory, loaded through a VFS) and thin
// accessors. Not part of the public API; use physics.hpp.
#include <mujoco/mujoco.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "cairn/robot/gripper.hpp"
#include "cairn/sim/physics/physics.hpp"
#include "cairn/sim/procedural_site.hpp"

namespace cairn::sim::detail {

/// What a geom belongs to: a stone index (>= 0) or one of these.
enum Entity : int { kTerrain = -1, kPalm = -2, kJawLeft = -3, kJawRight = -4 };
inline bool is_gripper(int e) { return e <= kPalm; }
std::string entity_name(int e);

struct SceneSpec {
  std::vector<Eigen::Isometry3d> start_poses;  // per stone T_world_stone at t = 0
  /// Per stone: a free body (true) or static (false: no joint, collides only with free bodies, no
  /// height-field collision). Empty: all free.
  std::vector<bool> free;
  bool with_gripper = false;
  Eigen::Isometry3d T_world_gripper = Eigen::Isometry3d::Identity();  // gripper start pose
  double opening = 1.0;                   // [m] jaw tip distance at the start
  std::vector<Eigen::Vector2d> extra_xy;  // points the height field must cover (gripper path)
};

struct Contact {
  int a = 0, b = 0;        // entities, a < b
  double depth = 0.0;      // [m] penetration (> 0)
  double normal_force = 0.0;  // [N]
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  // from a to b (MuJoCo's frame x axis)
};

/// One MuJoCo model + data of a site, owning both.
class Scene {
 public:
  Scene(const Site& site, const SceneSpec& spec, const GripperConfig& gripper,
        const PhysicsConfig& config);
  ~Scene();
  Scene(const Scene&) = delete;
  Scene& operator=(const Scene&) = delete;

  void step() { mj_step(m_, d_); }
  /// Lets overlaps left by the height field's sampling (stones in their moulds) resolve gently
  /// (nothing to do for a site at rest):
  /// PhysicsConfig::relax_time with soft contacts and viscous damping on the stones marked in
  /// `damped` (one flag per stone; undamped stones, e.g. dropped ones, fall freely), after which
  /// the damped stones' velocities are zeroed.
  void relax(const PhysicsConfig& config, const std::vector<bool>& damped);
  [[nodiscard]] double time() const { return d_->time; }
  [[nodiscard]] int num_stones() const { return static_cast<int>(stone_body_.size()); }
  [[nodiscard]] bool is_free(int k) const { return stone_qvel_[static_cast<std::size_t>(k)] >= 0; }
  /// Volume [m^3] of the convex hulls MuJoCo collides for stone k (its parts as MuJoCo sees them).
  [[nodiscard]] double hull_volume(int k) const;

  /// T_world_stone of stone k relative to its placement in the Site (identity = unmoved).
  [[nodiscard]] Eigen::Isometry3d stone_pose(int k) const;
  /// Body pose of stone k (origin at its original centroid, axes the world's at placement).
  [[nodiscard]] Eigen::Isometry3d stone_body_pose(int k) const;
  [[nodiscard]] double stone_mass(int k) const { return stone_mass_[static_cast<std::size_t>(k)]; }
  /// Radius of stone k about its centroid [m].
  [[nodiscard]] double stone_radius(int k) const { return stone_radius_[static_cast<std::size_t>(k)]; }
  /// Largest speed of any point of stone k [m/s].
  [[nodiscard]] double stone_point_speed(int k) const;
  /// Largest point speed over all stones [m/s].
  [[nodiscard]] double max_stone_speed() const;

  // Gripper (only when built with_gripper).
  [[nodiscard]] Eigen::Isometry3d gripper_pose() const;
  void set_gripper_target(const Eigen::Isometry3d& T_world_gripper);
  /// Jaw command: +1 closes with the full closing force, -1 opens.
  void set_jaw_command(double u);
  [[nodiscard]] double jaw_angle() const;  // [rad] mean of the two coupled jaws
  [[nodiscard]] double opening() const;    // [m] between the jaw tips
  [[nodiscard]] double jaw_speed() const;  // largest jaw tip speed [m/s]
  /// Vertical force [N] the arm (the weld to the mocap target) exerts on the gripper beyond the
  /// gripper's own weight: the load cell of the arm.
  [[nodiscard]] double arm_load() const;
  /// The force the arm's weld exerts on the gripper (world; z without the gripper's weight).
  [[nodiscard]] Eigen::Vector3d arm_force() const;
  /// The moment [N m] the arm's weld exerts on the gripper about the gripper's origin (world
  /// axes) beyond what the gripper's own weight needs: a load W hanging at r from the origin
  /// gives W (r_y, -r_x, 0) (the load cell's moment, with the gripper's own, known, mass taken out).
  [[nodiscard]] Eigen::Vector3d arm_moment() const;

  /// A box geom of the gripper in the world: its entity (kPalm, kJawLeft, kJawRight), pose and
  /// half sizes (the jaws are split into pads).
  struct GeomBox {
    int entity = kPalm;
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    Eigen::Vector3d half = Eigen::Vector3d::Zero();
  };
  [[nodiscard]] std::vector<GeomBox> gripper_boxes() const;

  /// Current contacts between different entities.
  [[nodiscard]] std::vector<Contact> contacts() const;
  /// Entity pairs whose contact buffer overflowed since the start (0 = fine).
  [[nodiscard]] int contact_overflows() const {
    return d_->warning[mjWARN_CONTACTFULL].number + d_->warning[mjWARN_CNSTRFULL].number;
  }

 private:
  mjModel* m_ = nullptr;
  mjData* d_ = nullptr;
  std::vector<int> stone_body_;
  std::vector<int> stone_qvel_;            // dof address of each stone's free joint (-1: static)
  std::vector<Eigen::Vector3d> centroid_;  // original centroids
  std::vector<double> stone_mass_, stone_radius_;
  std::vector<int> geom_entity_;
  /// Fills the geom → entity table, the stone bodies and dofs, the gripper's handles.
  void index_entities(const std::vector<bool>& free, bool with_gripper);

  GripperConfig gripper_;
  double gripper_weight_ = 0.0;
  bool at_rest_ = false;  // Site::at_rest: no seats, no gentle start
  int gripper_body_ = -1, mocap_ = -1, jaw_qpos_[2] = {-1, -1}, jaw_dof_[2] = {-1, -1};
};

}  // namespace cairn::sim::detail
