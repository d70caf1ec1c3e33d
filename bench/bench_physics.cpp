// Physics speed (issue #15, item 5): settling a whole scenario site (the world at rest, target
// <= 1 s wall for 7 stones) and full grasp trials (approach -> close -> lift -> move -> place ->
// release -> settle, target >= 5x real time on 2 cores), with the counters that explain the time:
// islands, free stones, simulated seconds per wall second. Also the collision hulls' volumes.
#include <benchmark/benchmark.h>

#include <algorithm>

#include "cairn/sim/physics/physics.hpp"
#include "cairn/sim/simulation.hpp"

namespace {
using namespace cairn::sim;

const std::vector<std::string> kScenarios = {"exp1", "exp2", "pile"};

/// The scenario's site as make_site generates it for settling (resting on the ground), unsettled.
SimulationConfig unsettled(const std::string& scenario) {
  SimulationConfig cfg = scenario_config(scenario, default_real_mesh_dir());
  cfg.settle_in_physics = false;
  cfg.site.stones.embed_depth = 0.0;
  return cfg;
}

/// settle_site on scenario range(0), seed range(1).
void BM_SettleSite(benchmark::State& state) {
  const std::string scenario = kScenarios[static_cast<std::size_t>(state.range(0))];
  const SimulationConfig cfg = unsettled(scenario);
  const Site generated = make_site(cfg, static_cast<std::uint64_t>(state.range(1)));
  SiteSettleResult r;
  for (auto _ : state) {
    Site site = generated;
    r = settle_site(site, cfg.physics);
  }
  state.SetLabel(scenario);
  state.counters["stones"] = static_cast<double>(generated.stones.size());
  state.counters["islands"] = r.islands;
  state.counters["rounds"] = r.rounds;
  state.counters["settled"] = r.settled ? 1 : 0;
  state.counters["sim_s"] = r.sim_time;
  state.counters["max_move_m"] = r.max_displacement;
}
BENCHMARK(BM_SettleSite)
    ->ArgsProduct({{0, 1, 2}, {1, 2, 3}})
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1)
    ->UseRealTime();

/// Centred top-down grasp of stone range(0) of the settled exp1 site, seed 1.
void BM_GraspTrial(benchmark::State& state) {
  SimulationConfig cfg = scenario_config("exp1", default_real_mesh_dir());
  cfg.settle_in_physics = true;
  static const Site site = make_site(cfg, 1);
  const int k = static_cast<int>(state.range(0));
  cairn::GraspPlan plan = centred_antipodal_grasp(site.stones[static_cast<std::size_t>(k)], cfg.gripper, &site.terrain);
  plan.target_stone = k;
  GraspTrialResult r;
  for (auto _ : state) r = run_grasp_trial(site, plan, cfg.gripper, cfg.physics);
  state.SetLabel(r.success ? "success" : r.failure_reasons.front());
  state.counters["sim_s"] = r.sim_time;
  state.counters["x_realtime"] = r.sim_time / r.wall_time;
  state.counters["free_stones"] = r.free_stones;
}
BENCHMARK(BM_GraspTrial)->DenseRange(0, 6)->Unit(benchmark::kMillisecond)->Iterations(1)->UseRealTime();

/// Collision hull volume over mesh volume per scenario (seed 1): the largest and the smallest.
void BM_HullVolumes(benchmark::State& state) {
  const std::string scenario = kScenarios[static_cast<std::size_t>(state.range(0))];
  const SimulationConfig cfg = unsettled(scenario);
  const Site site = make_site(cfg, 1);
  std::vector<double> hull;
  for (auto _ : state) hull = collision_hull_volumes(site, cfg.physics);
  double lo = 1e9, hi = 0.0;
  for (std::size_t k = 0; k < hull.size(); ++k) {
    lo = std::min(lo, hull[k] / site.stones[k].volume);
    hi = std::max(hi, hull[k] / site.stones[k].volume);
  }
  state.SetLabel(scenario);
  state.counters["hull_over_mesh_min"] = lo;
  state.counters["hull_over_mesh_max"] = hi;
}
BENCHMARK(BM_HullVolumes)->DenseRange(0, 2)->Unit(benchmark::kMillisecond)->Iterations(1)->UseRealTime();

}  // namespace
BENCHMARK_MAIN();
