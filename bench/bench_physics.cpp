// Physics speed (issue #15, item 5): settling a whole scenario site (the world at rest, target
// <= 1 s wall for 7 stones) and full grasp trials (approach -> close -> lift -> move -> place ->
// release -> settle, target >= 5x real time on 2 cores), with the counters that explain the time:
// islands, free stones, simulated seconds per wall second. Also the collision hulls' volumes and
// the convex decomposition of the real stones (item 4).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <filesystem>

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

/// The world at rest on fresh seeds (issue #15, item 1): scenario range(0), seeds range(1) to
/// range(2). Each site is generated and settled; a site reported at rest is restarted in one scene
/// for 3 s simulated (as WorldAtRest.RestartingThePhysicsMovesNoStone, which runs 4 seeds).
/// Counters: sites generated, reported at rest, the worst restart motion, restarts over 1 cm / 1°.
void BM_WorldAtRestSeeds(benchmark::State& state) {
  const std::string scenario = kScenarios[static_cast<std::size_t>(state.range(0))];
  SimulationConfig cfg = scenario_config(scenario, default_real_mesh_dir());
  cfg.settle_in_physics = true;
  PhysicsConfig restart = cfg.physics;
  restart.settle_time = 3.0;
  restart.settle_speed = 1e-9;  // run the whole time
  double generated = 0, at_rest = 0, moved = 0, worst_shift = 0, worst_turn = 0;
  for (auto _ : state) {
    for (auto seed = static_cast<std::uint64_t>(state.range(1)); seed <= static_cast<std::uint64_t>(state.range(2)); ++seed) {
      SiteSettleResult settle;
      Site site;
      try {
        site = make_site(cfg, seed, &settle);
      } catch (const std::exception&) {
        continue;  // the site cannot be made (a real stone mesh that cannot be read)
      }
      ++generated;
      if (!settle.settled) continue;
      ++at_rest;
      const SettleResult r = settle_stones(site, restart);
      double shift = 0, turn = 0;
      for (std::size_t k = 0; k < site.stones.size(); ++k) {
        shift = std::max(shift, (r.stone_poses[k] * site.stones[k].centroid - site.stones[k].centroid).norm());
        turn = std::max(turn, Eigen::AngleAxisd(r.stone_poses[k].linear()).angle() * 180.0 / 3.141592653589793);
      }
      moved += (shift >= 0.01 || turn >= 1.0) ? 1 : 0;
      worst_shift = std::max(worst_shift, shift);
      worst_turn = std::max(worst_turn, turn);
    }
  }
  state.SetLabel(scenario);
  state.counters["generated"] = generated;
  state.counters["at_rest"] = at_rest;
  state.counters["restart_moved"] = moved;
  state.counters["worst_shift_mm"] = 1e3 * worst_shift;
  state.counters["worst_turn_deg"] = worst_turn;
}
BENCHMARK(BM_WorldAtRestSeeds)
    ->ArgsProduct({{0, 1, 2}, {1}, {50}})
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1)
    ->UseRealTime();

/// Collision hull volume over mesh volume per scenario (seed 1): the largest and the smallest,
/// with the stones' convex parts (range(1) = 1) or one hull per stone (0).
void BM_HullVolumes(benchmark::State& state) {
  const std::string scenario = kScenarios[static_cast<std::size_t>(state.range(0))];
  SimulationConfig cfg = unsettled(scenario);
  if (state.range(1) == 0) cfg.site.stones.collision.max_excess = -1.0;
  const Site site = make_site(cfg, 1);
  std::vector<double> hull;
  for (auto _ : state) hull = collision_hull_volumes(site, cfg.physics);
  double lo = 1e9, hi = 0.0, parts = 0.0;
  for (std::size_t k = 0; k < hull.size(); ++k) {
    lo = std::min(lo, hull[k] / site.stones[k].volume);
    hi = std::max(hi, hull[k] / site.stones[k].volume);
    parts += static_cast<double>(std::max<std::size_t>(1, site.stones[k].collision_parts.size()));
  }
  state.SetLabel(scenario + (state.range(1) ? " parts" : " one hull"));
  state.counters["hull_over_mesh_min"] = lo;
  state.counters["hull_over_mesh_max"] = hi;
  state.counters["parts"] = parts;
}
BENCHMARK(BM_HullVolumes)->ArgsProduct({{0, 1, 2}, {0, 1}})->Unit(benchmark::kMillisecond)->Iterations(1)->UseRealTime();

/// Decomposing each shipped real stone mesh (data/stones, at unit volume): time, parts, and the
/// parts' hulls over the mesh volume (the single hull's in hull_over_mesh).
void BM_DecomposeRealStone(benchmark::State& state) {
  const std::vector<std::string> files = scenario_config("exp1", default_real_mesh_dir()).site.stones.real_meshes;
  const std::string& file = files.at(static_cast<std::size_t>(state.range(0)));
  const cairn::io::Mesh mesh = prepare_real_stone_mesh(cairn::io::read_ply_mesh(file), 1.0);
  std::vector<Eigen::Vector3d> v;
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i) v.push_back(mesh.vertices.world(i));
  ConvexDecomposition d;
  for (auto _ : state) d = decompose_convex(v, mesh.triangles);
  state.SetLabel(std::filesystem::path(file).filename().string());
  state.counters["triangles"] = static_cast<double>(mesh.triangles.size());
  state.counters["parts"] = static_cast<double>(d.parts.size());
  state.counters["hull_over_mesh"] = d.hull_volume / d.mesh_volume;
  state.counters["parts_over_mesh"] = d.parts_volume / d.mesh_volume;
}
BENCHMARK(BM_DecomposeRealStone)->DenseRange(0, 4)->Unit(benchmark::kMillisecond)->Iterations(1)->UseRealTime();

}  // namespace
BENCHMARK_MAIN();
