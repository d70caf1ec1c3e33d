#pragma once
// Simulated runs that several test processes read (ctest runs every test as its own process, so a
// function-local static simulated the same site once per test). Under ctest the runs are written
// once per ctest invocation by the fixture tests of tests/fixtures (FIXTURES_SETUP), into
// $CAIRN_TEST_RUNS; run by hand (no $CAIRN_TEST_RUNS, or the run not there) a test simulates its
// own private copy with the same code. Readers never write into a shared run.
#include <cstdlib>
#include <filesystem>
#include <string>
#include <system_error>

#include <unistd.h>

#include "cairn/core/io/io.hpp"
#include "cairn/core/io/run_dir.hpp"
#include "cairn/mapping/mapper.hpp"
#include "cairn/sim/simulation.hpp"
#include "support/sanitizers.hpp"
#include "support/test_data.hpp"

namespace cairn::test {

/// One simulated run: the scenario's configuration with the real stone meshes, as `cairn
/// simulate` uses it, and optionally its map as `cairn map` builds it (default mapping config).
struct RunSpec {
  std::string scenario;
  std::uint64_t seed = 1;
  double duration = 8.0;  // simulated time [s]
  bool drone = true;      // drone survey and truth/map_snapshot.ply; without: per-point scan truth
  bool mapped = false;    // also map.ply next to run/

  [[nodiscard]] std::string name() const {
    return scenario + "_s" + std::to_string(seed) + "_" + std::to_string(int(duration * 10)) + "ds" +
           (drone ? "_drone" : "_scans") + (mapped ? "_mapped" : "");
  }
};

/// The shared runs every consumer asks for (tests/fixtures writes each of them).
inline const RunSpec kExp1Drone8s{.scenario = "exp1", .seed = 1, .duration = 8.0, .drone = true, .mapped = true};
inline const RunSpec kExp1Scans20s{.scenario = "exp1", .seed = 1, .duration = 20.0, .drone = false, .mapped = false};

/// Writes `spec` under `dir`: DIR/run (a run directory) and, when mapped, DIR/map.ply.
inline void write_run(const RunSpec& spec, const std::filesystem::path& dir) {
  sim::SimulationConfig cfg = sim::scenario_config(spec.scenario, sim::default_real_mesh_dir());
  cfg.with_drone = spec.drone;
  cfg.with_snapshot = spec.drone;
  cfg.with_scan_truth = !spec.drone;
  (void)sim::simulate_run(spec.scenario, cfg, spec.seed, spec.duration, dir / "run", true);
  if (spec.mapped) io::write_ply(dir / "map.ply", map_run(io::open_run_directory(dir / "run"), {}).map);
}

/// Writes `spec` into $CAIRN_TEST_RUNS/NAME, atomically (written aside, then renamed), replacing
/// an older copy. Used by the fixture tests only.
inline std::filesystem::path publish_run(const RunSpec& spec) {
  const char* root = std::getenv("CAIRN_TEST_RUNS");
  if (root == nullptr || *root == '\0') throw std::runtime_error("CAIRN_TEST_RUNS is not set");
  const std::filesystem::path final_dir = std::filesystem::path(root) / spec.name();
  const std::filesystem::path aside = final_dir.string() + ".writing." + std::to_string(::getpid());
  std::filesystem::remove_all(aside);
  std::filesystem::create_directories(aside);
  write_run(spec, aside);
  std::filesystem::remove_all(final_dir);
  std::filesystem::rename(aside, final_dir);
  return final_dir;
}

/// The directory holding run/ (and map.ply) of `spec`: the shared copy when ctest's fixture
/// wrote it, otherwise a private one simulated now (removed when the process exits).
inline std::filesystem::path shared_run(const RunSpec& spec) {
  if (const char* root = std::getenv("CAIRN_TEST_RUNS"); root != nullptr && *root != '\0') {
    const std::filesystem::path dir = std::filesystem::path(root) / spec.name();
    std::error_code ec;
    if (std::filesystem::is_directory(dir / "run", ec)) return dir;
  }
  const std::filesystem::path dir = temp_dir("run_" + spec.name());
  write_run(spec, dir);
  return dir;
}

/// Under the sanitizers: keeps the scans that start in the first `seconds` of `run` (the state
/// estimate and joint states stay whole, they cost nothing to read); elsewhere leaves `run` as is.
/// Tests that compare two ways of mapping the same input keep their assertions on the prefix.
inline void shorten_under_sanitizers(io::RunDirectory& run, double seconds) {
  if (!kSanitized || run.scans.empty()) return;
  const double end = run.scans.front().t_start + seconds;
  std::erase_if(run.scans, [end](const io::ScanInfo& s) { return s.t_start >= end; });
}

}  // namespace cairn::test
