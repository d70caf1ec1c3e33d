// cairn grasp-baseline: the centred top-down grasp of every stone of simulated sites, executed in
// MuJoCo with the angular gripper (eval/grasp_baseline.hpp): success rate and failure reasons,
// the figure grasp planning must beat. Table on stdout, JSON with --out, progress on stderr.
#include <spdlog/spdlog.h>

#include <cstdio>
#include <nlohmann/json.hpp>

#include "app_config.hpp"
#include "cairn/core/error.hpp"
#include "cairn/eval/grasp_baseline.hpp"
#include "cairn/sim/physics/grasp_json.hpp"
#include "commands.hpp"

namespace cairn::app {
namespace {

struct GraspBaselineArgs {
  CommonOptions common;
  std::vector<std::string> scenarios = eval::GraspBaselineConfig{}.scenarios;
  std::vector<std::uint64_t> seeds = eval::GraspBaselineConfig{}.seeds;
  std::string out;
};

nlohmann::json to_json(const eval::GraspBaselineResult& r) {
  nlohmann::json trials = nlohmann::json::array();
  for (const eval::GraspBaselineTrial& t : r.trials) {
    nlohmann::json j = sim::to_json(t.result);
    j["scenario"] = t.scenario;
    j["seed"] = t.seed;
    j["stone"] = t.stone;
    j["volume"] = t.volume;
    j["width"] = t.width;
    j["site_at_rest"] = t.site_at_rest;
    trials.push_back(std::move(j));
  }
  const eval::GraspBaselineSummary& s = r.summary;
  return {{"trials", trials},
          {"skipped_sites", r.skipped_sites},
          {"summary", {{"trials", s.trials}, {"successes", s.successes}, {"success_rate", s.success_rate()},
                       {"failure_reasons", s.failure_reasons}, {"sim_time", s.sim_time}, {"wall_time", s.wall_time}}}};
}

int run_grasp_baseline(const GraspBaselineArgs& a) {
  const AppConfig cfg = a.common.load();
  eval::GraspBaselineConfig c;
  c.scenarios = a.scenarios;
  c.seeds = a.seeds;
  c.physics = cfg.simulation.physics;
  c.gripper = cfg.simulation.gripper;
  spdlog::info("grasp-baseline: {} scenarios x {} seeds, every stone (max opening {:.2f} m)", c.scenarios.size(),
               c.seeds.size(), max_opening(c.gripper));
  const eval::GraspBaselineResult r = eval::run_grasp_baseline(c, [](int done, int total) {
    if (done % 5 == 0 || done == total) spdlog::info("grasp-baseline: {}/{} trials", done, total);
  });
  std::printf("%-9s %5s %5s %7s %6s %-8s %s\n", "scenario", "seed", "stone", "vol_m3", "width", "result", "reasons");
  for (const eval::GraspBaselineTrial& t : r.trials) {
    std::string reasons;
    for (const std::string& s : t.result.failure_reasons) reasons += (reasons.empty() ? "" : ",") + s;
    std::printf("%-9s %5llu %5d %7.2f %6.2f %-8s %s\n", t.scenario.c_str(), static_cast<unsigned long long>(t.seed),
                t.stone, t.volume, t.width, t.result.success ? "success" : "failed", reasons.c_str());
  }
  const eval::GraspBaselineSummary& s = r.summary;
  std::printf("success %d / %d (%.1f %%); simulated %.0f s in %.0f s of trial wall time (%.1fx real time)\n",
              s.successes, s.trials, 100.0 * s.success_rate(), s.sim_time, s.wall_time,
              s.wall_time > 0.0 ? s.sim_time / s.wall_time : 0.0);
  for (const auto& [reason, count] : s.failure_reasons) std::printf("  %-20s %d\n", reason.c_str(), count);
  for (const std::string& site : r.skipped_sites) spdlog::warn("grasp-baseline: skipped {}", site);
  if (!a.out.empty()) write_out_file(a.out, to_json(r).dump(1));
  return kExitOk;
}

}  // namespace

void add_grasp_baseline_command(CLI::App& app, std::function<int()>& run) {
  auto args = std::make_shared<GraspBaselineArgs>();
  auto* cmd = app.add_subcommand("grasp-baseline",
                                 "Centred top-down grasp of every stone of simulated sites in MuJoCo: the baseline "
                                 "success rate and failure reasons");
  cmd->add_option("--scenarios", args->scenarios, "scenarios (exp1, exp2, pile)")->capture_default_str();
  cmd->add_option("--seeds", args->seeds, "site seeds")->capture_default_str();
  cmd->add_option("--out", args->out, "write every trial and the summary as JSON");
  args->common.add_to(*cmd);
  cmd->callback([&run, args] { run = [args] { return run_grasp_baseline(*args); }; });
}

}  // namespace cairn::app
