#pragma once
// The walking excavator (a Menzi Muck M545-like machine, paper Sec. 3): a base standing levelled on
// its legs, a cabin on a yaw joint that swings back and forth during mapping, a boom/stick arm
// holding the two-jaw gripper in a parking pose, and two VLP-16 LiDARs on the front edge of the
// cabin roof, one horizontal and one vertical (paper Fig. 2).
//
// Frames: world W (= map M, gravity-aligned, z up), base B (on the swing axis, top of the
// chassis), cabin C (B rotated by the cabin yaw), sensors H and V, gripper G (robot/gripper.hpp). The machine's geometry: robot/excavator_model.hpp.
#include <Eigen/Geometry>
#include <string>
#include <utility>
#include <vector>

#include "cairn/robot/excavator_model.hpp"
#include "cairn/sim/procedural_site.hpp"

namespace cairn::sim {

/// The arm's joints (boom, stick, gripper pitch and roll, jaw opening); the cabin yaw swings on
/// its own. The parking pose of the mapping phase and the carry pose come from ExcavatorConfig;
/// Excavator::move_arm commands them.
struct ArmPose {
  double boom_deg = 0.0, stick_deg = 0.0, gripper_pitch_deg = 0.0, gripper_roll_deg = 0.0;
  double gripper_opening = 0.0;  // [m]

  template <class V>
  void visit(V& v) {
    v("boom_deg", boom_deg, "[deg] boom joint (raises the boom)");
    v("stick_deg", stick_deg, "[deg] stick joint");
    v("gripper_pitch_deg", gripper_pitch_deg, "[deg] gripper pitch");
    v("gripper_roll_deg", gripper_roll_deg, "[deg] gripper rotator");
    v("gripper_opening", gripper_opening, "[m] jaw opening");
  }
};

struct ExcavatorConfig {
  // Base placement on the site.
  double base_x = -6.0, base_y = 0.0;  // [m] swing axis position in the world
  double base_yaw_deg = 0.0;           // [deg] heading of the chassis (x forward)
  double base_height = 1.3;            // [m] swing-axis height above the terrain (legs)
  // Cabin swing during mapping: yaw(t) = amplitude * sin(2 pi t / period + phase).
  double swing_amplitude_deg = 110.0;
  double swing_period = 16.0;  // [s] (peak rate 43 deg/s at the defaults)
  double swing_phase_deg = 0.0;
  // Small cabin vibration from the hydraulics (roll and pitch about the base) [deg], [Hz].
  double vibration_deg = 0.05;
  double vibration_frequency = 2.7;
  /// Arm pose during mapping (joint axes: see make_excavator_model): the gripper hangs pointing
  /// down in front of the cabin, its palm ~2.2 m above the ground, seen by both LiDARs.
  ArmPose parking{.boom_deg = 52.0, .stick_deg = -132.0, .gripper_pitch_deg = -10.0, .gripper_roll_deg = 0.0,
                  .gripper_opening = 0.8};
  /// Arm pose while a grasped stone is carried (the cabin keeps swinging, so the LiDARs see the
  /// arm with the stone): boom up, stick in, gripper pointing down, its palm ~2.5 m above the
  /// ground, 0.25 m above the parking pose (the opening is the grasp's, set when it closes).
  ArmPose carry{.boom_deg = 55.0, .stick_deg = -125.0, .gripper_pitch_deg = -20.0, .gripper_roll_deg = 0.0,
                .gripper_opening = 0.0};
  // LiDAR mounts on the cabin roof's front edge, in the cabin frame [m].
  double lidar_x = 0.95, lidar_z = 2.5;  // brackets 0.3 m above the roof (2.2 m)
  double lidar_h_y = 1.0, lidar_v_y = -1.2;  // V just outside the cab side (1.1 m)

  template <class V>
  void visit(V& v) {
    v("base_x", base_x, "[m] swing axis x in the world");
    v("base_y", base_y, "[m] swing axis y in the world");
    v("base_yaw_deg", base_yaw_deg, "[deg] heading of the chassis");
    v("base_height", base_height, "[m] swing-axis height above the terrain");
    v("swing_amplitude_deg", swing_amplitude_deg, "[deg] cabin swing amplitude (+/-)");
    v("swing_period", swing_period, "[s] period of one full swing back and forth");
    v("swing_phase_deg", swing_phase_deg, "[deg] swing phase at t = 0");
    v("vibration_deg", vibration_deg, "[deg] cabin roll/pitch vibration amplitude");
    v("vibration_frequency", vibration_frequency, "[Hz] cabin vibration frequency");
    v("parking", parking, "arm pose during mapping");
    v("carry", carry, "arm pose while a grasped stone is carried");
    v("lidar_x", lidar_x, "[m] LiDAR mounts: x in the cabin frame");
    v("lidar_z", lidar_z, "[m] LiDAR mounts: z in the cabin frame");
    v("lidar_h_y", lidar_h_y, "[m] horizontal LiDAR: y in the cabin frame");
    v("lidar_v_y", lidar_v_y, "[m] vertical LiDAR: y in the cabin frame");
  }
};

class Excavator {
 public:
  /// Places the machine on the terrain (base levelled, base_height above the ground at the axis).
  Excavator(const ExcavatorConfig& config, const GripperConfig& gripper, const Terrain& terrain);

  [[nodiscard]] const RobotModel& model() const { return model_; }
  [[nodiscard]] const ExcavatorConfig& config() const { return config_; }
  [[nodiscard]] const GripperConfig& gripper() const { return gripper_; }

  /// True joint state at time t (cabin swing; the arm as arm_at(t)).
  [[nodiscard]] JointState joints_at(double t) const;
  /// The parking pose of the config (the arm during mapping).
  [[nodiscard]] ArmPose parked() const;
  /// The arm's pose at time t: the parking pose until the first move_arm, then the latest pose
  /// commanded at or before t (the arm moves between them faster than the sweeps resolve).
  [[nodiscard]] ArmPose arm_at(double t) const;
  /// From time t on the arm holds `pose`. Commands come in time order: InputError for a time
  /// before the last command's or a non-finite value.
  void move_arm(double t, const ArmPose& pose);
  /// True cabin yaw joint [rad] at time t.
  [[nodiscard]] double cabin_yaw(double t) const;
  /// True base pose (levelled, with the cabin vibration) at time t.
  [[nodiscard]] Eigen::Isometry3d T_world_base(double t) const;
  /// True cabin pose at time t.
  [[nodiscard]] Eigen::Isometry3d T_world_cabin(double t) const;
  /// Fixed, calibrated sensor mounts (horizontal: spin axis = cabin z; vertical: spin axis = cabin -y,
  /// so its scan fan is the cabin's vertical x-z plane, swept sideways by the swing).
  [[nodiscard]] Eigen::Isometry3d T_cabin_H() const;
  [[nodiscard]] Eigen::Isometry3d T_cabin_V() const;
  /// Link poses in the world at time t.
  [[nodiscard]] std::vector<Eigen::Isometry3d> link_poses(double t) const;

 private:
  ExcavatorConfig config_;
  GripperConfig gripper_;
  RobotModel model_;
  std::vector<std::pair<double, ArmPose>> arm_commands_;  // (from time, pose), by time
  Eigen::Isometry3d T_world_base0_ = Eigen::Isometry3d::Identity();
};

}  // namespace cairn::sim
