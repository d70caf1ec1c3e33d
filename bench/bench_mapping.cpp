// End-to-end LiDAR mapping throughput (Sec. 4.2) in scan pairs per second: a simulated exp1 run
// (20 s, no drone) is written once to a temporary directory, then `map_run` maps it repeatedly.
// Sweeps are read from disk inside the timed loop (as `cairn map` does). Per-stage times of the
// last iteration are printed as counters (ms per scan pair; stages that overlap in time, like the
// map update and submap build running beside the next pair's assembly, each count in full).
// online_pairs_per_s: the streaming part alone. The ICP kernel alone vs PCL / Open3D: bench_icp.
#include <benchmark/benchmark.h>

#include <filesystem>
#include <random>

#include "cairn/core/io/run_dir.hpp"
#include "cairn/mapping/local_map.hpp"
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

// Map snapshots (the smoothing): from scratch, and incrementally after what the experiments do
// between two snapshots — a grasp removing one stone's voxels (1 m ball), and a short sweep seeing a
// quarter of the site again. The map: the mapped run's cloud seen 8 times with 1.5 cm noise (a
// noisy voxel shell of ~the size experiment 1's maps reach).
const cairn::LocalMap& bench_local_map() {
  static const cairn::LocalMap map = [] {
    const cairn::PointCloud mapped = cairn::map_run(bench_run(), {}).map;
    cairn::LocalMap m;
    std::mt19937 rng(1);
    std::normal_distribution<float> noise(0.0f, 0.015f);
    for (int pass = 0; pass < 8; ++pass) {
      cairn::PointCloud seen = mapped;
      for (cairn::Vec3f& p : seen.points) p += cairn::Vec3f(noise(rng), noise(rng), noise(rng));
      m.insert(seen);
    }
    return m;
  }();
  return map;
}

const cairn::PointCloud& bench_snapshot() {
  static const cairn::PointCloud c = bench_local_map().snapshot();
  return c;
}

/// Times the snapshot after `change` (untimed, as is the snapshot before it when `incremental`).
template <class Change>
void run_snapshot(benchmark::State& state, bool incremental, Change change) {
  const cairn::LocalMap& base = bench_local_map();
  std::size_t points = 0;
  for (auto _ : state) {
    state.PauseTiming();
    cairn::LocalMap m = base;  // a copy starts without kept surfaces
    if (incremental) (void)m.snapshot();
    change(m, bench_snapshot());
    state.ResumeTiming();
    points = m.snapshot().size();
  }
  state.counters["voxels"] = double(base.num_voxels());
  state.counters["snapshot_points"] = double(points);
}

void remove_a_stone(cairn::LocalMap& m, const cairn::PointCloud& c) {
  (void)m.remove_sphere(c.world(c.size() / 2), 1.0);
}

void sweep_a_quarter(cairn::LocalMap& m, const cairn::PointCloud& c) {
  Eigen::AlignedBox3d box;
  for (const cairn::Vec3f& p : c.points) box.extend(p.cast<double>());
  const cairn::Vec3d centre = c.origin + box.center();  // a quarter of the site: x and y above it
  cairn::PointCloud quarter;
  quarter.origin = c.origin;
  std::mt19937 rng(2);
  std::normal_distribution<float> noise(0.0f, 0.015f);
  for (const cairn::Vec3f& p : c.points) {
    const cairn::Vec3d d = c.origin + p.cast<double>() - centre;
    if (d.x() > 0.0 && d.y() > 0.0) quarter.points.push_back(p + cairn::Vec3f(noise(rng), noise(rng), noise(rng)));
  }
  m.insert(quarter);
}

void BM_Snapshot_FromScratch(benchmark::State& state) {
  run_snapshot(state, false, [](cairn::LocalMap&, const cairn::PointCloud&) {});
}
void BM_Snapshot_AfterGrasp(benchmark::State& state) { run_snapshot(state, true, remove_a_stone); }
void BM_Snapshot_AfterGrasp_FromScratch(benchmark::State& state) { run_snapshot(state, false, remove_a_stone); }
void BM_Snapshot_AfterQuarterSweep(benchmark::State& state) { run_snapshot(state, true, sweep_a_quarter); }
void BM_Snapshot_AfterQuarterSweep_FromScratch(benchmark::State& state) { run_snapshot(state, false, sweep_a_quarter); }

}  // namespace

BENCHMARK(BM_Snapshot_FromScratch)->Unit(benchmark::kMillisecond)->Iterations(3)->UseRealTime();
BENCHMARK(BM_Snapshot_AfterGrasp)->Unit(benchmark::kMillisecond)->Iterations(3)->UseRealTime();
BENCHMARK(BM_Snapshot_AfterGrasp_FromScratch)->Unit(benchmark::kMillisecond)->Iterations(3)->UseRealTime();
BENCHMARK(BM_Snapshot_AfterQuarterSweep)->Unit(benchmark::kMillisecond)->Iterations(3)->UseRealTime();
BENCHMARK(BM_Snapshot_AfterQuarterSweep_FromScratch)->Unit(benchmark::kMillisecond)->Iterations(3)->UseRealTime();
BENCHMARK(BM_MapRun)->Unit(benchmark::kMillisecond)->Iterations(2)->UseRealTime();
BENCHMARK(BM_MapRun_NoLoopClosures)->Unit(benchmark::kMillisecond)->Iterations(2)->UseRealTime();
BENCHMARK(BM_MapRun_OdometryOnly)->Unit(benchmark::kMillisecond)->Iterations(2)->UseRealTime();
BENCHMARK_MAIN();
