#pragma once
// Physics grasp trials (issue #4, item 6): the procedural site in MuJoCo 2.2.2 — stones as rigid
// bodies (MuJoCo collides the convex hulls of their meshes' convex parts; mass and inertia come from the closed
// meshes at rock density), the terrain as a height field sampled from Terrain::height around the
// stones, and the two-jaw angular gripper of robot/gripper.hpp (palm, two jaws on coupled pivots,
// one hydraulic DoF) — and the execution of one grasp (a GraspPlan, robot/grasp_plan.hpp):
// approach, close with the hydraulic force, lift, swing/rotate, place, release, settle.
//
// Success is the paper's (Sec. 6.3): "A grasp is deemed successful if it is collision-free, force
// closure and allows moving the object without dropping it"; slippage while lifting counts as a
// failure (the paper detects it by the jaws closing further). Failures carry stable reason codes.
//
// Stone poses: T_world_stone maps the stone's placement in the given Site (its mesh as stored)
// to its new placement; identity = unmoved. apply_stone_poses() moves the Site's meshes so the
// next scan sees the moved world.
//
// Everything is deterministic: same inputs, same results (MuJoCo runs single-threaded).
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <limits>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "cairn/robot/grasp_plan.hpp"
#include "cairn/robot/gripper.hpp"
#include "cairn/sim/procedural_site.hpp"

namespace cairn::sim {

// ---------------------------------------------------------------------------------------------
// Configuration

struct PhysicsConfig {
  // Simulation and materials.
  double timestep = 0.002;           // [s] MuJoCo time step
  /// Friction cone: "pyramidal" (2 (condim - 1) constraint rows per contact) or "elliptic"
  /// (condim rows; MuJoCo's Newton solver handles it directly). With pyramidal cones the soft
  /// frictional contacts creep: a stone squeezed by the jaws with a friction margin of 3 slid
  /// 1-2 cm/s along their faces, and most centred grasps failed as "slipped" (issue #17).
  std::string cone = "elliptic";
  int solver_iterations = 100;       // MuJoCo <option iterations>
  double solver_tolerance = 1e-8;    // MuJoCo <option tolerance>
  /// MuJoCo's no-slip post-pass (<option noslip_iterations>): removes the slow creep of soft
  /// frictional contacts, so a held stone stays put in the jaws while friction can hold it, and
  /// touching stones at rest stay at rest (0: off).
  int noslip_iterations = 10;
  double rock_density = 2600.0;      // [kg/m^3] granite/limestone boulders
  /// Collision hulls of a stone (one per convex part, Stone::collision_parts, else of the whole
  /// mesh): MuJoCo's convex hull of the part's extreme points along the 10 * 4^s + 2 directions
  /// of an icosphere with s = hull_subdivisions (< 0: of every point).
  int hull_subdivisions = 3;
  double friction = 0.6;             // sliding friction of every contact (rock–rock, rock–steel)
  double torsional_friction = 0.02;  // [m] torsional friction (resists spinning about a contact)
  /// [m] rolling friction: stands in for the gravel bed and the concavities the convex hulls
  /// smooth away, so rounded stones come to rest on slopes instead of rolling on.
  double rolling_friction = 0.02;
  /// [m] rolling friction of stone-ground contacts (MuJoCo takes the larger of the two geoms'):
  /// a 0.5-1 m^3 boulder beds into the gravel instead of rolling down a 5 % slope like a ball
  /// (0.1 m holds a 0.6 m radius stone on slopes up to ~16 %).
  double ground_rolling_friction = 0.1;
  /// [s] contact softness (MuJoCo solref time constant, >= 2 * timestep). The jaws press with
  /// tens of kN on a few hundred kg; softer contacts let them sink cm deep into the stone.
  double contact_timeconst = 0.005;
  double contact_impedance = 0.99;  // MuJoCo solimp dmax (dmin = contact_impedance - 0.04)
  // Terrain height field: only the region around the stones and the gripper's path.
  double terrain_resolution = 0.1;  // [m] height-field sample spacing
  double terrain_margin = 1.0;      // [m] around the stones' footprints and the gripper's path
  double terrain_base = 0.5;        // [m] depth of the height field's solid base below its minimum
  /// [m] height-field samples under a stone (at its placement in the Site) are lowered to this
  /// far below its hull's underside: stones embedded in the terrain start in a mould rather than
  /// overlapping the ground, which MuJoCo would resolve by launching them. < 0: no moulds.
  double seat_clearance = 0.002;
  /// [s] at the start, remaining overlaps (the height field is piecewise linear between samples)
  /// resolve for this long with soft contacts and damped stones, so stones do not jump.
  double relax_time = 0.2;
  double relax_timeconst = 0.05;  // [s] contact time constant and damping time while relaxing
  // Gripper dynamics (geometry and closing force come from GripperConfig).
  double palm_mass = 1200.0;      // [kg]
  double jaw_mass = 250.0;        // [kg] each
  double jaw_speed = 0.5;         // [m/s] free closing speed of a jaw tip (sets the joint damping)
  /// Each jaw is split into pads x pads boxes (same outer shape), so a flat contact gives several
  /// contact points (MuJoCo 2.2.2 reports one point per convex pair) and resists rotation.
  int jaw_pads = 2;
  double arm_timeconst = 0.01;    // [s] weld time constant of the arm holding the gripper
  /// [N] The arm's force limit while it carries (lift, hold, move): beyond it the hydraulics stall
  /// (relief valves) and the arm stops where it is, as a real arm does when the carried stone hits
  /// something; 2.3x the heaviest of the paper's stones (26 kN). The weld alone would drive on
  /// through the obstacle and fling stones.
  double arm_max_force = 60e3;
  /// [s] ... checked on the arm's force low-passed with this time constant: the hydraulics feel
  /// sustained pressure, while the weld's force rings at ~14 Hz about the load with single-step
  /// peaks of 90 kN under a 25 kN stone carried normally.
  double arm_stall_time = 0.1;
  // Trajectory (min-jerk segments; a segment lasts max(distance/speed, angle/rotation_speed)).
  double approach_speed = 0.3;  // [m/s] pre-grasp → grasp, and the retreat
  double lift_speed = 0.3;      // [m/s] lifting and lowering
  double move_speed = 0.8;      // [m/s] transport (swing) to above the place pose
  double rotation_speed = 0.5;  // [rad/s] largest rotation rate while moving
  double min_segment_time = 0.3;  // [s] shortest trajectory segment
  // Phases.
  double initial_settle_time = 0.3;  // [s] stones settle onto the height field before the trial
  double close_time = 3.0;   // [s] longest closing phase (ends earlier when the jaws stop)
  double hold_time = 0.5;    // [s] hold still after lifting and after moving (slip shows here)
  double release_time = 1.0;  // [s] opening the jaws at the place pose
  double settle_time = 3.0;   // [s] longest settling phase at the end
  double settle_speed = 0.01;  // [m/s] stones whose points move slower than this are at rest
  double settle_hold = 0.2;    // [s] ... for this long
  double jaw_stop_speed = 0.005;  // [m/s] closing has ended when both jaws are slower than this
  // Success criteria.
  /// A gripper contact is a collision when it is deeper than collision_depth or pushes harder
  /// than collision_force (stiff contacts stop the soft-welded gripper before it sinks in).
  double collision_depth = 0.005;  // [m]
  double collision_force = 2000.0;  // [N]
  /// Slip while lifting (paper Sec. 6.3): the jaws close further than this (its wire encoder).
  double jaw_slip_threshold = 0.02;  // [m]
  /// Slip while moving: stone motion relative to the gripper after it hangs still in the grip
  /// (end of the hold after lifting; the stone may first swing into place about the jaw axis).
  double slip_threshold = 0.05;        // [m] centroid displacement relative to the gripper
  double slip_angle_threshold = 0.17;  // [rad] rotation relative to the gripper (~10 deg)
  double drop_distance = 0.25;  // [m] relative motion since closing that counts as dropped
  /// Lowering to place stops when the arm's load, low-passed over place_filter_time, has fallen by
  /// this share of the load it carried (the ground carries it), or at the place pose. Measured on
  /// 161 trials of generated stones pressed 0.3 m below contact (docs/simulator-physics.md): the
  /// longer the jaws hold on, the less a stone tips or falls once they open (0.8: 55 of 120 moved
  /// more than 10 cm after the release; 0.95: 49; before the clip, 0.8: 78).
  double place_support_fraction = 0.95;
  /// [s] time constant of that low-pass (each load sample first clipped to [0, carried load]:
  /// a first touch rings the stiff contact at several times the weight, both signs).
  double place_filter_time = 0.1;
  /// When the set-down fires, the arm stops where it is (a hydraulic arm whose lowering command
  /// ends) rather than holding on to the last point of its lowering trajectory, which lies below
  /// the gripper once the ground carries the stone, and pressing towards it while the jaws open
  /// (release drift > 10 cm on 28 of 103 releases instead of 31, docs/simulator-physics.md,
  /// "The arm after the set-down, and feathering"). false: the former arm.
  bool place_stop_on_set_down = true;
  /// Feathering the set-down (off by default): once that load has fallen by place_touch_fraction
  /// (the stone touches), the arm goes on straight down at place_touch_speed until the set-down
  /// fires. At the lowering's own speed (up to ~0.56 m/s mid-segment) the filter's lag lets the arm
  /// drive on after the ground has taken the stone, pushing it through the grip onto its seat and
  /// often the jaw tips onto the ground. Feathered (0.2, 0.05 m/s), on 140 trials of fresh seeds
  /// the stones moved 3.5 cm in the grip instead of 12.8 (median), 33 releases had a jaw on the
  /// ground instead of 74, but 45 stones moved more than 10 cm after the release instead of 28:
  /// the push seats them (docs/simulator-physics.md, "The arm after the set-down, and
  /// feathering"). 0: no feathering. A stone not weighed is lowered on its contacts instead.
  double place_touch_fraction = 0.0;
  /// [m/s] Feathering's lowering speed after the touch (validated even when feathering is off).
  double place_touch_speed = 0.05;
  /// The release: converging jaws (a stone narrower than the pivots' spacing) swing their tips
  /// forwards and outwards as they open, so tips that stand on the ground when the stone is set
  /// down cannot open against it (the opening unchanged through the release phase, the arm's load
  /// -496 kN in its second half, median: docs/simulator-physics.md, "The release"). With
  /// release_backoff the arm backs off along the approach at release_backoff_speed while the jaws
  /// open, until the encoder reads the opening within release_open_tolerance of the plan's, at
  /// most release_backoff_max and never beyond the release phase (release_time): the operator's
  /// lift while opening. false: the arm holds still while the jaws open.
  bool release_backoff = true;
  double release_backoff_speed = 0.1;    // [m/s]
  double release_backoff_max = 0.1;      // [m]
  double release_open_tolerance = 0.02;  // [m]
  /// Placing by weight (GraspPlan::place_com_xy): the load the arm must carry for the weighing
  /// to count, and the largest horizontal shift of the place pose it may command.
  double weigh_min_load = 1000.0;     // [N]
  double max_place_correction = 0.5;  // [m]
  bool abort_on_failure = true;  // on a failure: open the jaws, retract upwards, settle
  /// [m] trials: only stones within this distance of the gripper's path (pre-grasp, grasp, lift,
  /// place; boxes around the jaws and the carried stone), and the stones touching those, are free
  /// bodies; the rest are static. A stone at rest that nothing can reach stays at rest, and each
  /// free stone costs a height-field collision per step (docs/simulator-physics.md, speed).
  double free_margin = 0.0;
  double trace_interval = 0.02;  // [s] trials: sampling of the jaw opening and arm load traces
  // Settling a whole site at generation (settle_site): the world at rest before anything is sensed.
  /// [m] stones whose bounding boxes come closer than this settle in one scene (an island);
  /// separate islands settle in separate scenes, in parallel.
  double island_gap = 0.3;
  double site_settle_time = 8.0;  // [s] longest settling of an island
  /// [m/s] a site is at rest when no stone point moved more than rest_speed * rest_hold over
  /// the last rest_hold seconds
  double rest_speed = 0.002;
  double rest_hold = 0.25;  // [s]
  /// A fresh scene started from a settled island (as every later scene of the site starts) moves
  /// its stones again by a little: restarts repeat until one moves no stone point more than
  /// rest_speed x rest_hold (at most restart_limit times). Some stones rock by ~1 mm-2 cm at every
  /// cold start and never get there; their island counts as at rest when the last restart moved
  /// no centroid more than restart_shift and turned no stone more than restart_turn_deg (the
  /// world-at-rest tolerance of issue #15: 1 cm, 1 deg).
  int restart_limit = 4;
  double restart_shift = 0.01;    // [m]
  double restart_turn_deg = 1.0;  // [deg]

  template <class V>
  void visit(V& v) {
    v("timestep", timestep, "[s] MuJoCo time step");
    v("cone", cone, "friction cone: pyramidal | elliptic");
    v("solver_iterations", solver_iterations, "MuJoCo solver iterations per step");
    v("solver_tolerance", solver_tolerance, "MuJoCo solver tolerance");
    v("noslip_iterations", noslip_iterations, "MuJoCo no-slip iterations (0: off)");
    v("rock_density", rock_density, "[kg/m^3] stone density (mass = mesh volume * density)");
    v("hull_subdivisions", hull_subdivisions, "collision hull from the extreme vertices along 10*4^s+2 directions (< 0: all)");
    v("friction", friction, "sliding friction coefficient of all contacts");
    v("torsional_friction", torsional_friction, "[m] torsional friction of all contacts");
    v("rolling_friction", rolling_friction, "[m] rolling friction of all contacts");
    v("ground_rolling_friction", ground_rolling_friction, "[m] rolling friction of stone-ground contacts (gravel bed)");
    v("contact_timeconst", contact_timeconst, "[s] contact softness (solref time constant)");
    v("contact_impedance", contact_impedance, "contact solimp dmax (dmin = dmax - 0.04)");
    v("terrain_resolution", terrain_resolution, "[m] height-field sample spacing");
    v("terrain_margin", terrain_margin, "[m] height-field margin around stones and gripper path");
    v("terrain_base", terrain_base, "[m] height-field base depth below its lowest sample");
    v("seat_clearance", seat_clearance, "[m] moulds carved under the stones' hulls (< 0: none)");
    v("relax_time", relax_time, "[s] gentle start: soft contacts and damped stones");
    v("relax_timeconst", relax_timeconst, "[s] contact and damping time constant while relaxing");
    v("palm_mass", palm_mass, "[kg] gripper palm mass");
    v("jaw_mass", jaw_mass, "[kg] mass of each jaw");
    v("jaw_speed", jaw_speed, "[m/s] free closing speed of a jaw");
    v("jaw_pads", jaw_pads, "each jaw is split into jaw_pads x jaw_pads boxes (contact points)");
    v("arm_timeconst", arm_timeconst, "[s] stiffness of the arm (weld time constant)");
    v("arm_max_force", arm_max_force, "[N] the arm stalls (stops where it is) above this force while carrying");
    v("arm_stall_time", arm_stall_time, "[s] time constant of the low-passed arm force checked against arm_max_force");
    v("approach_speed", approach_speed, "[m/s] approach and retreat speed");
    v("lift_speed", lift_speed, "[m/s] lifting and lowering speed");
    v("move_speed", move_speed, "[m/s] transport speed");
    v("rotation_speed", rotation_speed, "[rad/s] largest rotation rate");
    v("min_segment_time", min_segment_time, "[s] shortest trajectory segment");
    v("initial_settle_time", initial_settle_time, "[s] settling before the trial starts");
    v("close_time", close_time, "[s] longest closing phase");
    v("hold_time", hold_time, "[s] holding still after lifting and after moving");
    v("release_time", release_time, "[s] jaw opening time at the place pose");
    v("settle_time", settle_time, "[s] longest final settling phase");
    v("settle_speed", settle_speed, "[m/s] rest speed of stones");
    v("settle_hold", settle_hold, "[s] stones must stay below settle_speed this long");
    v("jaw_stop_speed", jaw_stop_speed, "[m/s] jaws slower than this have stopped closing");
    v("collision_depth", collision_depth, "[m] penetration counted as a collision");
    v("collision_force", collision_force, "[N] gripper contact force counted as a collision");
    v("jaw_slip_threshold", jaw_slip_threshold, "[m] further jaw closing while lifted = slip");
    v("slip_threshold", slip_threshold, "[m] largest stone motion relative to the gripper");
    v("slip_angle_threshold", slip_angle_threshold, "[rad] largest stone rotation rel. to gripper");
    v("drop_distance", drop_distance, "[m] relative motion that counts as a drop");
    v("place_support_fraction", place_support_fraction,
      "share of the carried load the arm's (low-passed) load must lose to end lowering");
    v("place_filter_time", place_filter_time, "[s] time constant of the low-passed load that ends lowering");
    v("place_stop_on_set_down", place_stop_on_set_down,
      "the arm stops where it is when the set-down fires (else it presses on to its last command)");
    v("place_touch_fraction", place_touch_fraction,
      "share of the carried load the ground takes at the touch that slows the lowering (0: no feathering)");
    v("place_touch_speed", place_touch_speed, "[m/s] lowering speed after the touch until the set-down");
    v("release_backoff", release_backoff, "the arm backs off along the approach while the jaws are not yet open");
    v("release_backoff_speed", release_backoff_speed, "[m/s] release_backoff: speed of the back-off");
    v("release_backoff_max", release_backoff_max, "[m] release_backoff: the farthest back-off");
    v("release_open_tolerance", release_open_tolerance, "[m] release_backoff: jaws this close to the plan's opening are open");
    v("weigh_min_load", weigh_min_load, "[N] placing by weight: the least load the weighing counts");
    v("max_place_correction", max_place_correction, "[m] placing by weight: the largest shift of the place pose");
    v("abort_on_failure", abort_on_failure, "open, retract and settle as soon as a grasp fails");
    v("free_margin", free_margin, "[m] trials: stones this close to the gripper path are free bodies");
    v("trace_interval", trace_interval, "[s] trials: sampling interval of the jaw and load traces");
    v("island_gap", island_gap, "[m] site settling: stones closer than this settle together");
    v("site_settle_time", site_settle_time, "[s] site settling: longest settling of one island");
    v("rest_speed", rest_speed, "[m/s] site settling: largest mean point speed over a window at rest");
    v("rest_hold", rest_hold, "[s] site settling: the window");
    v("restart_limit", restart_limit, "site settling: most restarts of a settled island from its rest poses");
    v("restart_shift", restart_shift, "[m] site settling: largest centroid shift of the last restart at rest");
    v("restart_turn_deg", restart_turn_deg, "[deg] site settling: largest rotation of the last restart at rest");
  }
};

/// Throws ConfigError naming the first invalid field.
void validate(const PhysicsConfig& config);

// ---------------------------------------------------------------------------------------------
// Grasp trials

/// Stable failure reason codes.
namespace reason {
inline constexpr const char* kCollisionApproach = "collision_approach";  // gripper hit something
inline constexpr const char* kCollisionClose = "collision_close";  // a jaw hit terrain closing
inline constexpr const char* kCollisionTransport = "collision_transport";  // lift/move contacts
inline constexpr const char* kEmptyGrasp = "empty_grasp";          // nothing between the jaws
inline constexpr const char* kMultipleStones = "multiple_stones";  // jaws on different stones
inline constexpr const char* kWrongStone = "wrong_stone";          // not plan.target_stone
inline constexpr const char* kSlipped = "slipped";  // relative motion beyond the slip threshold
inline constexpr const char* kDropped = "dropped";  // stone left the jaws while moving
inline constexpr const char* kArmStalled = "arm_stalled";  // the arm's force limit stopped the carry
}  // namespace reason

struct PhaseTiming {
  std::string name;  // approach, close, lift, move, hold, place, release, retreat, settle, abort
  double start = 0.0, end = 0.0;  // [s] simulated time
  double wall = 0.0;              // [s] elapsed (not deterministic)
};

/// What the machine measures during a trial (Sec. 6.3: slip shows as the jaws closing further,
/// a drop as the arm's load falling): the jaw angle (its wire-draw encoder), the tip opening it
/// gives, and the load the arm carries beyond the gripper's own weight (from the force of the
/// arm's weld on the gripper).
struct TraceSample {
  double time = 0.0;       // [s] simulated
  double jaw_angle = 0.0;  // [rad] the jaws' angle (robot/gripper.hpp; both share it)
  double opening = 0.0;    // [m] distance between the jaw tips (from the angle)
  double arm_load = 0.0;   // [N] vertical load on the arm minus the gripper's weight (static)
  /// Diagnostics (simulator truth, never a machine signal): the target stone's body origin in
  /// the gripper frame.
  Eigen::Vector3d stone_in_gripper = Eigen::Vector3d::Zero();
};

struct GraspTrialResult {
  bool success = false;
  std::vector<std::string> failure_reasons;  // codes from `reason`, first occurrence order
  std::string message;                       // human-readable summary (which part hit what, ...)
  int grasped_stone = -1;                    // stone held by both jaws after closing
  double grasp_opening = 0.0;   // [m] jaw distance after closing
  double slip_distance = 0.0;   // [m] largest stone displacement relative to the gripper while
                                //     moving (after hanging still in the grip)
  double slip_angle = 0.0;      // [rad] largest stone rotation relative to the gripper (same)
  double swing_in = 0.0;        // [m] stone displacement in the grip while lifting (no failure)
  double jaw_travel = 0.0;      // [m] further jaw closing while lifted (the paper's encoder)
  double place_error = -1.0;    // [m] final stone centroid vs expected placement (-1: not placed)
  /// Diagnostics of the placement (simulator truth, never a machine signal; NaN / -1 when the
  /// stone was not carried to the release): the held stone's centre of mass where the jaws
  /// opened and at rest after the settle, and how far it had moved relative to the gripper
  /// between the start of the lift and the jaws' opening [m].
  Eigen::Vector3d released_centroid = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  Eigen::Vector3d rest_centroid = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  double grip_drift = -1.0;
  /// The stone's motion relative to the gripper from the start of the lowering to place to the
  /// jaws' opening [m] (the ground pushing it through the grip).
  double set_down_drift = -1.0;
  /// Whether the ground carried the stone (place_support_fraction of its weight) when the jaws
  /// opened, and what the gripper touched then other than the held stone ("jaw_left:terrain").
  bool released_on_support = false;
  std::vector<std::string> release_touches;
  /// Machine signals of the release (the encoder, the arm's own command): how far the jaws opened
  /// during the release phase [m] (NaN: no release phase with a lifted stone):
  /// about the plan's opening minus the closed one when they opened freely, ~0 when their tips
  /// were held by the ground.
  double release_opened = std::numeric_limits<double>::quiet_NaN();
  double release_backoff = 0.0;  // [m] ... and how far the arm backed off meanwhile (release_backoff)
  /// Placing by weight (GraspPlan::place_com_xy): the centre of mass the arm weighed while the
  /// stone hung still (world; x, y measured, z the gripper's; NaN when not weighed) and the
  /// horizontal shift of the place pose it commanded (-1: none).
  Eigen::Vector3d weighed_com = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  double place_correction = -1.0;
  /// The arm stalled while carrying (its force above arm_max_force: the machine measures it) and
  /// lowered the stone where it stopped.
  bool arm_stalled = false;
  /// Commanded gripper pose when the jaws opened (the machine's kinematics: where lowering
  /// stopped on contact, or the plan's place pose; after an early stop, where the arm was).
  Eigen::Isometry3d T_world_release = Eigen::Isometry3d::Identity();
  /// Per stone T_world_stone after settling (identity = at its placement in the given Site).
  std::vector<Eigen::Isometry3d> stone_poses;
  bool settled = false;          // all stones at rest at the end
  /// Per stone T_world_stone after the initial settle-in, before the gripper moves (identity =
  /// the world was at rest), and the largest stone point speed then [m/s].
  std::vector<Eigen::Isometry3d> initial_stone_poses;
  double initial_max_speed = 0.0;
  int free_stones = 0;  // stones simulated as free bodies (the rest static: PhysicsConfig::free_margin)
  std::vector<TraceSample> trace;  // every PhysicsConfig::trace_interval
  std::vector<PhaseTiming> phases;
  double sim_time = 0.0;   // [s] simulated
  double wall_time = 0.0;  // [s] elapsed (not deterministic)
};

/// Runs one grasp trial. Throws ConfigError on invalid configs, InputError on an invalid plan
/// (non-finite or non-rigid poses, opening outside (0, max_opening], empty site) or when MuJoCo
/// rejects the generated model.
GraspTrialResult run_grasp_trial(const Site& site, const GraspPlan& plan,
                                 const GripperConfig& gripper, const PhysicsConfig& config);

// ---------------------------------------------------------------------------------------------
// Settling / drop tests

struct SettleResult {
  std::vector<Eigen::Isometry3d> stone_poses;  // T_world_stone at rest (identity = unmoved)
  bool settled = false;    // all stones came to rest within settle_time
  double max_speed = 0.0;  // [m/s] largest point speed of any stone at the end
  double sim_time = 0.0, wall_time = 0.0;  // [s]
};

/// Lets the stones fall/settle without the gripper. `start_poses` (empty, or one per stone) are
/// the initial T_world_stone (e.g. a translation upwards for a drop test). Throws InputError when
/// start_poses has the wrong size.
SettleResult settle_stones(const Site& site, const PhysicsConfig& config,
                           std::span<const Eigen::Isometry3d> start_poses = {});

/// The world at rest: settles every stone of `site` in the physics and moves the site's stones to
/// where they came to rest (apply_stone_poses). Stones form islands (bounding boxes within
/// island_gap); each island settles in its own scene (stones of other islands absent), islands in
/// parallel, until every stone point stayed slower than rest_speed for rest_hold (at most
/// site_settle_time). When a stone comes to rest near another island, the joined island is
/// settled again from the generated poses, so stones that meet interact. Deterministic.
struct SiteSettleResult {
  std::vector<Eigen::Isometry3d> stone_poses;  // T_world_stone relative to the generated placement
  bool settled = false;       // every island came to rest
  int islands = 0;            // islands of the final partition
  int rounds = 0;             // settling rounds (> 1 when islands joined)
  double max_displacement = 0.0;  // [m] largest centroid motion of a stone
  double max_rotation = 0.0;      // [rad] largest rotation of a stone
  /// Largest centroid shift [m] and rotation [rad] of a stone in its island's last restart (what
  /// a later scene starting from the site moves it by, within restart_shift / restart_turn_deg)
  double restart_shift = 0.0, restart_turn = 0.0;
  double sim_time = 0.0;   // [s] simulated, summed over islands and rounds
  double wall_time = 0.0;  // [s]
};
SiteSettleResult settle_site(Site& site, const PhysicsConfig& config);

/// Volume [m^3] of each stone's collision shape as MuJoCo builds it (hull_subdivisions): the
/// hulls of its convex parts together, which add what the parts' concavities leave out
/// (docs/simulator-physics.md).
std::vector<double> collision_hull_volumes(const Site& site, const PhysicsConfig& config);

/// Moves the stones of `site` by their poses (mesh vertices, centroid, bounds, yaw += rotation
/// about z), so sampling the site afterwards sees the moved world. Throws InputError when the
/// number of poses differs from the number of stones.
void apply_stone_poses(Site& site, std::span<const Eigen::Isometry3d> poses);

// ---------------------------------------------------------------------------------------------
// Grasp helpers

struct CentredGraspOptions {
  double palm_clearance = 0.05;  // [m] palm face above the stone's top
  double tip_clearance = 0.05;   // [m] jaw tips above the terrain (or the stone's bottom)
  double opening_margin = 0.10;  // [m] the open jaws clear the stone by this much (capped)
  double approach_distance = 0.5;  // [m]
  double lift_height = 1.0;        // [m]
  Eigen::Vector2d place_offset = Eigen::Vector2d(2.0, 0.0);  // [m] world xy shift of the place
  double place_yaw = 0.0;  // [rad] rotation of the place pose about the vertical (the swing)
  double place_drop = 0.02;  // [m] release this high above the ground contact pose
};

/// Top-down centred antipodal grasp: approach straight down (x_G = -z), closing along the stone's
/// shortest horizontal extent through its centroid; palm just above the stone's top, lowered
/// further only while the jaw tips stay above the terrain (when given; else above the stone's
/// lowest point). The place pose is the grasp pose shifted by place_offset, rotated by place_yaw
/// about the vertical through the grasp and raised/lowered with the terrain (when given).
GraspPlan centred_antipodal_grasp(const Stone& stone, const GripperConfig& gripper,
                                  const Terrain* terrain = nullptr,
                                  const CentredGraspOptions& options = {});

/// Shortest horizontal extent of a stone [m] and the unit direction (xy) along which it occurs.
std::pair<double, Eigen::Vector2d> shortest_horizontal_extent(const Stone& stone);

}  // namespace cairn::sim
