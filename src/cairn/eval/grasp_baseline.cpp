#include "cairn/eval/grasp_baseline.hpp"

#include <algorithm>
#include <filesystem>
#include <mutex>
#include <optional>
#include <stdexcept>

#include <tbb/parallel_for.h>

#include "cairn/core/error.hpp"
#include "cairn/eval/scanned_site.hpp"
#include "cairn/sim/simulation.hpp"

namespace cairn::eval {
namespace {

struct SiteJob {
  std::string scenario;
  std::uint64_t seed = 0;
  sim::Site site;
  bool at_rest = false;
  std::string error;  // why the site could not be made (the generator's ConfigError, a mesh's InputError)
};

/// The scenario's site of `seed`, settled at rest in the physics (as the sensors see it).
SiteJob settled_site(const std::string& scenario, std::uint64_t seed, const GraspBaselineConfig& c,
                     const std::filesystem::path& mesh_dir) {
  sim::SimulationConfig cfg = sim::scenario_config(scenario, mesh_dir);
  cfg.physics = c.physics;
  cfg.gripper = c.gripper;
  cfg.settle_in_physics = true;
  sim::SiteSettleResult settle;
  SiteJob job{.scenario = scenario, .seed = seed};
  try {
    job.site = sim::make_site(cfg, seed, &settle);
  } catch (const std::runtime_error& e) {  // e.g. a real stone mesh that cannot be read
    job.error = e.what();
  }
  job.at_rest = settle.settled;
  return job;
}

GraspBaselineTrial run_trial(const SiteJob& job, int stone, const GraspBaselineConfig& c) {
  const sim::Stone& s = job.site.stones[static_cast<std::size_t>(stone)];
  sim::CentredGraspOptions o;
  o.place_offset = Eigen::Vector2d::Zero();
  o.place_yaw = c.place_yaw;
  GraspPlan plan = sim::centred_antipodal_grasp(s, c.gripper, &job.site.terrain, o);
  plan.target_stone = stone;
  GraspBaselineTrial t{.scenario = job.scenario, .seed = job.seed, .stone = stone, .volume = s.volume,
                       .width = sim::shortest_horizontal_extent(s).first, .site_at_rest = job.at_rest,
                       .result = sim::run_grasp_trial(job.site, plan, c.gripper, c.physics)};
  t.result.trace.clear();
  return t;
}

}  // namespace

GraspBaselineSummary summarize(const std::vector<GraspBaselineTrial>& trials) {
  GraspBaselineSummary s;
  for (const GraspBaselineTrial& t : trials) {
    ++s.trials;
    s.successes += t.result.success ? 1 : 0;
    for (const std::string& r : t.result.failure_reasons) ++s.failure_reasons[r];
    s.sim_time += t.result.sim_time;
    s.wall_time += t.result.wall_time;
  }
  return s;
}

GraspBaselineResult run_grasp_baseline(const GraspBaselineConfig& c, const std::function<void(int, int)>& progress) {
  sim::validate(c.physics);
  validate(c.gripper);
  std::vector<std::pair<std::string, std::uint64_t>> keys;
  for (const std::string& scenario : c.scenarios) {
    for (const std::uint64_t seed : c.seeds) keys.emplace_back(scenario, seed);
  }
  require_scenarios(c.scenarios);
  const std::filesystem::path mesh_dir =
      c.mesh_dir.empty() ? sim::default_real_mesh_dir() : std::filesystem::path(c.mesh_dir);
  std::vector<SiteJob> sites(keys.size());
  tbb::parallel_for(std::size_t{0}, keys.size(),
                    [&](std::size_t i) { sites[i] = settled_site(keys[i].first, keys[i].second, c, mesh_dir); });
  GraspBaselineResult r;
  std::vector<std::pair<std::size_t, int>> jobs;  // (site, stone)
  for (std::size_t i = 0; i < sites.size(); ++i) {
    if (!sites[i].error.empty()) {
      r.skipped_sites.push_back(sites[i].scenario + " seed " + std::to_string(sites[i].seed) + ": " + sites[i].error);
      continue;
    }
    for (int k = 0; k < static_cast<int>(sites[i].site.stones.size()); ++k) jobs.emplace_back(i, k);
  }
  r.trials.resize(jobs.size());
  std::mutex mutex;
  int done = 0;
  tbb::parallel_for(std::size_t{0}, jobs.size(), [&](std::size_t j) {
    r.trials[j] = run_trial(sites[jobs[j].first], jobs[j].second, c);
    if (!progress) return;
    const std::lock_guard<std::mutex> lock(mutex);
    progress(++done, static_cast<int>(jobs.size()));
  });
  r.summary = summarize(r.trials);
  return r;
}

}  // namespace cairn::eval
