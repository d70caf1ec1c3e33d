// cairn demo: the main job, the paper's experiments end to end on the built-in simulated site
// (eval/experiment.hpp): drone survey and scale, online LiDAR map, registration every 5 s until
// accepted, segmentation and the object database, then every stone planned, grasped in the
// physics, carried to its place in a row, released, rescanned and re-aligned (exp1 once, exp2
// four rounds). Prints the summary JSON; writes it, the object database and the HTML report
// (report/report.hpp) with its figures to --out.
#include <spdlog/spdlog.h>

#include <fstream>
#include <iostream>

#include "app_config.hpp"
#include "cairn/core/error.hpp"
#include "cairn/core/image.hpp"
#include "cairn/eval/experiment.hpp"
#include "cairn/report/report.hpp"
#include "cairn/segmentation/output.hpp"
#include "commands.hpp"

namespace cairn::app {
namespace {

struct DemoArgs {
  std::string out = "cairn_demo";
  std::string scenario = "exp1";
  std::uint64_t seed = 1;
  bool overwrite = false;
  CommonOptions common;
};

/// Prepares the output directory: refuses to replace an earlier run's database unless told to.
void prepare_out(const std::filesystem::path& out, bool overwrite) {
  if (std::filesystem::exists(out) && !std::filesystem::is_directory(out))
    throw InputError(out.string() + ": exists and is not a directory");
  std::filesystem::create_directories(out);
  const std::filesystem::path db = out / "objects.db";
  if (std::filesystem::exists(db)) {
    if (!overwrite) throw InputError(db.string() + ": exists (an earlier run's database; use --overwrite to replace it)");
    for (const char* side : {"", "-wal", "-shm"}) std::filesystem::remove(db.string() + side);
  }
  std::filesystem::remove_all(out / "trials");  // an earlier run's physics trials
}

int run_demo(const DemoArgs& a) {
  AppConfig base;
  base.simulation = sim::scenario_config(a.scenario, sim::default_real_mesh_dir());
  const AppConfig cfg = a.common.load(base);
  eval::ExperimentConfig c = cfg.experiment;
  c.experiment = a.scenario;
  c.tracking.scenario = a.scenario;
  c.tracking.seed = a.seed;
  c.tracking.simulation = cfg.simulation;
  c.tracking.mapping = cfg.mapping;
  c.tracking.segmentation = cfg.segmentation;
  c.tracking.objects = cfg.objects;
  c.registration = cfg.registration;
  c.grasp = cfg.grasp;
  const std::filesystem::path out(a.out);
  prepare_out(out, a.overwrite);
  c.tracking.database = out / "objects.db";
  c.trials_dir = out / "trials";
  spdlog::info("demo: experiment {} on seed {} -> {}", a.scenario, a.seed, out.string());
  const eval::ExperimentResult r = eval::run_experiment(c, [](const std::string& what, int done, int total) {
    spdlog::info("demo: {} {}/{}", what, done, total);
  });
  const nlohmann::json j = eval::to_json(r);
  std::ofstream(out / "summary.json") << j.dump(2) << "\n";
  std::cout << j.dump(2) << std::endl;
  const report::ReportFiles files = report::write_report(out, r, {.target_tolerance = c.detection.target_tolerance});
  spdlog::info("demo: report {} ({} figures beside it)", files.html.string(), files.figures.size());
  spdlog::info("demo: {} of {} moves placed within {} m of their targets; first-attempt success {}/{}, within {} "
               "attempts {}/{}; {} failed attempts, {} detected, {} false alarms; summary {}",
               r.placed, r.moves, c.detection.target_tolerance, r.first_attempt_success, r.moves, c.max_attempts,
               r.within_attempts, r.moves, r.failures, r.failures_detected, r.false_alarms,
               (out / "summary.json").string());
  return kExitOk;
}

}  // namespace

void add_demo_command(CLI::App& app, std::function<int()>& run) {
  auto args = std::make_shared<DemoArgs>();
  auto* cmd = app.add_subcommand(
      "demo", "The main job: the paper's experiments end to end on the simulated machine (Sec. 6): map, register "
              "the drone cloud, segment, fill the object database, then plan, grasp, carry, place, rescan and "
              "re-align every stone (exp1: once; exp2: four rounds)");
  cmd->add_option("--out", args->out, "output directory (summary.json, objects.db, report.html, fig_*, trials/: every physics trial)")->capture_default_str();
  cmd->add_option("--scenario", args->scenario, "experiment: exp1, exp2 or pile (clearing a pile of touching stones, issue #21)")->capture_default_str();
  cmd->add_option("--seed", args->seed, "site seed (same seed, same site and sensor data)")->capture_default_str();
  cmd->add_flag("--overwrite", args->overwrite, "replace the object database of an earlier run in --out");
  args->common.add_to(*cmd);
  cmd->callback([&run, args] { run = [args] { return run_demo(*args); }; });
}

}  // namespace cairn::app
