// Simulator throughput (issue #4 target: 20 s of both LiDARs, ~400 sweeps of 28.8k rays, in
// <= 10 s on 2 cores). Ray casting alone, and the whole run directory (scans, state, truth) written
// to a temporary directory, scenario exp1, seed 1.
#include <benchmark/benchmark.h>

#include <filesystem>

#include "cairn/sim/simulation.hpp"

namespace {
using namespace cairn::sim;
constexpr double kDuration = 20.0;  // [s] of simulated time

void BM_LidarSweeps20s(benchmark::State& state) {
  const SimulationConfig cfg = scenario_config("exp1", default_real_mesh_dir());
  const SimulatedWorld world = make_world(cfg, 1);
  const auto schedule = sweep_schedule(cfg.lidar, kDuration, 1);
  std::size_t points = 0, rays = 0;
  for (auto _ : state) {
    points = rays = 0;
    for (const auto& s : schedule) {
      const Sweep sweep = simulate_scheduled_sweep(world, cfg.lidar, s, 1);
      points += sweep.points.size();
      rays += sweep.num_rays;
    }
  }
  state.counters["sweeps"] = static_cast<double>(schedule.size());
  state.counters["points"] = static_cast<double>(points);
  state.counters["rays"] = static_cast<double>(rays);
  state.counters["Mrays_per_s"] = benchmark::Counter(static_cast<double>(rays) * 1e-6, benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_LidarSweeps20s)->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();

void BM_SimulateRun20sNoDrone(benchmark::State& state) {
  SimulationConfig cfg = scenario_config("exp1", default_real_mesh_dir());
  cfg.with_drone = false;
  const auto dir = std::filesystem::temp_directory_path() / "cairn_bench_simulate";
  for (auto _ : state) {
    std::filesystem::remove_all(dir);
    const SimulationSummary s = simulate_run("exp1", cfg, 1, kDuration, dir);
    state.counters["sweeps"] = static_cast<double>(s.sweeps);
    state.counters["lidar_s"] = s.seconds_lidar;
    state.counters["write_s"] = s.seconds_write;
  }
  std::filesystem::remove_all(dir);
}
BENCHMARK(BM_SimulateRun20sNoDrone)->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();

void BM_DroneSurvey(benchmark::State& state) {
  const SimulationConfig cfg = scenario_config("exp1", default_real_mesh_dir());
  const SimulatedWorld world = make_world(cfg, 1);
  for (auto _ : state) {
    const DroneSurvey s = simulate_drone(world.site, world.scene, cfg.drone, 1);
    state.counters["points"] = static_cast<double>(s.cloud.size());
    state.counters["images"] = static_cast<double>(s.images.size());
  }
}
BENCHMARK(BM_DroneSurvey)->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
