// cairn grasp: grasp poses for one object of a map (paper Sec. 5; grasp/planner.hpp). JSON on
// stdout (docs/grasp.md), pictures and meshes with --out. Exit 0 with grasps, 3 when none
// passes, 2 on bad input.
// cairn grasp-trials: the paper's grasp test in the simulator's physics (eval/grasp_trials.hpp).
#include <spdlog/spdlog.h>

#include <cstdio>
#include <iostream>
#include <optional>

#include "app_config.hpp"
#include "cairn/core/error.hpp"
#include "cairn/core/io/io.hpp"
#include "cairn/eval/grasp_trials.hpp"
#include "cairn/grasp/output.hpp"
#include "cairn/objects/pipeline.hpp"
#include "commands.hpp"

namespace cairn::app {
namespace {

struct GraspArgs {
  CommonOptions common;
  std::string map, db, object_cloud, drone, out;
  std::optional<std::int64_t> object;
};

/// The object to grasp: the given cloud, or the database's (objects/pipeline.hpp, Sec. 5.1).
PointCloud object_model(const GraspArgs& a) {
  if (!a.object_cloud.empty()) return io::read_cloud(a.object_cloud).cloud;
  const ObjectDatabase db(a.db, ObjectDatabase::Mode::read_only);
  ObjectRecord r = object_to_grasp(db, a.object);
  spdlog::info("grasp: object {} ({} points)", r.id, r.num_points);
  return std::move(r.cloud);
}

int run_grasp(const GraspArgs& a) {
  const AppConfig cfg = a.common.load();
  if (a.object_cloud.empty() == a.db.empty()) throw InputError("give exactly one of --db and --object-cloud");
  if (a.object && a.db.empty()) throw InputError("--object needs --db");
  const PointCloud map = io::read_cloud(a.map).cloud;
  const PointCloud object = object_model(a);
  std::optional<PointCloud> drone;
  if (!a.drone.empty()) drone = io::read_cloud(a.drone).cloud;
  const grasp::GraspPlanning p =
      grasp::plan_grasps(map, object, drone ? &*drone : nullptr, cfg.simulation.gripper, cfg.grasp);
  spdlog::info("grasp: {} samples, {} hypotheses, {} collision-free, {} force closure, {} robust: {} grasps in {:.0f} ms",
               p.counts.samples, p.counts.hypotheses, p.counts.collision_free, p.counts.force_closure,
               p.counts.robust, p.grasps.size(), p.timings_ms.at("total"));
  if (!a.out.empty()) grasp::write_planning_outputs(a.out, p, cfg.simulation.gripper);
  std::cout << grasp::to_json(p, cfg.simulation.gripper).dump(2) << std::endl;
  return p.grasps.empty() ? kExitNoResult : kExitOk;
}

struct TrialsArgs {
  CommonOptions common;
  eval::GraspTrialsConfig trials;
  bool no_baseline = false;
  int study = 0;
  std::string out;
};

void print_rate(const char* name, const eval::RateSummary& r) {
  std::printf("%-18s %3d / %3d  %5.1f %%  (95 %% Wilson %.1f-%.1f %%)\n", name, r.successes, r.trials,
              r.trials ? 100.0 * r.successes / r.trials : 0.0, 100.0 * r.wilson_low, 100.0 * r.wilson_high);
  for (const auto& [reason, n] : r.failure_reasons) std::printf("    %-22s %d\n", reason.c_str(), n);
}

int run_trials(const TrialsArgs& a) {
  const AppConfig cfg = a.common.load();
  eval::GraspTrialsConfig c = a.trials;
  c.physics = cfg.simulation.physics;
  c.gripper = cfg.simulation.gripper;
  c.mapping = cfg.mapping;
  c.segmentation = cfg.segmentation;
  c.registration = cfg.registration;
  c.grasp = cfg.grasp;
  c.baseline = !a.no_baseline;
  c.study = a.study;
  const eval::GraspTrialsResult r = eval::run_grasp_trials(c, [](const std::string& what, int done, int total) {
    spdlog::info("grasp-trials: {}/{} sites ({})", done, total, what);
  });
  for (const eval::PlannedGraspTrial& t : r.trials) {
    std::string reasons = t.planned ? "" : "no_grasp";
    for (const std::string& s : t.result.failure_reasons) reasons += (reasons.empty() ? "" : ",") + s;
    std::printf("%-5s %3llu %2d %-5s %-24.24s %6.0f ms %-8s %s\n", t.scenario.c_str(), static_cast<unsigned long long>(t.seed),
                t.stone, t.flat ? "flat" : "round", t.shape.c_str(), t.planning_ms, t.success() ? "success" : "failed",
                reasons.c_str());
  }
  print_rate("planned", r.planned);
  print_rate("planned, flat", r.planned_flat);
  print_rate("planned, roundish", r.planned_roundish);
  if (c.baseline) print_rate("centred baseline", r.baseline);
  for (const std::string& s : r.skipped) spdlog::warn("grasp-trials: skipped {}", s);
  if (!a.out.empty()) write_out_file(a.out, eval::to_json(r).dump(1));
  return kExitOk;
}

}  // namespace

void add_grasp_command(CLI::App& app, std::function<int()>& run) {
  auto args = std::make_shared<GraspArgs>();
  auto* cmd = app.add_subcommand("grasp", "Plan grasps for one object of a map (Sec. 5): ranked gripper poses as JSON");
  cmd->add_option("--map", args->map, "the LiDAR map (any cloud format)")->required();
  cmd->add_option("--db", args->db, "object database: the object's model (the largest unless --object)");
  cmd->add_option("--object", args->object, "object id in --db");
  cmd->add_option("--object-cloud", args->object_cloud, "the object's model as a cloud (instead of --db)");
  cmd->add_option("--drone", args->drone, "the registered drone cloud (map frame)");
  cmd->add_option("--out", args->out, "write the planning cloud, the best grasps' gripper meshes and costs.png");
  args->common.add_to(*cmd);
  cmd->callback([&run, args] { run = [args] { return run_grasp(*args); }; });
}

void add_grasp_trials_command(CLI::App& app, std::function<int()>& run) {
  auto args = std::make_shared<TrialsArgs>();
  auto* cmd = app.add_subcommand("grasp-trials",
                                 "Plan from the sensed map and execute the best grasp of every stone in MuJoCo (Sec. "
                                 "6.3), with the centred baseline on the same sites");
  cmd->add_option("--scenarios", args->trials.scenarios, "scenarios (exp1, exp2, pile)")->capture_default_str();
  cmd->add_option("--seeds", args->trials.seeds, "site seeds")->capture_default_str();
  cmd->add_option("--source", args->trials.source, "merged with the LiDAR map: model | drone")->capture_default_str();
  cmd->add_option("--scan-time", args->trials.scan_time, "scanning before planning [s]")->capture_default_str();
  cmd->add_flag("--no-baseline", args->no_baseline, "skip the centred baseline");
  cmd->add_option("--study", args->study,
                  "diagnostic: also execute this many random force-closure grasps per stone (features vs outcome)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--out", args->out, "write every trial and the summary as JSON");
  args->common.add_to(*cmd);
  cmd->callback([&run, args] { run = [args] { return run_trials(*args); }; });
}

}  // namespace cairn::app
