// cairn protocol: the paper's evaluation of the registration (Sec. 6): while the LiDAR map is
// being built online, register the drone cloud into it every `--every` seconds for `--duration`
// seconds; a trial succeeds when the acceptance test passes (RMSE < e_icp over the overlap) AND
// every stone is a single merged object. Repeated over seeds; prints a JSON summary (success
// rate, errors against the truth and against the map as built, time to first success) and draws
// the trials as a grid.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <fstream>
#include <iostream>

#include "app_config.hpp"
#include "cairn/core/image.hpp"
#include "cairn/core/io/run_dir.hpp"
#include "cairn/eval/registration_scoring.hpp"
#include "cairn/mapping/mapper.hpp"
#include "cairn/sim/simulation.hpp"
#include "commands.hpp"

namespace cairn::app {
namespace {

// A success whose error exceeds these is a false positive (the acceptance test let a wrong
// alignment through); the protocol counts them separately.
constexpr double kWrongRotationDeg = 2.0;
constexpr double kWrongTranslation = 0.10;  // [m]
constexpr int kCellPixels = 24;             // grid picture: one cell per trial
// Acceptance-study picture: overlap share (x, 0..1) against overlap RMSE (y, 0..kPlotMaxRmse).
constexpr int kPlotSize = 480;
constexpr double kPlotMaxRmse = 0.08;  // [m]

struct ProtocolArgs {
  std::string out = "cairn_protocol";
  std::string scenario = "exp1";
  std::uint64_t first_seed = 1;
  int seeds = 5;
  double duration = 60.0;
  double every = 5.0;
  bool keep_runs = false;
  bool study = false;  // acceptance study: refine all candidates, add a wrong site (mirrored drone cloud)
  bool windowed_map = false;  // register into the windowed map as is, without Mapper::reoptimize()
  CommonOptions common;
};

/// A refined candidate, right or wrong by its error against the truth: data of the acceptance study.
struct RefinedCandidate {
  double rmse = 0.0, overlap = 0.0;
  bool right = false, accepted = false;
};

struct Trial {
  std::uint64_t seed = 0;
  double time = 0.0;  // seconds of scanning
  std::size_t map_points = 0;
  eval::ScoredRegistration score;
  /// The error against the map as built: the truth moved by the map's own rigid offset from the
  /// true surfaces at the stones at that time (ICP of the map's points near the stones onto the
  /// truth snapshot; the GNSS bias and heading error no relative constraint can observe). score.error = registration + map offset; this is
  /// the registration's share alone.
  RegistrationError error_vs_map;
  double map_offset_m = 0.0;  // displacement of the map's offset at the site centre
  double rmse = 0.0, overlap = 0.0, ms = 0.0;
  double reoptimize_ms = 0.0;  // full pose-graph optimisation and map rebuild before the snapshot
  std::size_t matched = 0;
  std::vector<RefinedCandidate> refined;
  [[nodiscard]] bool false_positive() const {
    return score.accepted &&
           (score.error.rotation_deg > kWrongRotationDeg || score.error.translation_m > kWrongTranslation);
  }
};

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
}

/// {"median", "max"} of a sample (0 for both when it is empty).
nlohmann::json median_max(const std::vector<double>& v) {
  return {{"median", median(v)}, {"max", v.empty() ? 0.0 : *std::max_element(v.begin(), v.end())}};
}

void draw_acceptance(const std::filesystem::path& file, const std::vector<RefinedCandidate>& candidates,
                     const RegistrationAcceptanceConfig& acc) {
  Image img(kPlotSize, kPlotSize, {255, 255, 255});
  // Clamped in double first: an RMSE without overlapping points is +inf.
  const auto px = [](double overlap) { return int(std::clamp(overlap, 0.0, 1.0) * (kPlotSize - 1)); };
  const auto py = [](double rmse) {
    return kPlotSize - 1 - int(std::clamp(rmse / kPlotMaxRmse, 0.0, 1.0) * (kPlotSize - 1));
  };
  for (int y = 0; y < kPlotSize; ++y) img.at(px(acc.min_overlap), y) = {150, 150, 150};  // acceptance lines
  for (int x = 0; x < kPlotSize; ++x) img.at(x, py(acc.e_icp)) = {150, 150, 150};
  for (const RefinedCandidate& c : candidates) {
    const Rgb col = c.right ? Rgb{40, 160, 70} : Rgb{210, 40, 40};
    const int cx = px(c.overlap), cy = py(c.rmse);
    for (int dy = -3; dy <= 3; ++dy)
      for (int dx = -3; dx <= 3; ++dx)
        if (dx * dx + dy * dy <= 9 && cx + dx >= 0 && cx + dx < kPlotSize && cy + dy >= 0 && cy + dy < kPlotSize)
          img.at(cx + dx, cy + dy) = col;
  }
  write_png(file, img);
}

void draw_grid(const std::filesystem::path& file, const std::vector<Trial>& trials, int seeds, int per_seed) {
  Image img(per_seed * kCellPixels + 2, seeds * kCellPixels + 2, {255, 255, 255});
  for (std::size_t k = 0; k < trials.size(); ++k) {
    const Trial& t = trials[k];
    const int row = int(k) / per_seed, col = int(k) % per_seed;
    Rgb c{200, 60, 50};                                // refused
    if (t.score.success) c = {60, 170, 80};            // success
    else if (t.score.accepted) c = {240, 170, 40};     // accepted, a stone split or missing
    if (t.false_positive()) c = {90, 0, 90};           // wrong answer accepted
    for (int y = 2; y < kCellPixels; ++y)
      for (int x = 2; x < kCellPixels; ++x) img.at(col * kCellPixels + x, row * kCellPixels + y) = c;
  }
  write_png(file, img);
}

int run_protocol(const ProtocolArgs& a) {
  AppConfig base;
  base.simulation = sim::scenario_config(a.scenario, sim::default_real_mesh_dir());
  AppConfig cfg = a.common.load(base);
  cfg.simulation.with_drone = true;
  cfg.simulation.with_snapshot = true;
  cfg.simulation.with_scan_truth = false;
  cfg.mapping.validate();
  if (a.study) cfg.registration.refine_all = true;
  cfg.registration.validate();
  if (!(a.every > 0.0) || a.every > a.duration) throw InputError("protocol: --every must be in (0, --duration]");
  const std::filesystem::path out(a.out);
  std::filesystem::create_directories(out);
  const int per_seed = int(a.duration / a.every + 1e-9);
  const int num_stones = int(cfg.simulation.site.stones.count);

  std::vector<Trial> trials;
  std::vector<RefinedCandidate> wrong_site;  // --study: candidates of the mirrored drone cloud (all wrong)
  nlohmann::json first_success = nlohmann::json::array();
  for (int s = 0; s < a.seeds; ++s) {
    const std::uint64_t seed = a.first_seed + std::uint64_t(s);
    const std::filesystem::path run_dir = out / ("run_seed" + std::to_string(seed));
    spdlog::info("protocol seed {} ({}/{}): simulating {} s of scanning", seed, s + 1, a.seeds, a.duration);
    struct RemoveRun {  // also when a stage throws: no run_seedN is left behind
      std::filesystem::path dir;
      bool keep;
      ~RemoveRun() {
        std::error_code ec;
        if (!keep) std::filesystem::remove_all(dir, ec);
      }
    } remove_run{run_dir, a.keep_runs};
    (void)sim::simulate_run(a.scenario, cfg.simulation, seed, a.duration, run_dir, /*overwrite=*/true);
    const io::RunDirectory rd = io::open_run_directory(run_dir);
    const eval::MetricDrone drone = eval::load_metric_drone(rd, cfg.scale);
    const eval::RegistrationTruth truth = eval::load_registration_truth(rd, num_stones);
    const ObjectSurfaceTruth true_objects(truth.snapshot);  // for the map's offset at the stones
    PointCloud mirrored = drone.cloud;  // a site that does not exist: the stones' layout mirrored
    for (Vec3f& p : mirrored.points) p.x() = -p.x();
    mirrored.origin.x() = -mirrored.origin.x();
    mirrored.normals.clear();
    if (rd.scans.empty()) throw InputError("protocol: the simulated run holds no scans");

    Mapper mapper({.robot = rd.robot, .T_cabin_sensor = rd.T_cabin_sensor}, cfg.mapping);
    mapper.add_state_estimates(rd.state_estimate);
    mapper.add_joint_states(rd.joint_states);
    const double t0 = rd.scans.front().t_start;
    int done = 0;
    double first = -1.0;
    const auto trigger = [&](double time) {
      Trial t;
      t.seed = seed;
      t.time = time;
      // The map as the mapper would hand it to registration: every node reoptimised, so its
      // absolute frame follows all GNSS/INS priors so far, not only the first window's.
      if (!a.windowed_map) {
        Stopwatch reopt;
        mapper.reoptimize();
        t.reoptimize_ms = reopt.elapsed_ms();
      }
      const PointCloud map = mapper.map();
      t.map_points = map.size();
      if (!map.empty()) {
        const GlobalRegistrationResult r = register_global(drone.cloud, map, cfg.segmentation, cfg.registration);
        t.score = eval::score_registration(r, drone, truth);
        const eval::MapRelativeError rel = eval::error_against_map(r.T_target_source, drone, truth, true_objects, map);
        t.error_vs_map = rel.error;
        t.map_offset_m = rel.map_offset_m;
        t.rmse = r.rmse;
        t.overlap = r.overlap;
        t.ms = r.timings.total();
        t.matched = r.matched_segments.size();
        for (const CandidateReport& c : r.reports)
          if (c.refined) {
            const RegistrationError e =
                registration_error(Similarity::from_isometry(c.T_world), drone.T_map_metric_true, truth.site_centre);
            t.refined.push_back({.rmse = c.rmse, .overlap = c.overlap,
                                 .right = e.rotation_deg < kWrongRotationDeg && e.translation_m < kWrongTranslation,
                                 .accepted = c.accepted});
          }
      }
      if (a.study && !map.empty()) {
        const GlobalRegistrationResult w = register_global(mirrored, map, cfg.segmentation, cfg.registration);
        for (const CandidateReport& c : w.reports)
          if (c.refined) wrong_site.push_back({.rmse = c.rmse, .overlap = c.overlap, .right = false, .accepted = c.accepted});
        if (w.success) spdlog::warn("protocol seed {} t = {:.1f} s: the mirrored (wrong) site was accepted", seed, time);
      }
      if (t.score.success && first < 0) first = time;
      spdlog::info("protocol seed {} t = {:4.1f} s: {} (accepted {}, {}/{} stones single, {:.3f} deg, {:.1f} mm; "
                   "vs the map {:.3f} deg, {:.1f} mm (its offset at the stones {:.1f} mm); {:.0f} ms)",
                   seed, time, t.score.success ? "success" : "failure", t.score.accepted, t.score.single_stones,
                   num_stones, t.score.error.rotation_deg, 1000 * t.score.error.translation_m,
                   t.error_vs_map.rotation_deg, 1000 * t.error_vs_map.translation_m, 1000 * t.map_offset_m, t.ms);
      trials.push_back(t);
      ++done;
    };
    for (const io::ScanInfo& scan : rd.scans) {
      while (done < per_seed && scan.t_end - t0 > a.every * (done + 1)) trigger(a.every * (done + 1));
      mapper.add_sweep(scan.sensor, rd.read_scan(scan), scan.t_start, scan.t_end);
    }
    mapper.flush();
    while (done < per_seed) trigger(a.every * (done + 1));
    first_success.push_back(first >= 0 ? nlohmann::json(first) : nlohmann::json(nullptr));
  }

  const auto summarise = [&](double from) {
    std::size_t n = 0, ok = 0, accepted = 0, wrong = 0;
    std::vector<double> rot, trans, rot_map, trans_map, ms, reopt_ms, offsets;
    for (const Trial& t : trials) {
      if (t.time < from) continue;
      ++n;
      ok += t.score.success;
      accepted += t.score.accepted;
      wrong += t.false_positive();
      ms.push_back(t.ms);
      reopt_ms.push_back(t.reoptimize_ms);
      if (t.map_points > 0) offsets.push_back(t.map_offset_m);  // an empty map has no offset
      if (t.score.success) {
        rot.push_back(t.score.error.rotation_deg);
        trans.push_back(t.score.error.translation_m);
        rot_map.push_back(t.error_vs_map.rotation_deg);
        trans_map.push_back(t.error_vs_map.translation_m);
      }
    }
    return nlohmann::json{
        {"from_s", from},
        {"trials", n},
        {"success", ok},
        {"success_rate", n ? double(ok) / double(n) : 0.0},
        {"accepted", accepted},
        {"false_positives", wrong},
        {"rotation_error_deg", median_max(rot)},
        {"translation_error_m", median_max(trans)},
        {"rotation_error_vs_map_deg", median_max(rot_map)},
        {"translation_error_vs_map_m", median_max(trans_map)},
        {"registration_ms_median", median(ms)},
        {"reoptimize_ms_median", median(reopt_ms)},
        {"map_offset_m", median_max(offsets)}};
  };
  nlohmann::json trial_json = nlohmann::json::array();
  for (const Trial& t : trials) {
    nlohmann::json j = t.score.to_json();
    j["seed"] = t.seed;
    j["time_s"] = t.time;
    j["map_points"] = t.map_points;
    j["rmse_m"] = t.rmse;
    j["overlap"] = t.overlap;
    j["matched_segments"] = t.matched;
    j["registration_ms"] = t.ms;
    j["reoptimize_ms"] = t.reoptimize_ms;
    j["rotation_error_vs_map_deg"] = t.error_vs_map.rotation_deg;
    j["translation_error_vs_map_m"] = t.error_vs_map.translation_m;
    j["map_offset_m"] = t.map_offset_m;
    j["false_positive"] = t.false_positive();
    nlohmann::json cands = nlohmann::json::array();
    for (const RefinedCandidate& c : t.refined)
      cands.push_back({{"rmse_m", c.rmse}, {"overlap", c.overlap}, {"right", c.right}, {"accepted", c.accepted}});
    j["refined_candidates"] = cands;
    trial_json.push_back(j);
  }
  // The acceptance study: how the refined candidates, right and wrong, fall against the test.
  std::size_t right = 0, wrong = 0, right_accepted = 0, wrong_accepted = 0;
  std::vector<double> right_rmse, right_overlap, wrong_rmse, wrong_overlap;
  std::vector<RefinedCandidate> all_refined = wrong_site;
  for (const Trial& t : trials) all_refined.insert(all_refined.end(), t.refined.begin(), t.refined.end());
  for (const RefinedCandidate& c : all_refined) {
    (c.right ? right : wrong)++;
    (c.right ? right_accepted : wrong_accepted) += c.accepted;
    (c.right ? right_rmse : wrong_rmse).push_back(c.rmse);
    (c.right ? right_overlap : wrong_overlap).push_back(c.overlap);
  }
  const auto range = [](const std::vector<double>& v) {
    if (v.empty()) return nlohmann::json(nullptr);
    return nlohmann::json{{"min", *std::min_element(v.begin(), v.end())}, {"median", median(v)},
                          {"max", *std::max_element(v.begin(), v.end())}};
  };
  const nlohmann::json acceptance{
      {"right", {{"refined", right}, {"accepted", right_accepted}, {"rmse_m", range(right_rmse)}, {"overlap", range(right_overlap)}}},
      {"wrong", {{"refined", wrong}, {"accepted", wrong_accepted}, {"rmse_m", range(wrong_rmse)}, {"overlap", range(wrong_overlap)}}},
      {"wrong_site_refined", wrong_site.size()},
      {"wrong_site_accepted", std::count_if(wrong_site.begin(), wrong_site.end(), [](const auto& c) { return c.accepted; })},
      {"picture", (out / "acceptance.png").string()}};
  draw_acceptance(out / "acceptance.png", all_refined, cfg.registration.acceptance);
  std::vector<double> firsts;
  for (const auto& f : first_success)
    if (!f.is_null()) firsts.push_back(f.get<double>());
  nlohmann::json summary{{"scenario", a.scenario},
                         {"seeds", a.seeds},
                         {"first_seed", a.first_seed},
                         {"duration_s", a.duration},
                         {"every_s", a.every},
                         {"windowed_map", a.windowed_map},
                         {"stones", num_stones},
                         {"all", summarise(0.0)},
                         {"from_15s", summarise(15.0)},
                         {"time_to_first_success_s", first_success},
                         {"time_to_first_success_median_s", median(firsts)},
                         {"seeds_without_success", a.seeds - int(firsts.size())},
                         {"acceptance_study", acceptance},
                         {"picture", (out / "trials.png").string()}};
  std::ofstream(out / "protocol.json") << nlohmann::json{{"summary", summary}, {"trials", trial_json}}.dump(2) << "\n";
  draw_grid(out / "trials.png", trials, a.seeds, per_seed);
  std::cout << summary.dump(2) << std::endl;
  spdlog::info("protocol: {} (rows: seeds, columns: every {} s; green success, orange accepted with a stone split "
               "or missing, red refused, purple wrong answer accepted)",
               (out / "trials.png").string(), a.every);
  return kExitOk;
}

}  // namespace

void add_protocol_command(CLI::App& app, std::function<int()>& run) {
  auto args = std::make_shared<ProtocolArgs>();
  auto* cmd = app.add_subcommand("protocol",
                                 "The paper's registration protocol on the simulator: register the drone cloud into the "
                                 "growing LiDAR map every few seconds, over several seeds; success rate, errors, time "
                                 "to first success");
  cmd->add_option("--out", args->out, "output directory (protocol.json, trials.png)")->capture_default_str();
  cmd->add_option("--scenario", args->scenario, "scenario")->capture_default_str();
  cmd->add_option("--first-seed", args->first_seed, "first scenario seed")->capture_default_str();
  cmd->add_option("--seeds", args->seeds, "number of seeds (sites)")->capture_default_str()->check(CLI::Range(1, 1000));
  cmd->add_option("--duration", args->duration, "seconds of scanning per seed")
      ->capture_default_str()
      ->check(CLI::Range(1.0, 600.0));
  cmd->add_option("--every", args->every, "registration every this many seconds of scanning")->capture_default_str();
  cmd->add_flag("--keep-runs", args->keep_runs, "keep the simulated run directories");
  cmd->add_flag("--study-acceptance", args->study,
                "acceptance-test study: refine every candidate, and also register a mirrored (wrong) site each time");
  cmd->add_flag("--windowed-map", args->windowed_map,
                "register into the map as the windowed updates left it, without a full reoptimisation of the "
                "trajectory and a map rebuild before each registration");
  args->common.add_to(*cmd);
  cmd->callback([&run, args] { run = [args] { return run_protocol(*args); }; });
}

}  // namespace cairn::app
