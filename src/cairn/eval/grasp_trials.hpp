#pragma once
// The paper's grasp test (Sec. 6.3) in the simulator's physics (issue #17): on settled sites, the
// machine scans (both LiDARs through the Mapper, 32 s: two swings), segments its map, and plans a
// grasp on each stone from what it senses — the LiDAR map plus the registered drone cloud
// (`source = drone`), or the LiDAR map plus the object's model without a drone (`source = model`)
// — never from the truth meshes. The best-ranked grasp, commanded in the map frame, is executed
// where the machine's state estimate puts it in the true physics world: approach, close, lift
// 1 m, a quarter turn about the vertical through the stone, lower, release, settle. The
// centred-grasp baseline (eval/grasp_baseline.hpp) runs on the same settled sites in the same run.
#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "cairn/grasp/config.hpp"
#include "cairn/grasp/planner.hpp"
#include "cairn/mapping/config.hpp"
#include "cairn/registration/global_registration.hpp"
#include "cairn/segmentation/segmenter.hpp"
#include "cairn/sim/physics/physics.hpp"

namespace cairn::eval {

struct GraspTrialsConfig {
  std::vector<std::string> scenarios = {"exp1", "exp2"};
  std::vector<std::uint64_t> seeds = {1, 2, 3, 4};
  std::string source = "model";  // "model" | "drone": what is merged with the LiDAR map (Sec. 5.2)
  double scan_time = 32.0;       // [s] scanning before planning (two swings)
  double place_yaw = 1.5707963267948966;  // [rad] the move: a quarter turn about the vertical
  double place_drop = 0.02;      // [m] the place pose is the grasp pose turned and raised by this
  double score_near = 0.05;      // [m] a segment point this close to a true surface lies on it
  bool baseline = true;          // also run the centred grasp on the same sites
  /// Diagnostic study (0: off): per stone, this many grasps drawn at random from all its
  /// force-closure grasps are executed too, to relate the planner's features to the outcome.
  int study = 0;
  sim::PhysicsConfig physics;
  GripperConfig gripper;
  MappingConfig mapping;
  SegmentationConfig segmentation;
  GlobalRegistrationConfig registration;
  grasp::GraspConfig grasp;
};

struct PlannedGraspTrial {
  std::string scenario;
  std::uint64_t seed = 0;
  int stone = 0;
  std::string shape;          // "procedural" or the real mesh's file name
  bool flat = false;          // slab-like stone (the generator's)
  double volume = 0.0, width = 0.0;  // [m^3], [m] shortest horizontal extent
  Eigen::Vector3d true_centroid = Eigen::Vector3d::Zero();  // world, at rest (scoring only)
  Eigen::AlignedBox3d true_bounds;
  bool site_at_rest = false;
  bool segmented = false;     // one segment holds the stone (else not planned)
  double purity = 0.0;        // share of the segment's points on the stone
  bool planned = false;       // a grasp passed (else the trial fails with "no_grasp")
  double planning_ms = 0.0;
  grasp::GraspCounts counts;
  Eigen::Vector3d mass_centroid = Eigen::Vector3d::Zero();  // the planner's estimate (world)
  Eigen::Vector3d model_centroid = Eigen::Vector3d::Zero();  // the model's centroid (map): the place turns about it
  grasp::Grasp best;
  sim::GraspTrialResult result;    // the planned grasp (trace dropped)
  sim::GraspTrialResult baseline;  // the centred grasp on the same stone
  GraspPlan plan, baseline_plan;   // as executed (world frame)
  std::vector<grasp::Grasp> study_grasps;            // config.study: the drawn grasps ...
  std::vector<sim::GraspTrialResult> study_results;  // ... and their outcomes (traces dropped)
  [[nodiscard]] bool success() const { return planned && result.success; }
};

struct RateSummary {
  int trials = 0, successes = 0;
  double wilson_low = 0.0, wilson_high = 0.0;  // 95 % Wilson score interval
  std::map<std::string, int> failure_reasons;
};

struct GraspTrialsResult {
  std::vector<PlannedGraspTrial> trials;  // scenario, seed, stone order
  std::vector<std::string> skipped;       // sites that could not be made, stones not segmented
  std::string drone_registration;         // per site when source = drone ("exp1 seed 1: ok", ...)
  RateSummary planned, planned_flat, planned_roundish, baseline;
  std::vector<double> planning_ms;        // per planned stone
};

/// The 95 % Wilson score interval of k successes in n trials.
[[nodiscard]] std::pair<double, double> wilson_interval(int k, int n, double z = 1.959963984540054);

/// Progress: (what, done, total).
using GraspTrialsProgress = std::function<void(const std::string&, int, int)>;

/// Runs the trials. Throws ConfigError on bad settings or an unknown scenario/source.
GraspTrialsResult run_grasp_trials(const GraspTrialsConfig& config, const GraspTrialsProgress& progress = {});

[[nodiscard]] nlohmann::json to_json(const GraspTrialsResult& r);

}  // namespace cairn::eval
