// cairn grasp-trial: execute one grasp on a simulated site in MuJoCo and report the outcome
// (docs/simulator-physics.md). JSON result on stdout, progress on stderr.
// Exit codes: 0 grasp succeeded, 3 grasp failed, 2 bad input.
#include <spdlog/spdlog.h>

#include <fstream>
#include <iostream>
#include <numbers>
#include <nlohmann/json.hpp>

#include "app_config.hpp"
#include "cairn/core/config.hpp"
#include "cairn/core/error.hpp"
#include "cairn/sim/physics/grasp_json.hpp"
#include "cairn/sim/physics/physics.hpp"
#include "cairn/sim/simulation.hpp"
#include "commands.hpp"

namespace cairn::app {
namespace {

/// The settings of this command (`--config FILE`, `--set physics.x=v`, `--set gripper.x=v`).
struct GraspTrialConfig {
  sim::PhysicsConfig physics;
  GripperConfig gripper;

  template <class V>
  void visit(V& v) {
    v("physics", physics, "MuJoCo grasp trials");
    v("gripper", gripper, "two-jaw gripper geometry and closing force");
  }
};

struct GraspTrialArgs {
  std::string scenario = "default";
  std::uint64_t seed = 1;
  int stone = -1;
  std::string grasp_file;
  std::string out;
  std::vector<double> place_offset = {2.0, 0.0};
  double place_yaw = 0.0;
  double place_drop = sim::CentredGraspOptions{}.place_drop;
  bool no_settle = false;
  std::string config_file;
  std::vector<std::string> overrides;
};

nlohmann::json read_json(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError("--grasp: cannot open '" + path + "'");
  try {
    return nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception& e) {
    throw InputError("--grasp: '" + path + "' is not valid JSON: " + e.what());
  }
}

int run_grasp_trial(const GraspTrialArgs& a) {
  GraspTrialConfig cfg;
  if (!a.config_file.empty()) config::load_yaml_file(cfg, a.config_file);
  for (const auto& o : a.overrides) config::apply_override(cfg, o);
  // "default": the procedural site of SiteConfig{}; otherwise the site of a simulator scenario
  // (the same stones `cairn simulate --scenario NAME --seed N` writes). Either way settled in the
  // physics first (the world at rest the sensors see); --no-settle keeps the generator's placement.
  sim::SimulationConfig sim_cfg;
  if (a.scenario != "default") {
    sim_cfg = sim::scenario_config(a.scenario, sim::default_real_mesh_dir());
  } else {
    sim_cfg.site = sim::SiteConfig{};
    sim_cfg.site.stones.settle = !a.no_settle;  // tipped onto its support before the physics settle
  }
  sim_cfg.physics = cfg.physics;
  sim_cfg.settle_in_physics = !a.no_settle;
  // Refused before the site is settled (seconds): the generator places exactly stones.count.
  const int n = sim_cfg.site.stones.count;
  if (a.stone < 0 || a.stone >= n) {
    throw InputError("--stone: " + std::to_string(a.stone) + " is not a stone of this site (0.." + std::to_string(n - 1) + ")");
  }
  sim::SiteSettleResult settled;
  if (!a.no_settle) spdlog::info("grasp-trial: settling the site of seed {} in the physics", a.seed);
  sim::Site site = sim::make_site(sim_cfg, a.seed, &settled);
  nlohmann::json settle_json = nullptr;
  if (!a.no_settle) {
    settle_json = sim::to_json(settled);
    spdlog::info("grasp-trial: site at rest={} ({} islands, a restart moves a stone {:.1f} mm, {:.2f} deg; {:.1f} s "
                 "simulated, {:.2f} s wall)",
                 settled.settled, settled.islands, 1e3 * settled.restart_shift, settled.restart_turn * 180.0 / std::numbers::pi,
                 settled.sim_time, settled.wall_time);
  }
  GraspPlan plan;
  if (a.grasp_file.empty()) {
    sim::CentredGraspOptions o;
    if (a.place_offset.size() != 2) throw InputError("--place-offset needs two values: X Y");
    o.place_offset = Eigen::Vector2d(a.place_offset[0], a.place_offset[1]);
    o.place_yaw = a.place_yaw;
    o.place_drop = a.place_drop;
    plan = sim::centred_antipodal_grasp(site.stones[static_cast<std::size_t>(a.stone)], cfg.gripper, &site.terrain, o);
    plan.target_stone = a.stone;
  } else {
    plan = grasp_plan_from_json(read_json(a.grasp_file), a.grasp_file);
    if (plan.target_stone < 0) plan.target_stone = a.stone;
  }
  spdlog::info("grasp-trial: stone {} — opening {:.2f} m, approach {:.2f} m, lift {:.2f} m", a.stone, plan.opening,
               plan.approach_distance, plan.lift_height);
  sim::GraspTrialResult r = sim::run_grasp_trial(site, plan, cfg.gripper, cfg.physics);
  nlohmann::json j = sim::to_json(r);
  // The trial's stone poses are relative to the site as generated (settled in the physics): the
  // world after the trial is make_site(seed) with these applied.
  j["scenario"] = a.scenario;
  j["seed"] = a.seed;
  j["stone"] = a.stone;
  j["plan"] = to_json(plan);
  j["site_settle"] = settle_json;
  // Relative to the raw generated placement (generate_site), settling composed in.
  nlohmann::json from_generated = nlohmann::json::array();
  for (std::size_t k = 0; k < r.stone_poses.size(); ++k) {
    from_generated.push_back(pose_to_json(a.no_settle ? r.stone_poses[k] : r.stone_poses[k] * settled.stone_poses[k]));
  }
  j["stone_poses_from_generated"] = from_generated;
  j["config"] = config::to_json(cfg);
  const std::string text = j.dump(2);
  std::cout << text << std::endl;
  if (!a.out.empty()) write_out_file(a.out, text);
  if (r.success) {
    spdlog::info("grasp-trial: success — {} ({:.1f} s simulated in {:.1f} s)", r.message, r.sim_time, r.wall_time);
    return kExitOk;
  }
  spdlog::warn("grasp-trial: failed — {}", r.message);
  return kExitNoResult;
}

}  // namespace

void add_grasp_trial_command(CLI::App& app, std::function<int()>& run) {
  auto args = std::make_shared<GraspTrialArgs>();
  auto* cmd = app.add_subcommand("grasp-trial",
                                 "Execute a grasp (approach, close, lift, swing, place, release) on a simulated site "
                                 "in MuJoCo; print the JSON result (exit 0 success, 3 failed)");
  cmd->add_option("--scenario", args->scenario, "site: default, or a simulator scenario (exp1, exp2, pile)")->capture_default_str();
  cmd->add_option("--seed", args->seed, "site seed")->capture_default_str();
  cmd->add_option("--stone", args->stone, "index of the stone to grasp")->required();
  cmd->add_option("--grasp", args->grasp_file,
                  "grasp plan JSON (docs/simulator-physics.md); default: centred antipodal grasp of the stone");
  cmd->add_option("--out", args->out, "also write the JSON result to this file");
  cmd->add_option("--place-offset", args->place_offset, "default grasp: place shift X Y [m]")->expected(2)->capture_default_str();
  cmd->add_option("--place-yaw", args->place_yaw, "default grasp: place rotation about the vertical [rad]")->capture_default_str();
  cmd->add_option("--place-drop", args->place_drop,
                  "default grasp: place pose this high above the ground-contact pose [m]; negative: pressed "
                  "below it, lowering stops when the arm's load says the ground carries the stone")
      ->capture_default_str();
  cmd->add_flag("--no-settle", args->no_settle, "start from the procedural placement (not settled in the physics)");
  cmd->add_option("--config", args->config_file, "YAML with physics.* and gripper.* settings");
  cmd->add_option("--set", args->overrides, "override a setting: physics.timestep=0.004 (repeatable)");
  cmd->callback([&run, args] { run = [args] { return run_grasp_trial(*args); }; });
}

}  // namespace cairn::app
