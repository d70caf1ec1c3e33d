// cairn simulate: one scenario of the simulator written as a run directory (docs/run-directory.md).
#include <spdlog/spdlog.h>

#include <cmath>
#include <iostream>
#include <nlohmann/json.hpp>

#include "app_config.hpp"
#include "bag_support.hpp"
#include "cairn/core/io/run_dir.hpp"
#include "cairn/core/error.hpp"
#include "cairn/sim/simulation.hpp"
#include "commands.hpp"

namespace cairn::app {
namespace {

struct SimulateArgs {
  std::string scenario = "exp1";
  std::uint64_t seed = 1;
  double duration = 20.0;
  std::string out;
  std::string bag;
  std::string real_meshes;
  bool overwrite = false;
  bool no_drone = false;
  std::vector<std::string> moves;
  CommonOptions common;
};

/// "T:K:DX:DY[:TURN]" -> StoneMove (time [s], stone, shift [m], turn [deg]).
sim::StoneMove parse_move(const std::string& text) {
  std::vector<double> v;
  std::size_t from = 0;
  while (from <= text.size()) {
    const std::size_t to = std::min(text.find(':', from), text.size());
    const std::string part = text.substr(from, to - from);
    std::size_t used = 0;
    double x = NAN;
    try {
      x = std::stod(part, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (part.empty() || used != part.size() || !std::isfinite(x))
      throw InputError("--move '" + text + "': '" + part + "' is not a number (expected T:K:DX:DY[:TURN_DEG])");
    v.push_back(x);
    from = to + 1;
  }
  if (v.size() < 4 || v.size() > 5) throw InputError("--move '" + text + "': expected T:K:DX:DY[:TURN_DEG]");
  if (v[1] < 0 || v[1] > 1e6 || v[1] != std::floor(v[1]))
    throw InputError("--move '" + text + "': the stone must be an index >= 0");
  return {.time = v[0], .stone = static_cast<std::size_t>(v[1]), .shift = {v[2], v[3]},
          .turn_deg = v.size() == 5 ? v[4] : 0.0};
}

int run_simulate(const SimulateArgs& a) {
  const std::filesystem::path mesh_dir = a.real_meshes.empty() ? sim::default_real_mesh_dir() : std::filesystem::path(a.real_meshes);
  if (!a.real_meshes.empty() && !std::filesystem::is_directory(mesh_dir)) {
    throw InputError("--real-meshes: '" + a.real_meshes + "' is not a directory");
  }
  if (!a.bag.empty()) {  // refused before simulating, not after
    require_bag_support();
    if (std::filesystem::exists(a.bag) && !a.overwrite)
      throw InputError("--bag: '" + a.bag + "' exists (--overwrite replaces it)");
  }
  AppConfig base;
  base.simulation = sim::scenario_config(a.scenario, mesh_dir);
  AppConfig cfg = a.common.load(base);
  if (a.no_drone) cfg.simulation.with_drone = false;
  std::vector<sim::StoneMove> moves;
  for (const std::string& m : a.moves) moves.push_back(parse_move(m));
  spdlog::info("simulate: scenario {} seed {} for {} s -> {}", a.scenario, a.seed, a.duration, a.out);
  std::size_t last_percent = 101;
  const auto progress = [&](const std::string& stage, std::size_t done, std::size_t total) {
    const std::size_t percent = total == 0 ? 100 : 100 * done / total;
    if (stage == "lidar" && percent / 10 != last_percent / 10) {
      spdlog::info("simulate: LiDAR sweeps {}/{} ({}%)", done, total, percent);
      last_percent = percent;
    } else if (stage == "drone" && done == 0) {
      spdlog::info("simulate: drone survey");
    }
  };
  const sim::SimulationSummary s = sim::simulate_run(a.scenario, cfg.simulation, a.seed, a.duration, a.out, a.overwrite,
                                                     progress, moves);
  nlohmann::json out{{"scenario", s.scenario}, {"seed", s.seed}, {"duration", s.duration}, {"out", a.out},
                     {"sweeps", s.sweeps}, {"points", s.points}, {"rays", s.rays},
                     {"drone_points", s.drone_points}, {"drone_images", s.drone_images},
                     {"timings_s", {{"site", s.seconds_site}, {"lidar", s.seconds_lidar}, {"write", s.seconds_write},
                                    {"drone", s.seconds_drone}, {"total", s.seconds_total}}}};
  if (!a.bag.empty()) {
    spdlog::info("simulate: writing the rosbag {}", a.bag);
    out["bag"] = {{"file", a.bag}, {"messages", write_bag(io::open_run_directory(a.out), a.bag, cfg.bag)}};
  }
  std::cout << out.dump(2) << std::endl;
  spdlog::info("simulate: {} sweeps, {} points in {:.1f} s (LiDAR ray casting {:.1f} s, drone {:.1f} s)", s.sweeps,
               s.points, s.seconds_total, s.seconds_lidar, s.seconds_drone);
  return kExitOk;
}

}  // namespace

void add_simulate_command(CLI::App& app, std::function<int()>& run) {
  auto args = std::make_shared<SimulateArgs>();
  auto* cmd = app.add_subcommand("simulate",
                                 "Simulate a stone site, the swinging excavator's two LiDARs, state estimation and a "
                                 "drone survey; write a run directory");
  std::string names;
  for (const auto& n : sim::scenario_names()) names.append(names.empty() ? "" : ", ").append(n);
  cmd->add_option("--scenario", args->scenario, "scenario: " + names)->capture_default_str();
  cmd->add_option("--seed", args->seed, "seed (same seed, same files)")->capture_default_str();
  cmd->add_option("--duration", args->duration, "simulated time [s]")->capture_default_str()->check(CLI::Range(0.2, 3600.0));
  cmd->add_option("--out", args->out, "run directory to write")->required();
  cmd->add_option("--bag", args->bag, "also write the run as a rosbag, as a real machine records it (docs/ros.md)");
  cmd->add_option("--real-meshes", args->real_meshes, "directory of real scanned stone meshes (PLY)");
  cmd->add_flag("--overwrite", args->overwrite, "replace an existing run directory");
  cmd->add_flag("--no-drone", args->no_drone, "skip the drone survey");
  cmd->add_option("--move", args->moves,
                  "T:K:DX:DY[:TURN_DEG] — at T s the machine picks stone K up, holds it for held_time s and puts "
                  "it down shifted by (DX, DY) m and turned; repeatable (truth/segments.json)");
  args->common.add_to(*cmd);
  cmd->callback([&run, args] { run = [args] { return run_simulate(*args); }; });
}

}  // namespace cairn::app
