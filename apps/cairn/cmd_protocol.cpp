// cairn protocol: the paper's evaluation of the registration (Sec. 6.2) on the simulator
// (cairn/eval/protocol.hpp): parses the options, runs the protocol, writes protocol.json and the
// pictures, prints the summary.
#include <spdlog/spdlog.h>

#include <fstream>
#include <iostream>

#include "app_config.hpp"
#include "cairn/eval/protocol.hpp"
#include "commands.hpp"

namespace cairn::app {
namespace {

struct ProtocolArgs {
  std::string out = "cairn_protocol";
  eval::ProtocolConfig protocol;
  CommonOptions common;
};

int run_protocol(const ProtocolArgs& a) {
  AppConfig base;
  base.simulation = sim::scenario_config(a.protocol.scenario, sim::default_real_mesh_dir());
  const AppConfig cfg = a.common.load(base);
  const std::filesystem::path out(a.out);
  const eval::ProtocolResult r = eval::run_protocol(a.protocol, cfg, out);
  const std::filesystem::path grid = out / "trials.png", acceptance = out / "acceptance.png";
  eval::draw_acceptance(acceptance, r, cfg.registration.acceptance);
  const nlohmann::json summary = eval::protocol_summary(r, grid, acceptance);
  nlohmann::json trials = nlohmann::json::array();
  for (const eval::ProtocolTrial& t : r.trials) trials.push_back(t.to_json());
  std::ofstream(out / "protocol.json") << nlohmann::json{{"summary", summary}, {"trials", trials}}.dump(2) << "\n";
  eval::draw_protocol_grid(grid, r);
  std::cout << summary.dump(2) << std::endl;
  spdlog::info("protocol: {} (rows: seeds, columns: every {} s; green success, orange accepted with a stone split "
               "or missing, red refused, purple wrong answer accepted)",
               grid.string(), a.protocol.every);
  return kExitOk;
}

}  // namespace

void add_protocol_command(CLI::App& app, std::function<int()>& run) {
  auto args = std::make_shared<ProtocolArgs>();
  eval::ProtocolConfig& p = args->protocol;
  auto* cmd = app.add_subcommand("protocol",
                                 "The paper's registration protocol on the simulator: register the drone cloud into the "
                                 "growing LiDAR map every few seconds, over several seeds; success rate, errors, time "
                                 "to first success");
  cmd->add_option("--out", args->out, "output directory (protocol.json, trials.png)")->capture_default_str();
  cmd->add_option("--scenario", p.scenario, "scenario")->capture_default_str();
  cmd->add_option("--first-seed", p.first_seed, "first scenario seed")->capture_default_str();
  cmd->add_option("--seeds", p.seeds, "number of seeds (sites)")->capture_default_str()->check(CLI::Range(1, 1000));
  cmd->add_option("--duration", p.duration, "seconds of scanning per seed")
      ->capture_default_str()
      ->check(CLI::Range(1.0, 600.0));
  cmd->add_option("--every", p.every, "registration every this many seconds of scanning")->capture_default_str();
  cmd->add_flag("--keep-runs", p.keep_runs, "keep the simulated run directories");
  cmd->add_flag("--study-acceptance", p.study,
                "acceptance-test study: refine every candidate, and also register a mirrored (wrong) site each time");
  cmd->add_flag("--windowed-map", p.windowed_map,
                "register into the map as the windowed updates left it, without a full reoptimisation of the "
                "trajectory and a map rebuild before each registration");
  args->common.add_to(*cmd);
  cmd->callback([&run, args] { run = [args] { return run_protocol(*args); }; });
}

}  // namespace cairn::app
