#include "cairn/eval/protocol.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>

#include "cairn/core/error.hpp"
#include "cairn/core/image.hpp"
#include "cairn/core/log.hpp"
#include "cairn/core/stats.hpp"
#include "cairn/mapping/mapper.hpp"
#include "cairn/sim/simulation.hpp"

namespace cairn::eval {
namespace {

constexpr int kCellPixels = 24;  // grid picture: one cell per trial
// Acceptance-study picture: overlap share (x, 0..1) against overlap RMSE (y, 0..kPlotMaxRmse).
constexpr int kPlotSize = 480;
constexpr double kPlotMaxRmse = 0.08;  // [m]
constexpr double kLateFrom = 15.0;     // [s] the summary's second window: trials from 15 s of scanning on

/// The median of a sample, 0 when it is empty (the summary's convention).
double median_or_zero(const std::vector<double>& v) { return v.empty() ? 0.0 : median(v); }

/// {"median", "max"} of a sample (0 for both when it is empty).
nlohmann::json median_max(const std::vector<double>& v) {
  return {{"median", median_or_zero(v)}, {"max", v.empty() ? 0.0 : *std::max_element(v.begin(), v.end())}};
}

/// {"min", "median", "max"} of a sample (null when it is empty).
nlohmann::json range(const std::vector<double>& v) {
  if (v.empty()) return nullptr;
  return {{"min", *std::min_element(v.begin(), v.end())}, {"median", median(v)}, {"max", *std::max_element(v.begin(), v.end())}};
}

bool right_answer(const RegistrationError& e) {
  return e.rotation_deg < kWrongRotationDeg && e.translation_m < kWrongTranslation;
}

/// A run directory removed when it goes out of scope (also when a stage throws), unless kept.
struct RemoveRun {
  std::filesystem::path dir;
  bool keep;
  ~RemoveRun() {
    std::error_code ec;
    if (!keep) std::filesystem::remove_all(dir, ec);
  }
};

/// The drone cloud's layout mirrored: a site that does not exist (the acceptance study's wrong site).
PointCloud mirrored(const PointCloud& drone) {
  PointCloud m = drone;
  for (Vec3f& p : m.points) p.x() = -p.x();
  m.origin.x() = -m.origin.x();
  m.normals.clear();
  return m;
}

/// The seed's run simulated into `run_dir` and opened.
io::RunDirectory simulate(const ProtocolConfig& p, const AppConfig& cfg, std::uint64_t seed,
                          const std::filesystem::path& run_dir) {
  (void)sim::simulate_run(p.scenario, cfg.simulation, seed, p.duration, run_dir, /*overwrite=*/true);
  return io::open_run_directory(run_dir);
}

/// One seed: the run simulated, the map built sweep by sweep, a registration every `every` seconds.
class SeedRun {
 public:
  SeedRun(const ProtocolConfig& p, const AppConfig& cfg, std::uint64_t seed, const std::filesystem::path& run_dir,
          ProtocolResult& out)
      : p_(p), cfg_(cfg), seed_(seed), out_(out),
        run_(simulate(p, cfg, seed, run_dir)),
        drone_(load_metric_drone(run_, cfg.scale)), truth_(load_registration_truth(run_, out.stones)),
        true_objects_(truth_.snapshot), mirrored_(mirrored(drone_.cloud)),
        mapper_({.robot = run_.robot, .T_cabin_sensor = run_.T_cabin_sensor}, cfg.mapping) {
    if (run_.scans.empty()) throw InputError("protocol: the simulated run holds no scans");
    mapper_.add_state_estimates(run_.state_estimate);
    mapper_.add_joint_states(run_.joint_states);
  }

  /// Maps every sweep, registering at each multiple of `every` before the sweep that passes it.
  std::optional<double> run() {
    const double t0 = run_.scans.front().t_start;
    for (const io::ScanInfo& scan : run_.scans) {
      while (done_ < out_.per_seed && scan.t_end - t0 > p_.every * (done_ + 1)) trigger(p_.every * (done_ + 1));
      mapper_.add_sweep(scan.sensor, run_.read_scan(scan), scan.t_start, scan.t_end);
    }
    mapper_.flush();
    while (done_ < out_.per_seed) trigger(p_.every * (done_ + 1));
    return first_;
  }

 private:
  void trigger(double time) {
    ProtocolTrial t{.seed = seed_, .time = time};
    // The map as the mapper would hand it to registration: every node reoptimised, so its
    // absolute frame follows all GNSS/INS priors so far, not only the first window's.
    if (!p_.windowed_map) {
      Stopwatch reopt;
      mapper_.reoptimize();
      t.reoptimize_ms = reopt.elapsed_ms();
    }
    const PointCloud map = mapper_.map();
    t.map_points = map.size();
    if (!map.empty()) register_into(map, t);
    if (p_.study && !map.empty()) study_wrong_site(map, time);
    if (t.score.success && !first_) first_ = time;
    spdlog::info("protocol seed {} t = {:4.1f} s: {} (accepted {}, {}/{} stones single, {:.3f} deg, {:.1f} mm; "
                 "vs the map {:.3f} deg, {:.1f} mm (its offset at the stones {:.1f} mm); {:.0f} ms)",
                 seed_, time, t.score.success ? "success" : "failure", t.score.accepted, t.score.single_stones,
                 out_.stones, t.score.error.rotation_deg, 1000 * t.score.error.translation_m,
                 t.error_vs_map.rotation_deg, 1000 * t.error_vs_map.translation_m, 1000 * t.map_offset_m, t.ms);
    out_.trials.push_back(std::move(t));
    ++done_;
  }

  void register_into(const PointCloud& map, ProtocolTrial& t) const {
    const GlobalRegistrationResult r = register_global(drone_.cloud, map, cfg_.segmentation, cfg_.registration);
    t.score = score_registration(r, drone_, truth_);
    const MapRelativeError rel = error_against_map(r.T_target_source, drone_, truth_, true_objects_, map);
    t.error_vs_map = rel.error;
    t.map_offset_m = rel.map_offset_m;
    t.rmse = r.rmse;
    t.overlap = r.overlap;
    t.ms = r.timings.total();
    t.matched = r.matched_segments.size();
    for (const CandidateReport& c : r.reports) {
      if (!c.refined) continue;
      const RegistrationError e =
          registration_error(Similarity::from_isometry(c.T_world), drone_.T_map_metric_true, truth_.site_centre);
      t.refined.push_back({.rmse = c.rmse, .overlap = c.overlap, .right = right_answer(e), .accepted = c.accepted});
    }
  }

  void study_wrong_site(const PointCloud& map, double time) {
    const GlobalRegistrationResult w = register_global(mirrored_, map, cfg_.segmentation, cfg_.registration);
    for (const CandidateReport& c : w.reports)
      if (c.refined) out_.wrong_site.push_back({.rmse = c.rmse, .overlap = c.overlap, .right = false, .accepted = c.accepted});
    if (w.success) spdlog::warn("protocol seed {} t = {:.1f} s: the mirrored (wrong) site was accepted", seed_, time);
  }

  const ProtocolConfig& p_;
  const AppConfig& cfg_;
  std::uint64_t seed_;
  ProtocolResult& out_;
  io::RunDirectory run_;
  MetricDrone drone_;
  RegistrationTruth truth_;
  ObjectSurfaceTruth true_objects_;  // for the map's offset at the stones
  PointCloud mirrored_;
  Mapper mapper_;
  int done_ = 0;
  std::optional<double> first_;
};

}  // namespace

void validate(const ProtocolConfig& c) {
  if (c.seeds < 1) throw InputError("protocol: --seeds must be >= 1");
  if (!(c.duration > 0.0) || !std::isfinite(c.duration)) throw InputError("protocol: --duration must be > 0");
  if (!(c.every > 0.0) || c.every > c.duration) throw InputError("protocol: --every must be in (0, --duration]");
}

bool ProtocolTrial::false_positive() const {
  return score.accepted &&
         (score.error.rotation_deg > kWrongRotationDeg || score.error.translation_m > kWrongTranslation);
}

nlohmann::json ProtocolTrial::to_json() const {
  nlohmann::json j = score.to_json();
  j["seed"] = seed;
  j["time_s"] = time;
  j["map_points"] = map_points;
  j["rmse_m"] = rmse;
  j["overlap"] = overlap;
  j["matched_segments"] = matched;
  j["registration_ms"] = ms;
  j["reoptimize_ms"] = reoptimize_ms;
  j["rotation_error_vs_map_deg"] = error_vs_map.rotation_deg;
  j["translation_error_vs_map_m"] = error_vs_map.translation_m;
  j["map_offset_m"] = map_offset_m;
  j["false_positive"] = false_positive();
  nlohmann::json cands = nlohmann::json::array();
  for (const RefinedCandidate& c : refined)
    cands.push_back({{"rmse_m", c.rmse}, {"overlap", c.overlap}, {"right", c.right}, {"accepted", c.accepted}});
  j["refined_candidates"] = cands;
  return j;
}

ProtocolResult run_protocol(const ProtocolConfig& protocol, AppConfig cfg, const std::filesystem::path& out) {
  validate(protocol);
  cfg.simulation.with_drone = true;
  cfg.simulation.with_snapshot = true;
  cfg.simulation.with_scan_truth = false;
  cfg.mapping.validate();
  if (protocol.study) cfg.registration.refine_all = true;
  cfg.registration.validate();
  std::filesystem::create_directories(out);
  ProtocolResult result{.config = protocol, .stones = int(cfg.simulation.site.stones.count),
                        .per_seed = int(protocol.duration / protocol.every + 1e-9)};
  for (int s = 0; s < protocol.seeds; ++s) {
    const std::uint64_t seed = protocol.first_seed + std::uint64_t(s);
    const std::filesystem::path run_dir = out / ("run_seed" + std::to_string(seed));
    spdlog::info("protocol seed {} ({}/{}): simulating {} s of scanning", seed, s + 1, protocol.seeds, protocol.duration);
    const RemoveRun remove_run{run_dir, protocol.keep_runs};
    SeedRun run(protocol, cfg, seed, run_dir, result);
    result.first_success.push_back(run.run());
  }
  return result;
}

nlohmann::json summarise_trials(const std::vector<ProtocolTrial>& trials, double from) {
  std::size_t n = 0, ok = 0, accepted = 0, wrong = 0;
  std::vector<double> rot, trans, rot_map, trans_map, ms, reopt_ms, offsets;
  for (const ProtocolTrial& t : trials) {
    if (t.time < from) continue;
    ++n;
    ok += t.score.success;
    accepted += t.score.accepted;
    wrong += t.false_positive();
    ms.push_back(t.ms);
    reopt_ms.push_back(t.reoptimize_ms);
    if (t.map_points > 0) offsets.push_back(t.map_offset_m);  // an empty map has no offset
    if (!t.score.success) continue;
    rot.push_back(t.score.error.rotation_deg);
    trans.push_back(t.score.error.translation_m);
    rot_map.push_back(t.error_vs_map.rotation_deg);
    trans_map.push_back(t.error_vs_map.translation_m);
  }
  return {{"from_s", from},
          {"trials", n},
          {"success", ok},
          {"success_rate", n ? double(ok) / double(n) : 0.0},
          {"accepted", accepted},
          {"false_positives", wrong},
          {"rotation_error_deg", median_max(rot)},
          {"translation_error_m", median_max(trans)},
          {"rotation_error_vs_map_deg", median_max(rot_map)},
          {"translation_error_vs_map_m", median_max(trans_map)},
          {"registration_ms_median", median_or_zero(ms)},
          {"reoptimize_ms_median", median_or_zero(reopt_ms)},
          {"map_offset_m", median_max(offsets)}};
}

namespace {

/// Every refined candidate of the protocol: the study's wrong site first, then the trials'.
std::vector<RefinedCandidate> all_refined(const ProtocolResult& r) {
  std::vector<RefinedCandidate> all = r.wrong_site;
  for (const ProtocolTrial& t : r.trials) all.insert(all.end(), t.refined.begin(), t.refined.end());
  return all;
}

}  // namespace

nlohmann::json acceptance_study(const ProtocolResult& r) {
  std::size_t right = 0, wrong = 0, right_accepted = 0, wrong_accepted = 0;
  std::vector<double> right_rmse, right_overlap, wrong_rmse, wrong_overlap;
  for (const RefinedCandidate& c : all_refined(r)) {
    (c.right ? right : wrong)++;
    (c.right ? right_accepted : wrong_accepted) += c.accepted;
    (c.right ? right_rmse : wrong_rmse).push_back(c.rmse);
    (c.right ? right_overlap : wrong_overlap).push_back(c.overlap);
  }
  return {{"right", {{"refined", right}, {"accepted", right_accepted}, {"rmse_m", range(right_rmse)}, {"overlap", range(right_overlap)}}},
          {"wrong", {{"refined", wrong}, {"accepted", wrong_accepted}, {"rmse_m", range(wrong_rmse)}, {"overlap", range(wrong_overlap)}}},
          {"wrong_site_refined", r.wrong_site.size()},
          {"wrong_site_accepted",
           std::count_if(r.wrong_site.begin(), r.wrong_site.end(), [](const RefinedCandidate& c) { return c.accepted; })}};
}

nlohmann::json protocol_summary(const ProtocolResult& r, const std::filesystem::path& grid_png,
                                const std::filesystem::path& acceptance_png) {
  nlohmann::json first = nlohmann::json::array();
  std::vector<double> firsts;
  for (const std::optional<double>& f : r.first_success) {
    first.push_back(f ? nlohmann::json(*f) : nlohmann::json(nullptr));
    if (f) firsts.push_back(*f);
  }
  nlohmann::json acceptance = acceptance_study(r);
  acceptance["picture"] = acceptance_png.string();
  const ProtocolConfig& c = r.config;
  return {{"scenario", c.scenario},
          {"seeds", c.seeds},
          {"first_seed", c.first_seed},
          {"duration_s", c.duration},
          {"every_s", c.every},
          {"windowed_map", c.windowed_map},
          {"stones", r.stones},
          {"all", summarise_trials(r.trials, 0.0)},
          {"from_15s", summarise_trials(r.trials, kLateFrom)},
          {"time_to_first_success_s", first},
          {"time_to_first_success_median_s", median_or_zero(firsts)},
          {"seeds_without_success", c.seeds - int(firsts.size())},
          {"acceptance_study", acceptance},
          {"picture", grid_png.string()}};
}

void draw_protocol_grid(const std::filesystem::path& file, const ProtocolResult& r) {
  Image img(r.per_seed * kCellPixels + 2, r.config.seeds * kCellPixels + 2, {255, 255, 255});
  for (std::size_t k = 0; k < r.trials.size(); ++k) {
    const ProtocolTrial& t = r.trials[k];
    const int row = int(k) / r.per_seed, col = int(k) % r.per_seed;
    Rgb c{200, 60, 50};                             // refused
    if (t.score.success) c = {60, 170, 80};         // success
    else if (t.score.accepted) c = {240, 170, 40};  // accepted, a stone split or missing
    if (t.false_positive()) c = {90, 0, 90};        // wrong answer accepted
    for (int y = 2; y < kCellPixels; ++y)
      for (int x = 2; x < kCellPixels; ++x) img.at(col * kCellPixels + x, row * kCellPixels + y) = c;
  }
  write_png(file, img);
}

void draw_acceptance(const std::filesystem::path& file, const ProtocolResult& r, const RegistrationAcceptanceConfig& acc) {
  Image img(kPlotSize, kPlotSize, {255, 255, 255});
  // Clamped in double first: an RMSE without overlapping points is +inf.
  const auto px = [](double overlap) { return int(std::clamp(overlap, 0.0, 1.0) * (kPlotSize - 1)); };
  const auto py = [](double rmse) {
    return kPlotSize - 1 - int(std::clamp(rmse / kPlotMaxRmse, 0.0, 1.0) * (kPlotSize - 1));
  };
  for (int y = 0; y < kPlotSize; ++y) img.at(px(acc.min_overlap), y) = {150, 150, 150};  // acceptance lines
  for (int x = 0; x < kPlotSize; ++x) img.at(x, py(acc.e_icp)) = {150, 150, 150};
  for (const RefinedCandidate& c : all_refined(r)) {
    const Rgb col = c.right ? Rgb{40, 160, 70} : Rgb{210, 40, 40};
    const int cx = px(c.overlap), cy = py(c.rmse);
    for (int dy = -3; dy <= 3; ++dy)
      for (int dx = -3; dx <= 3; ++dx)
        if (dx * dx + dy * dy <= 9 && cx + dx >= 0 && cx + dx < kPlotSize && cy + dy >= 0 && cy + dy < kPlotSize)
          img.at(cx + dx, cy + dy) = col;
  }
  write_png(file, img);
}

}  // namespace cairn::eval
