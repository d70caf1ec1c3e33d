// Grasp planning speed (issue #17: <= 100 ms per object on 2 cores): cairn::grasp::plan_grasps on
// what the simulated machine senses — the LiDAR map after two swings and each object segment as
// the model, the grasp-trials' "model" source — with each step's time as a counter (planning
// cloud, candidates, force closure + robustness, ranking). No peer: GPD is not packaged.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <map>
#include <memory>

#include "cairn/eval/grasp_trials.hpp"
#include "cairn/eval/scanned_site.hpp"
#include "cairn/grasp/planner.hpp"
#include "cairn/objects/pipeline.hpp"
#include "cairn/segmentation/segmenter.hpp"

namespace {
using namespace cairn;

/// The map and the object segments (largest first) of exp1 seed `seed`, sensed once.
struct SensedMap {
  PointCloud map;
  std::vector<PointCloud> segments;
};

const SensedMap& sensed(std::uint64_t seed) {
  static std::map<std::uint64_t, std::unique_ptr<SensedMap>> cache;
  auto& slot = cache[seed];
  if (slot) return *slot;
  const eval::GraspTrialsConfig c;  // the grasp trials' scanning, mapping and segmentation
  sim::SimulationConfig cfg = sim::scenario_config("exp1", sim::default_real_mesh_dir());
  cfg.physics = c.physics;
  cfg.gripper = c.gripper;
  eval::ScanningMachine machine(cfg, seed, c.scan_time + 1.0, c.mapping);
  machine.scan(0.0, c.scan_time);
  slot = std::make_unique<SensedMap>();
  slot->map = machine.mapper().map();
  slot->segments = object_segments(slot->map, segment(slot->map, c.segmentation));
  std::stable_sort(slot->segments.begin(), slot->segments.end(),
                   [](const PointCloud& a, const PointCloud& b) { return a.size() > b.size(); });
  return *slot;
}

/// plan_grasps on segment range(1) (by size) of exp1 seed range(0); the step times as counters.
void BM_PlanGrasps(benchmark::State& state) {
  const SensedMap& s = sensed(static_cast<std::uint64_t>(state.range(0)));
  const auto k = static_cast<std::size_t>(state.range(1));
  if (k >= s.segments.size()) {
    state.SkipWithError("no such segment");
    return;
  }
  const eval::GraspTrialsConfig c;
  std::map<std::string, double> sum;
  grasp::GraspPlanning p;
  for (auto _ : state) {
    p = grasp::plan_grasps(s.map, s.segments[k], nullptr, c.gripper, c.grasp);
    for (const auto& [step, ms] : p.timings_ms) sum[step] += ms;
  }
  for (const auto& [step, ms] : sum) state.counters[step + "_ms"] = ms / static_cast<double>(state.iterations());
  state.counters["object_points"] = static_cast<double>(p.cloud.object_points);
  state.counters["planning_points"] = static_cast<double>(p.cloud.cloud.size());
  state.counters["poses"] = static_cast<double>(p.counts.poses);
  state.counters["hypotheses"] = static_cast<double>(p.counts.hypotheses);
  state.counters["collision_free"] = static_cast<double>(p.counts.collision_free);
  state.counters["balanced"] = static_cast<double>(p.counts.balanced);
  state.counters["grasps"] = static_cast<double>(p.grasps.size());
}
BENCHMARK(BM_PlanGrasps)
    ->ArgsProduct({{1, 2, 3, 4, 5, 6}, {0, 1, 2, 3, 4, 5, 6}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
