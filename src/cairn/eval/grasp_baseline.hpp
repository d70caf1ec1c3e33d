#pragma once
// The baseline grasp planning must beat (issue #15, item 8): the centred top-down antipodal grasp
// (sim::centred_antipodal_grasp) of every stone of simulated sites, executed in the physics with
// the angular gripper. Each trial: the site of (scenario, seed) settled at rest, approach, close,
// lift, a quarter turn about the vertical (the move; rotating in place keeps the trial about the
// grasp, not about whether a place next to it is free), lower it back, release, settle.
// Trials run in parallel (each is deterministic, so the results do not depend on scheduling).
#include <cstdint>
#include <functional>
#include <numbers>
#include <map>
#include <string>
#include <vector>

#include "cairn/robot/gripper.hpp"
#include "cairn/sim/physics/physics.hpp"

namespace cairn::eval {

struct GraspBaselineConfig {
  std::vector<std::string> scenarios = {"exp1", "exp2"};
  std::vector<std::uint64_t> seeds = {1, 2, 3, 4};
  double place_yaw = 0.5 * std::numbers::pi;  // [rad] the move: a quarter turn about the vertical
  /// Real stone meshes (*.ply) the scenarios draw from; empty: sim::default_real_mesh_dir().
  std::string mesh_dir;
  sim::PhysicsConfig physics;
  GripperConfig gripper;
};

struct GraspBaselineTrial {
  std::string scenario;
  std::uint64_t seed = 0;
  int stone = 0;
  double volume = 0.0;           // [m^3]
  double width = 0.0;            // [m] shortest horizontal extent (the closing direction)
  bool site_at_rest = false;     // the site's settle converged
  sim::GraspTrialResult result;  // without the trace (kept small)
};

struct GraspBaselineSummary {
  int trials = 0, successes = 0;
  std::map<std::string, int> failure_reasons;  // code -> trials that failed with it
  double sim_time = 0.0, wall_time = 0.0;      // [s] summed over the trials
  [[nodiscard]] double success_rate() const { return trials > 0 ? static_cast<double>(successes) / trials : 0.0; }
};

struct GraspBaselineResult {
  std::vector<GraspBaselineTrial> trials;  // scenario, seed, stone order
  /// Sites that could not be made for their seed ("exp2 seed 8: ...": a real stone mesh that
  /// cannot be read, a layout that jammed 50 times), and trials that could not run ("exp1 seed 1
  /// stone 3: ..."): reported instead of aborting the run.
  std::vector<std::string> skipped_sites;
  GraspBaselineSummary summary;
};

/// Runs the baseline; `progress(done, total)` is called after each trial (any thread, serialised).
/// Throws ConfigError on an unknown scenario or invalid physics/gripper settings.
GraspBaselineResult run_grasp_baseline(const GraspBaselineConfig& config,
                                       const std::function<void(int, int)>& progress = {});

GraspBaselineSummary summarize(const std::vector<GraspBaselineTrial>& trials);

}  // namespace cairn::eval
