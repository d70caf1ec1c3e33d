// End-to-end LiDAR mapping throughput (Sec. 4.2) in scan pairs per second: a simulated exp1 run
// (20 s, no drone) is written once to a temporary directory, then `map_run` maps it repeatedly.
// Sweeps are read from disk inside the timed loop (as `cairn map` does). Per-stage times of the
// last iteration are printed as counters (ms per scan pair; stages that overlap in time, like the
// map update and submap build running beside the next pair's assembly, each count in full).
// online_pairs_per_s: the streaming part alone. The ICP kernel alone vs PCL / Open3D: bench_icp.
#include <benchmark/benchmark.h>

#include <filesystem>

#include "cairn/core/io/run_dir.hpp"
#include "cairn/mapping/mapper.hpp"
#include "cairn/sim/simulation.hpp"

namespace {

namespace fs = std::filesystem;

const cairn::io::RunDirectory& bench_run() {
  static const cairn::io::RunDirectory run = [] {
    const fs::path dir = fs::temp_directory_path() / "cairn_bench_mapping_exp1";
    if (!fs::exists(dir / "run.json")) {
      auto cfg = cairn::sim::scenario_config("exp1", cairn::sim::default_real_mesh_dir());
      cfg.with_drone = false;
      cfg.with_snapshot = false;
      (void)cairn::sim::simulate_run("exp1", cfg, 1, 20.0, dir, true);
    }
    return cairn::io::open_run_directory(dir);
  }();
  return run;
}

void run_mapping(benchmark::State& state, const cairn::MappingConfig& config) {
  const auto& run = bench_run();
  cairn::MapRunResult r;
  std::size_t pairs = 0;
  double online_seconds = 0.0;
  for (auto _ : state) {
    r = cairn::map_run(run, config);
    pairs += r.stats.pairs;
    online_seconds += r.online_seconds;
    benchmark::DoNotOptimize(r.map.points.data());
  }
  state.counters["pairs_per_s"] = benchmark::Counter(double(pairs), benchmark::Counter::kIsRate);
  // The streaming part alone (read sweeps .. last node), without finish() and the snapshot.
  state.counters["online_pairs_per_s"] = double(pairs) / online_seconds;
  state.counters["nodes"] = double(r.stats.nodes);
  state.counters["map_points"] = double(r.map.size());
  for (const auto& [stage, ms] : r.timings.stages) state.counters[stage + "_ms_per_pair"] = ms / r.stats.pairs;
}

void BM_MapRun(benchmark::State& state) { run_mapping(state, {}); }
void BM_MapRun_NoLoopClosures(benchmark::State& state) {
  cairn::MappingConfig c;
  c.scan_matching.loop_closures = false;
  run_mapping(state, c);
}
void BM_MapRun_OdometryOnly(benchmark::State& state) {  // no ICP: the floor of the pipeline
  cairn::MappingConfig c;
  c.scan_matching.enabled = false;
  run_mapping(state, c);
}

}  // namespace

BENCHMARK(BM_MapRun)->Unit(benchmark::kMillisecond)->Iterations(2)->UseRealTime();
BENCHMARK(BM_MapRun_NoLoopClosures)->Unit(benchmark::kMillisecond)->Iterations(2)->UseRealTime();
BENCHMARK(BM_MapRun_OdometryOnly)->Unit(benchmark::kMillisecond)->Iterations(2)->UseRealTime();
BENCHMARK_MAIN();
