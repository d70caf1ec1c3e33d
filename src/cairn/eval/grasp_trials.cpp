#include "cairn/eval/grasp_trials.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <mutex>
#include <optional>
#include <random>

#include <tbb/parallel_for.h>

#include "cairn/core/error.hpp"
#include "cairn/core/stats.hpp"
#include "cairn/core/transform.hpp"
#include "cairn/eval/scanned_site.hpp"
#include "cairn/objects/pipeline.hpp"
#include "cairn/registration/scale_recovery.hpp"
#include "cairn/sim/drone.hpp"
#include "cairn/sim/physics/grasp_json.hpp"

namespace cairn::eval {
namespace {

using Eigen::Isometry3d;
constexpr double kTruthSpacing = 0.04;  // [m] sampling of the true surfaces

/// What the machine knows about one site after scanning it.
struct SensedSite {
  std::unique_ptr<ScanningMachine> machine;
  PointCloud map;
  std::vector<PointCloud> segments;
  std::vector<int> segment_stone;  // per segment: the stone it lies on (truth), or -1
  std::vector<double> segment_purity;
  std::optional<PointCloud> drone;      // registered drone cloud (map frame)
  std::vector<PointCloud> drone_objects;  // merged LiDAR + drone objects (map frame)
  std::string drone_report;
};

/// The registered drone cloud (Sec. 4.1 scale recovery, 4.4 registration) of the site.
void register_drone(SensedSite& s, const GraspTrialsConfig& c, std::uint64_t seed) {
  const sim::SimulatedWorld& w = s.machine->world();
  const sim::DroneSurvey survey = sim::simulate_drone(w.site, w.scene, s.machine->config().drone, seed);
  const ScaleRecoveryResult scale = recover_scale(sim::to_colmap_model(survey), sim::vins_trajectory(survey));
  PointCloud cloud = survey.cloud;
  cloud.labels.clear();  // the survey's labels are truth: never seen by the planner
  transform_cloud(cloud, scale.T_metric_sfm);
  const GlobalRegistrationResult r = register_global(cloud, s.map, c.segmentation, c.registration);
  if (!r.success) {
    s.drone_report = "registration failed: " + r.reason;
    return;
  }
  transform_cloud(cloud, r.T_target_source);
  s.drone = std::move(cloud);
  for (const auto& o : r.objects) s.drone_objects.push_back(o.cloud);
  s.drone_report = "registered";
}

/// Diagnostic oracle (source = truth): the true surfaces stand in for the drone cloud and each
/// stone's true surface for its model, moved into the map frame by the state estimate's offset.
void truth_as_drone(SensedSite& s, const SurfaceTruth& truth) {
  const Isometry3d map_from_world = s.machine->E_state(s.machine->now()).inverse();
  PointCloud all;
  all.origin = truth.cloud.origin;
  const std::size_t stones = s.machine->world().site.stones.size();
  s.drone_objects.assign(stones, PointCloud{});
  for (std::size_t i = 0; i < truth.cloud.size(); ++i) {
    const Vec3d p = map_from_world * truth.cloud.world(i);
    all.points.push_back((p - all.origin).cast<float>());
    const std::int32_t l = truth.cloud.labels[i];
    if (l < 0 || std::size_t(l) >= stones) continue;
    PointCloud& o = s.drone_objects[std::size_t(l)];
    if (o.empty()) o.origin = all.origin;
    o.points.push_back((p - o.origin).cast<float>());
  }
  s.drone = std::move(all);
  s.drone_report = "truth (oracle)";
}

SensedSite sense_site(const std::string& scenario, std::uint64_t seed, const GraspTrialsConfig& c) {
  sim::SimulationConfig cfg = sim::scenario_config(scenario, sim::default_real_mesh_dir());
  cfg.physics = c.physics;
  cfg.gripper = c.gripper;
  SensedSite s;
  s.machine = std::make_unique<ScanningMachine>(cfg, seed, c.scan_time + 1.0, c.mapping);
  s.machine->scan(0.0, c.scan_time);
  s.map = s.machine->mapper().map();
  s.segments = object_segments(s.map, segment(s.map, c.segmentation));
  const sim::SimulatedWorld& w = s.machine->world();
  const SurfaceTruth truth(w.site, s.machine->base(), kTruthRadius, kTruthSpacing, seed);
  const Isometry3d E = truth.offset->map_offset(s.map);  // scoring only: which stone a segment is
  for (const PointCloud& seg : s.segments) {
    double purity = 0.0;
    s.segment_stone.push_back(truth.stone_of(seg, E, c.score_near, w.site.stones.size(), &purity));
    s.segment_purity.push_back(purity);
  }
  if (c.source == "drone") register_drone(s, c, seed);
  if (c.source == "truth") truth_as_drone(s, truth);
  return s;
}

/// The object's model: its segment, or the registered scene's object holding it (LiDAR + drone).
PointCloud object_model(const SensedSite& s, std::size_t segment) {
  const PointCloud& seg = s.segments[segment];
  const PointCloud* merged = nearest_cloud(s.drone_objects, seg.origin + centroid(seg.points).cast<double>(), kMergedNear);
  return merged ? *merged : seg;
}

/// The largest segment on each stone, or -1.
std::vector<int> segment_of_stone(const SensedSite& s, std::size_t stones) {
  std::vector<int> out(stones, -1);
  for (std::size_t i = 0; i < s.segments.size(); ++i) {
    const int k = s.segment_stone[i];
    if (k < 0) continue;
    int& o = out[std::size_t(k)];
    if (o < 0 || s.segments[i].size() > s.segments[std::size_t(o)].size()) o = int(i);
  }
  return out;
}

/// The plan in the world: commanded in the map frame, executed where the state estimate puts it;
/// placed turned by place_yaw about the vertical through the object's centroid.
GraspPlan world_plan(const grasp::Grasp& g, const Vec3d& centroid_map, const Isometry3d& E, int stone,
                     const GraspTrialsConfig& c) {
  GraspPlan p = grasp::to_grasp_plan(g, GraspPlan{});
  p.T_world_gripper = E * g.T_map_gripper;
  const Vec3d centre = E * centroid_map;
  Isometry3d turn = Isometry3d::Identity();
  turn.translation() = Vec3d(0.0, 0.0, c.place_drop);
  turn = turn * Eigen::Translation3d(centre) * Eigen::AngleAxisd(c.place_yaw, Vec3d::UnitZ()) *
         Eigen::Translation3d(-centre);
  p.T_world_place = turn * p.T_world_gripper;
  p.target_stone = stone;
  return p;
}

/// Plans the stone's grasp on its segment and, when one passes, the plan to execute (E: map -> world).
void plan_trial(PlannedGraspTrial& t, const SensedSite& s, int segment, const Isometry3d& E, const GraspTrialsConfig& c) {
  t.segmented = segment >= 0;
  if (!t.segmented) return;
  t.purity = s.segment_purity[std::size_t(segment)];
  const PointCloud model = object_model(s, std::size_t(segment));
  const grasp::GraspPlanning p = grasp::plan_grasps(s.map, model, s.drone ? &*s.drone : nullptr, c.gripper, c.grasp);
  t.planning_ms = p.timings_ms.at("total");
  t.mass_centroid = E * p.cloud.mass_centroid;
  t.model_centroid = p.cloud.centroid;
  t.counts = p.counts;
  t.planned = !p.grasps.empty();
  if (c.study > 0) {
    std::vector<grasp::Grasp> pool = p.force_closure_grasps;
    std::seed_seq seq{std::uint64_t(std::hash<std::string>{}(t.scenario)), t.seed, std::uint64_t(t.stone)};
    std::mt19937 rng(seq);
    std::shuffle(pool.begin(), pool.end(), rng);
    pool.resize(std::min(pool.size(), std::size_t(c.study)));
    t.study_grasps = std::move(pool);
  }
  if (!t.planned) return;
  t.best = p.grasps.front();
  t.plan = world_plan(t.best, p.cloud.centroid, E, t.stone, c);
}

RateSummary rate(const std::vector<PlannedGraspTrial>& trials, const std::function<bool(const PlannedGraspTrial&)>& keep,
                 bool baseline) {
  RateSummary r;
  for (const PlannedGraspTrial& t : trials) {
    if (!t.segmented || !keep(t)) continue;
    ++r.trials;
    const bool ok = baseline ? t.baseline.success : t.success();
    r.successes += ok ? 1 : 0;
    if (!baseline && !t.planned) ++r.failure_reasons["no_grasp"];
    for (const std::string& f : (baseline ? t.baseline : t.result).failure_reasons) ++r.failure_reasons[f];
  }
  std::tie(r.wilson_low, r.wilson_high) = wilson_interval(r.successes, r.trials);
  return r;
}

void validate(const GraspTrialsConfig& c) {
  if (c.source != "model" && c.source != "drone" && c.source != "truth")
    throw ConfigError("grasp trials: source must be 'model', 'drone' or 'truth' (oracle), not '" + c.source + "'");
  if (!(c.scan_time > 0)) throw ConfigError("grasp trials: scan_time must be > 0");
  c.grasp.validate();
  sim::validate(c.physics);
  validate(c.gripper);
  require_scenarios(c.scenarios);
}

/// config.study: every drawn grasp of every stone executed (in parallel).
void run_study(const sim::Site& site, std::vector<PlannedGraspTrial>& trials, const Isometry3d& E,
               const GraspTrialsConfig& c) {
  std::vector<std::pair<std::size_t, std::size_t>> jobs;
  for (std::size_t k = 0; k < trials.size(); ++k) {
    trials[k].study_results.resize(trials[k].study_grasps.size());
    for (std::size_t j = 0; j < trials[k].study_grasps.size(); ++j) jobs.emplace_back(k, j);
  }
  tbb::parallel_for(std::size_t{0}, jobs.size(), [&](std::size_t i) {
    PlannedGraspTrial& t = trials[jobs[i].first];
    const grasp::Grasp& g = t.study_grasps[jobs[i].second];  // placed as the planned grasp is
    sim::GraspTrialResult r =
        sim::run_grasp_trial(site, world_plan(g, t.model_centroid, E, t.stone, c), c.gripper, c.physics);
    r.trace.clear();
    t.study_results[jobs[i].second] = std::move(r);
  });
}

/// One site: sense, plan every stone, execute the plans (and the baseline) in parallel.
void run_site(const std::string& scenario, std::uint64_t seed, const GraspTrialsConfig& c, GraspTrialsResult& out) {
  const std::string name = scenario + " seed " + std::to_string(seed);
  SensedSite s;
  try {
    s = sense_site(scenario, seed, c);
  } catch (const std::runtime_error& e) {  // the site cannot be made (a mesh that cannot be read)
    out.skipped.push_back(name + ": " + e.what());
    return;
  }
  if (c.source != "model") out.drone_registration += name + ": " + s.drone_report + "; ";
  const sim::Site& site = s.machine->world().site;
  const std::vector<int> seg = segment_of_stone(s, site.stones.size());
  const Isometry3d E = s.machine->E_state(c.scan_time);
  std::vector<PlannedGraspTrial> trials(site.stones.size());
  for (std::size_t k = 0; k < trials.size(); ++k) {
    const sim::Stone& st = site.stones[k];
    trials[k] = {.scenario = scenario, .seed = seed, .stone = int(k), .shape = st.source, .flat = st.flat,
                 .volume = st.volume, .width = sim::shortest_horizontal_extent(st).first,
                 .true_centroid = st.centroid, .true_bounds = st.bounds, .site_at_rest = true};
    plan_trial(trials[k], s, seg[k], E, c);
    if (!trials[k].segmented) out.skipped.push_back(name + " stone " + std::to_string(k) + ": no segment holds it");
  }
  tbb::parallel_for(std::size_t{0}, trials.size() * 2, [&](std::size_t j) {
    PlannedGraspTrial& t = trials[j / 2];
    if (!t.segmented) return;
    if (j % 2 == 0 && t.planned) {
      t.result = sim::run_grasp_trial(site, t.plan, c.gripper, c.physics);
      t.result.trace.clear();
    } else if (j % 2 == 1 && c.baseline) {
      sim::CentredGraspOptions o;
      o.place_offset = Eigen::Vector2d::Zero();
      o.place_yaw = c.place_yaw;
      GraspPlan plan = sim::centred_antipodal_grasp(site.stones[std::size_t(t.stone)], c.gripper, &site.terrain, o);
      plan.target_stone = t.stone;
      t.baseline_plan = plan;
      t.baseline = sim::run_grasp_trial(site, plan, c.gripper, c.physics);
      t.baseline.trace.clear();
    }
  });
  run_study(site, trials, E, c);
  for (PlannedGraspTrial& t : trials) out.trials.push_back(std::move(t));
}

}  // namespace

std::pair<double, double> wilson_interval(int k, int n, double z) {
  if (n <= 0) return {0.0, 1.0};
  const double p = double(k) / n, z2 = z * z, d = 1.0 + z2 / n;
  const double centre = (p + z2 / (2.0 * n)) / d;
  const double half = z * std::sqrt(p * (1.0 - p) / n + z2 / (4.0 * n * n)) / d;
  return {k == 0 ? 0.0 : std::max(0.0, centre - half), k == n ? 1.0 : std::min(1.0, centre + half)};
}

GraspTrialsResult run_grasp_trials(const GraspTrialsConfig& c, const GraspTrialsProgress& progress) {
  validate(c);
  GraspTrialsResult out;
  int done = 0;
  const int total = int(c.scenarios.size() * c.seeds.size());
  for (const std::string& scenario : c.scenarios) {
    for (const std::uint64_t seed : c.seeds) {
      if (progress) progress(scenario + " seed " + std::to_string(seed), done, total);
      run_site(scenario, seed, c, out);
      ++done;
    }
  }
  if (progress) progress("done", done, total);
  const auto all = [](const PlannedGraspTrial&) { return true; };
  out.planned = rate(out.trials, all, false);
  out.planned_flat = rate(out.trials, [](const PlannedGraspTrial& t) { return t.flat; }, false);
  out.planned_roundish = rate(out.trials, [](const PlannedGraspTrial& t) { return !t.flat; }, false);
  if (c.baseline) out.baseline = rate(out.trials, all, true);
  for (const PlannedGraspTrial& t : out.trials)
    if (t.segmented) out.planning_ms.push_back(t.planning_ms);
  return out;
}

namespace {
nlohmann::json study_json(const PlannedGraspTrial& t) {
  nlohmann::json out = nlohmann::json::array();
  for (std::size_t j = 0; j < t.study_grasps.size(); ++j) {
    const grasp::Grasp& g = t.study_grasps[j];
    const sim::GraspTrialResult& r = t.study_results[j];
    out.push_back({{"align_rad", g.costs.align}, {"enclose_m", g.costs.enclose}, {"dist_m", g.costs.dist},
                   {"contact_height_m", g.contact_height}, {"gravity_lever_m", g.gravity_lever},
                   {"contact_angle_rad", g.contact_angle}, {"shift_m", g.shift}, {"opening_m", g.opening},
                   {"closed_opening_m", g.closed_opening}, {"cone_margin_rad", g.cone_margin},
                   {"robustness", g.robustness}, {"undercut", g.undercut}, {"approach", {g.approach.x(), g.approach.y(), g.approach.z()}},
                   {"contact_z", {g.contacts[0].z(), g.contacts[1].z()}},
                   {"palm_z", g.T_map_gripper.translation().z()},
                   {"success", r.success}, {"failure_reasons", r.failure_reasons}, {"message", r.message}});
  }
  return out;
}

nlohmann::json rate_json(const RateSummary& r) {
  return {{"trials", r.trials}, {"successes", r.successes},
          {"success_rate", r.trials > 0 ? double(r.successes) / r.trials : 0.0},
          {"wilson95", {r.wilson_low, r.wilson_high}}, {"failure_reasons", r.failure_reasons}};
}
}  // namespace

nlohmann::json to_json(const GraspTrialsResult& r) {
  nlohmann::json trials = nlohmann::json::array();
  for (const PlannedGraspTrial& t : r.trials) {
    trials.push_back({{"scenario", t.scenario}, {"seed", t.seed}, {"stone", t.stone}, {"shape", t.shape},
                      {"flat", t.flat}, {"volume_m3", t.volume}, {"width_m", t.width}, {"segmented", t.segmented},
                      {"purity", t.purity}, {"planned", t.planned}, {"planning_ms", t.planning_ms},
                      {"success", t.success()}, {"failure_reasons", t.planned ? t.result.failure_reasons
                                                                              : std::vector<std::string>{"no_grasp"}},
                      {"result", sim::to_json(t.result)}, {"force_closure_grasps", t.counts.force_closure},
                      {"balanced_grasps", t.counts.balanced}, {"robust_grasps", t.counts.robust},
                      {"costs", {{"align_rad", t.best.costs.align}, {"enclose_m", t.best.costs.enclose},
                                 {"dist_m", t.best.costs.dist}}},
                      {"robustness", t.best.robustness}, {"contact_height_m", t.best.contact_height},
                      {"gravity_lever_m", t.best.gravity_lever},
                      {"shift_m", t.best.shift}, {"opening_m", t.best.opening},
                      {"closed_opening_m", t.best.closed_opening},
                      {"plan", to_json(t.plan)}, {"baseline_plan", to_json(t.baseline_plan)},
                      {"true_centroid", {t.true_centroid.x(), t.true_centroid.y(), t.true_centroid.z()}},
                      {"mass_centroid", {t.mass_centroid.x(), t.mass_centroid.y(), t.mass_centroid.z()}},
                      {"true_z_range", {t.true_bounds.min().z(), t.true_bounds.max().z()}},
                      {"baseline", sim::to_json(t.baseline)}});
    if (!t.study_grasps.empty()) trials.back()["study"] = study_json(t);
  }
  std::vector<double> ms = r.planning_ms;
  std::sort(ms.begin(), ms.end());
  const auto q = [&](double f) { return ms.empty() ? 0.0 : ms[std::min(ms.size() - 1, std::size_t(f * double(ms.size())))]; };
  return {{"planned", rate_json(r.planned)}, {"planned_flat", rate_json(r.planned_flat)},
          {"planned_roundish", rate_json(r.planned_roundish)}, {"baseline", rate_json(r.baseline)},
          {"planning_ms", {{"median", ms.empty() ? 0.0 : median(ms)}, {"p90", q(0.9)}, {"max", ms.empty() ? 0.0 : ms.back()}}},
          {"skipped", r.skipped}, {"drone_registration", r.drone_registration}, {"trials", trials}};
}

}  // namespace cairn::eval
