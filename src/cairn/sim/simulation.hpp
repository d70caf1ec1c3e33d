#pragma once
// `cairn simulate`: one scenario (site + excavator + sensors + drone) simulated over a duration and
// written as a run directory (core/io/run_dir.hpp, docs/run-directory.md).
//
// Scenarios (paper Sec. 6.1 and beyond):
//   exp1  seven stones of 0.5–1 m³ spread over ~50 m² in front of the machine (as Sec. 6.1);
//         two of them are real scanned stones (epfl-stone-models) scaled to the drawn volume.
//   exp2  a different arrangement: seven stones in a wide band across the machine's front, so the
//         cabin must swing to see them all; more flat stones, three real meshes.
//   pile  six stones touching each other in one heap (for later segmentation work).
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <nlohmann/json_fwd.hpp>
#include <optional>
#include <string>
#include <vector>

#include "cairn/robot/gripper.hpp"
#include "cairn/sim/drone.hpp"
#include "cairn/sim/excavator.hpp"
#include "cairn/sim/lidar.hpp"
#include "cairn/sim/physics/physics.hpp"
#include "cairn/sim/procedural_site.hpp"
#include "cairn/sim/state_estimation.hpp"

namespace cairn::sim {

struct SimulationConfig {
  SiteConfig site;
  ExcavatorConfig excavator;
  GripperConfig gripper;
  LidarConfig lidar;
  StateEstimationConfig state;
  DroneConfig drone;
  SamplingConfig snapshot;           // the dense ground-truth map snapshot
  PhysicsConfig physics;             // MuJoCo: the world at rest, grasp trials
  /// Settle the generated site in the physics before anything is sensed (settle_site, stones
  /// generated resting on the ground), so the sensors, the truth files and every later physics
  /// scene start from one world at rest (every generated site of seeds 1-50 of each scenario
  /// does: docs/simulator-physics.md). On in every scenario (scenario_config: `cairn simulate`,
  /// the experiments, `cairn grasp-trial`); off for a hand-built configuration, whose site is
  /// the generator's (placed, optionally tipped onto its support: SiteConfig::stones.settle).
  /// A settled site ignores site.stones.embed_depth (generated resting on the ground: make_site).
  bool settle_in_physics = false;
  double terrain_mesh_spacing = 0.05;  // [m] triangulation of the terrain for ray casting
  bool with_drone = true;             // fly the drone survey
  bool with_snapshot = true;          // write truth/map_snapshot.ply
  bool with_scan_truth = true;        // write per-point true labels of every sweep
  /// Stones the machine moves during a run (StoneMove) are held in the gripper this long (the arm
  /// in its carry pose, the sweeps seeing it); carried stones (StoneMove, carry_and_release in the
  /// experiments) are put down this high above the terrain and settled.
  double held_time = 4.0;     // [s]
  double drop_height = 0.03;  // [m]

  template <class V>
  void visit(V& v) {
    v("site", site, "terrain and stones");
    v("excavator", excavator, "machine placement, cabin swing, arm pose, LiDAR mounts");
    v("gripper", gripper, "two-jaw gripper geometry (shared with grasp planning)");
    v("lidar", lidar, "VLP-16 model (both sensors)");
    v("state", state, "state-estimation error model");
    v("drone", drone, "drone photogrammetry survey (Sec. 4.1)");
    v("snapshot", snapshot, "dense labelled ground-truth map snapshot");
    v("physics", physics, "MuJoCo physics (settling the site, grasp trials)");
    v("settle_in_physics", settle_in_physics, "settle the generated site in the physics before sensing");
    v("terrain_mesh_spacing", terrain_mesh_spacing, "[m] terrain triangulation for ray casting");
    v("with_drone", with_drone, "fly the drone survey");
    v("with_snapshot", with_snapshot, "write the dense ground-truth map snapshot");
    v("with_scan_truth", with_scan_truth, "write the true label of every scan point");
    v("held_time", held_time, "[s] a stone moved during the run is held in the gripper this long");
    v("drop_height", drop_height, "[m] a carried stone is released this high above the terrain");
  }
};

/// Names of the built-in scenarios.
std::vector<std::string> scenario_names();
/// The configuration of a scenario; throws ConfigError listing the known names otherwise.
/// `real_mesh_dir` holds the real scanned stones (epfl-stone-models); when empty or missing, the
/// scenario's real stones are procedural instead (a warning says so).
SimulationConfig scenario_config(const std::string& name, const std::filesystem::path& real_mesh_dir);

/// Directory of the real stone meshes: $CAIRN_STONE_MESH_DIR if set and present, else the meshes
/// shipped in the repository (data/stones, MIT, IBOIS/EPFL: see data/stones/SOURCE.md).
std::filesystem::path default_real_mesh_dir();

struct SimulationSummary {
  std::string scenario;
  std::uint64_t seed = 0;
  double duration = 0.0;
  std::size_t sweeps = 0, points = 0, rays = 0;
  std::size_t drone_points = 0, drone_images = 0;
  double seconds_site = 0, seconds_lidar = 0, seconds_drone = 0, seconds_write = 0, seconds_total = 0;
};

/// Progress callback: (stage, done, total).
using Progress = std::function<void(const std::string&, std::size_t, std::size_t)>;


/// The site of a simulation: generate_site(config.site, seed), or with settle_in_physics the
/// site generated resting on the ground (embed_depth 0) and settled (settle_site; the result in
/// `settle` when given). Deterministic for a seed.
Site make_site(const SimulationConfig& config, std::uint64_t seed, SiteSettleResult* settle = nullptr);

/// The drone survey's true map-from-SfM similarity of a run directory (truth/drone.json,
/// "T_map_drone"); InputError naming the file when it is missing or malformed.
[[nodiscard]] Similarity read_drone_truth(const std::filesystem::path& run);

/// A stone in the gripper: its site mesh (world coordinates, where it lay when grasped) mapped
/// into the gripper frame G by T_G_world, so it moves with the arm.
struct HeldStone {
  std::size_t stone = 0;
  Eigen::Isometry3d T_G_world = Eigen::Isometry3d::Identity();
};

/// Everything the simulator knows, for tests and other stages (no files): the site (stones where
/// they lie), the machine (its arm commands over time), the ray-cast scene of the ground and the
/// stones on it, and the stone the gripper holds, if any (ray-cast with the arm instead).
struct SimulatedWorld {
  Site site;
  Excavator excavator;
  RayScene scene;
  std::optional<HeldStone> held;
  std::unique_ptr<RayScene> held_scene;  // the held stone's mesh in the gripper frame
};
SimulatedWorld make_world(const SimulationConfig& config, std::uint64_t seed);
/// The machine and the ray-cast scene around a site made before (make_site): one settling for
/// several worlds of the same site.
SimulatedWorld make_world(const SimulationConfig& config, Site site);

/// Stone k taken into the gripper at time t (issue #15 item 2: the sweeps see the arm with the
/// stone while it is carried). From t on the arm holds config.excavator.carry with the jaws closed
/// on the stone (their opening: its width across the jaws), and the stone stays fixed in the
/// gripper frame where the grasp left it:
/// T_world_G_grasp is the true gripper pose when the jaws closed on the stone as it lies in the
/// site. The stone leaves the ground's ray-cast scene. Throws InputError when a stone is already
/// held, k is out of range or the pose is not finite, and as Excavator::move_arm.
void hold_stone(SimulatedWorld& world, std::size_t k, const Eigen::Isometry3d& T_world_G_grasp, double t,
                const SimulationConfig& config);
/// World pose at time t of the held stone's site mesh (vertex v lies at T * v); InputError when
/// nothing is held.
Eigen::Isometry3d held_stone_pose(const SimulatedWorld& world, double t);
/// The held stone let go at time t: the arm back in its parking pose from t, the stone back in
/// the ground's scene where the site has it (put it down with carry_and_release or
/// execute_grasp). Returns its index; InputError when nothing is held.
std::size_t release_stone(SimulatedWorld& world, double t, const SimulationConfig& config);

/// A stone the machine moves during a run (issue #15 item 2: runs with several scanning
/// segments): at `time` the gripper takes stone `stone` (the centred top-down grasp) and holds it
/// in its carry pose for SimulationConfig::held_time (the sweeps see the arm with it); then it is
/// put down shifted by `shift` [m] and turned by `turn_deg` about the vertical through its
/// centroid, drop_height above the terrain, and the site settles in the physics.
struct StoneMove {
  double time = 0.0;  // [s]
  std::size_t stone = 0;
  Eigen::Vector2d shift = Eigen::Vector2d::Zero();
  double turn_deg = 0.0;
};

/// InputError naming the move: a stone the site lacks, non-finite values, a move starting before
/// the run or within one LiDAR revolution after the previous one has put its stone down, or
/// ending after the run. ConfigError when there are moves and held_time is not longer than one
/// revolution.
void validate_moves(const std::vector<StoneMove>& moves, std::size_t stones, double duration,
                    const SimulationConfig& config);

/// The truth of one scanning segment: from t_start on, stone k lies at T_world_stone[k] (its mesh
/// at t = 0 moved), except the held one (held >= 0), fixed in the gripper frame by T_gripper_stone.
struct TruthSegment {
  double t_start = 0.0;
  int held = -1;
  Eigen::Isometry3d T_gripper_stone = Eigen::Isometry3d::Identity();
  std::vector<Eigen::Isometry3d> T_world_stone;
};

/// The moves of a run as they happen: advance(world, t) applies every pick-up and put-down due by
/// t to the world (hold_stone, release_stone + carry_and_release) and opens a segment for each.
class MoveScript {
 public:
  MoveScript(std::vector<StoneMove> moves, std::size_t stones);
  void advance(SimulatedWorld& world, double t, const SimulationConfig& config);
  /// Time of the next pick-up or put-down (+inf when none is left).
  [[nodiscard]] double next_event(const SimulationConfig& config) const;
  [[nodiscard]] const std::vector<TruthSegment>& segments() const { return segments_; }
  /// truth/segments.json: every segment with its end (the next one's start, or `duration`).
  [[nodiscard]] nlohmann::json to_json(double duration) const;

 private:
  std::vector<StoneMove> moves_;
  std::size_t next_ = 0;  // event 2i picks move i's stone up, 2i + 1 puts it down
  std::vector<TruthSegment> segments_;
};

/// Simulates `duration` seconds of the scenario and writes the run directory `out` (created; an
/// existing non-empty directory is an InputError unless `overwrite`). The machine moves stones as
/// `moves` say between its sweeps (validate_moves; truth/segments.json holds the truth of every
/// segment). Deterministic for a seed: the same inputs give identical files.
SimulationSummary simulate_run(const std::string& scenario, const SimulationConfig& config, std::uint64_t seed,
                               double duration, const std::filesystem::path& out, bool overwrite = false,
                               const Progress& progress = {}, const std::vector<StoneMove>& moves = {});

/// Executes a grasp plan in the physics (run_grasp_trial with config.gripper and
/// config.physics) on the world's site, then moves the world to where the physics left it: the
/// site's stones (apply_stone_poses) and the ray-cast scene, so the next sweeps, truth snapshots
/// and trials see the moved stones. The first step of issue #15's persistent world: the arm
/// still sits in its parking pose for the sensors, and the plan is executed at its map pose
/// (no state-estimate offset yet). Throws as run_grasp_trial.
GraspTrialResult execute_grasp(SimulatedWorld& world, const GraspPlan& plan, const SimulationConfig& config);

/// A held stone carried rigidly and put down (the outcome of a grasp that holds, for stages that
/// test what happens around the grasp, e.g. the object database): stone k is moved by T_motion
/// (world frame), lowered or raised so its lowest vertex is `drop_height` above the terrain,
/// released and settled with the rest of the site in the physics (settle_site); the ray-cast
/// scene is rebuilt. Returns the stone's total motion (the carry, the vertical correction and the
/// settling). Throws InputError on a bad index or a non-finite motion.
struct CarryResult {
  double lift = 0.0;  // [m] vertical correction of the carry (the machine lowers until contact)
  Eigen::Isometry3d carried = Eigen::Isometry3d::Identity();  // T_motion with the lift
  Eigen::Isometry3d total = Eigen::Isometry3d::Identity();    // carried, then the settling
  std::vector<Eigen::Isometry3d> settling;  // every stone's motion while the site settled
  bool settled = false;                     // the site came to rest
};
CarryResult carry_and_release(SimulatedWorld& world, std::size_t k, const Eigen::Isometry3d& T_motion,
                              double drop_height, const SimulationConfig& config);

/// The sweeps of both sensors in [0, duration): H starts at a random phase, V at another one (the
/// sensors are not synchronised). Returned in order of start time.
struct SweepSchedule {
  std::string sensor;
  int index;
  double t_start;
};
std::vector<SweepSchedule> sweep_schedule(const LidarConfig& lidar, double duration, std::uint64_t seed);

/// Simulates one scheduled sweep of the world.
Sweep simulate_scheduled_sweep(const SimulatedWorld& world, const LidarConfig& lidar, const SweepSchedule& s,
                               std::uint64_t seed);

}  // namespace cairn::sim
