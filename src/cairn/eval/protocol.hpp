#pragma once
// The paper's evaluation of the registration (Sec. 6.2) on the simulator: while the LiDAR map is
// built online, the drone cloud is registered into it every `every` seconds for `duration`
// seconds; a trial succeeds when the acceptance test passes (RMSE < e_icp over the overlap) and
// every stone is a single merged object. Repeated over seeds, scored against each run's truth
// (registration_scoring.hpp). `cairn protocol` parses its options, calls run_protocol and prints.
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "cairn/eval/app_config.hpp"
#include "cairn/eval/registration_scoring.hpp"

namespace cairn::eval {

/// A success whose error exceeds these is a false positive (the acceptance test let a wrong
/// alignment through); the protocol counts them apart.
inline constexpr double kWrongRotationDeg = 2.0;
inline constexpr double kWrongTranslation = 0.10;  // [m]

struct ProtocolConfig {
  std::string scenario = "exp1";
  std::uint64_t first_seed = 1;
  int seeds = 5;
  double duration = 60.0;  // [s] of scanning per seed
  double every = 5.0;      // [s] a registration every this many seconds of scanning
  bool keep_runs = false;  // keep the simulated run directories (run_seedN under the output)
  /// Acceptance study: refine every candidate, and also register a mirrored (wrong) site each time.
  bool study = false;
  /// Register into the map as the windowed updates left it, without Mapper::reoptimize().
  bool windowed_map = false;
};
/// Throws InputError naming the first bad field (seeds >= 1, every in (0, duration]).
void validate(const ProtocolConfig& config);

/// A refined candidate, right or wrong by its error against the truth: data of the acceptance study.
struct RefinedCandidate {
  double rmse = 0.0, overlap = 0.0;
  bool right = false, accepted = false;
};

/// One registration of the protocol: seed, time of scanning, the scored result.
struct ProtocolTrial {
  std::uint64_t seed = 0;
  double time = 0.0;  // [s] of scanning
  std::size_t map_points = 0;
  ScoredRegistration score;
  /// The error against the map as built: the truth moved by the map's own rigid offset from the
  /// true surfaces at the stones at that time (the GNSS bias and heading error no relative
  /// constraint can observe). score.error = registration + map offset; this is the registration's
  /// share alone.
  RegistrationError error_vs_map;
  double map_offset_m = 0.0;  // displacement of the map's offset at the site centre
  double rmse = 0.0, overlap = 0.0, ms = 0.0;
  double reoptimize_ms = 0.0;  // full pose-graph optimisation and map rebuild before the registration
  std::size_t matched = 0;
  std::vector<RefinedCandidate> refined;
  [[nodiscard]] bool false_positive() const;
  [[nodiscard]] nlohmann::json to_json() const;
};

struct ProtocolResult {
  ProtocolConfig config;
  int stones = 0;
  int per_seed = 0;  // registrations per seed (duration / every)
  std::vector<ProtocolTrial> trials;          // seed by seed, in time order
  std::vector<RefinedCandidate> wrong_site;   // study: candidates of the mirrored drone cloud (all wrong)
  std::vector<std::optional<double>> first_success;  // per seed: the first successful time [s]
};

/// Runs the protocol with `config` (its simulation, mapping, segmentation, registration and scale
/// sections; the drone survey and the truth snapshot are turned on). The run directories go to
/// `out`/run_seedN and are removed unless keep_runs, also when a stage throws. Progress: a log
/// line per seed and per registration (spdlog, info).
[[nodiscard]] ProtocolResult run_protocol(const ProtocolConfig& protocol, AppConfig config,
                                          const std::filesystem::path& out);

/// Counts, success rate and error medians / maxima of the trials from `from_s` seconds of scanning on.
[[nodiscard]] nlohmann::json summarise_trials(const std::vector<ProtocolTrial>& trials, double from_s);
/// How the refined candidates, right and wrong (the study's wrong site included), fall against the test.
[[nodiscard]] nlohmann::json acceptance_study(const ProtocolResult& result);
/// The summary `cairn protocol` prints: configuration, summarise_trials over all trials and from
/// 15 s on, times to first success, the acceptance study; `pictures` names the files drawn.
[[nodiscard]] nlohmann::json protocol_summary(const ProtocolResult& result, const std::filesystem::path& grid_png,
                                              const std::filesystem::path& acceptance_png);

/// Pictures: one cell per trial (rows: seeds; green success, orange accepted with a stone split
/// or missing, red refused, purple wrong answer accepted), and every refined candidate's overlap
/// against its RMSE with the acceptance lines (green right, red wrong).
void draw_protocol_grid(const std::filesystem::path& file, const ProtocolResult& result);
void draw_acceptance(const std::filesystem::path& file, const ProtocolResult& result,
                     const RegistrationAcceptanceConfig& acceptance);

}  // namespace cairn::eval
