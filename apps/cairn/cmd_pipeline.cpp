// cairn pipeline: the perception chain on the built-in simulated site, each stage through files:
// simulate a scenario (exp1: seven stones of 0.5–1 m³ in front of the swinging excavator, two
// VLP-16s, GNSS/IMU state estimate, drone survey) → LiDAR mapping online (Sec. 4.2) → drone cloud
// scaled (Sec. 4.1) and registered into the map (Sec. 4.4) → segment the merged map (Sec. 4.3) →
// score against the simulator's ground truth. Writes the run directory, the map, the trajectory,
// the segments and a top view with the stones coloured; prints per-stage figures.
#include <spdlog/spdlog.h>

#include <fstream>
#include <iostream>

#include "app_config.hpp"
#include "cairn/core/image.hpp"
#include "cairn/core/io/io.hpp"
#include "cairn/core/io/run_dir.hpp"
#include "cairn/core/io/trajectory.hpp"
#include "cairn/eval/map_scoring.hpp"
#include "cairn/eval/registration_scoring.hpp"
#include "cairn/mapping/mapper.hpp"
#include "cairn/segmentation/evaluation.hpp"
#include "cairn/segmentation/output.hpp"
#include "cairn/sim/simulation.hpp"
#include "commands.hpp"

namespace cairn::app {
namespace {

constexpr double kTopViewPixelsPerMetre = 40.0;

struct PipelineArgs {
  std::string out = "cairn_pipeline";
  std::string scenario = "exp1";
  std::uint64_t seed = 1;
  double duration = 20.0;
  int stones = 0;  // 0: the scenario's count
  bool no_drone = false;
  CommonOptions common;
};

nlohmann::json ate_json(const eval::TrajectoryError& e) {
  return {{"rmse_m", e.ate_rmse}, {"rmse_without_mean_m", e.ate_rmse_without_mean}, {"rotation_rmse_deg", e.rotation_rmse_deg}};
}

void write_trajectory(const std::filesystem::path& file, const std::vector<StampedPose>& poses) {
  std::vector<io::TrajectoryPose> tum;
  for (const StampedPose& p : poses)
    tum.push_back({.timestamp = p.time, .position = p.pose.translation(),
                   .orientation = Eigen::Quaterniond(p.pose.linear()).normalized()});
  io::write_tum_trajectory(file, tum);
}

int run_pipeline(const PipelineArgs& a) {
  AppConfig base;
  base.simulation = sim::scenario_config(a.scenario, sim::default_real_mesh_dir());
  AppConfig cfg = a.common.load(base);
  if (a.stones > 0) cfg.simulation.site.stones.count = a.stones;
  if (a.no_drone) cfg.simulation.with_drone = false;
  cfg.mapping.validate();
  const std::filesystem::path out(a.out);
  const std::filesystem::path run_dir = out / "run";
  Timings t;
  Stopwatch sw;

  spdlog::info("pipeline [1/5] simulating scenario {} (seed {}, {} s of cabin swinging) -> {}", a.scenario, a.seed,
               a.duration, run_dir.string());
  std::size_t last_decile = 11;
  const sim::SimulationSummary s = sim::simulate_run(
      a.scenario, cfg.simulation, a.seed, a.duration, run_dir, /*overwrite=*/true,
      [&](const std::string& stage, std::size_t done, std::size_t total) {
        const std::size_t decile = total == 0 ? 10 : 10 * done / total;
        if (stage == "lidar" && decile != last_decile) {
          spdlog::info("pipeline       LiDAR sweeps {}/{}", done, total);
          last_decile = decile;
        } else if (stage == "drone" && done == 0) {
          spdlog::info("pipeline       drone survey");
        }
      });
  t.add("simulate", sw.lap_ms());

  const io::RunDirectory rd = io::open_run_directory(run_dir);
  spdlog::info("pipeline [2/5] mapping {} sweeps online (Sec. 4.2)", rd.scans.size());
  std::size_t last = 0;
  const MapRunResult mapped = map_run(rd, cfg.mapping, [&last](std::size_t done, std::size_t total) {
    if (done == total || done >= last + 50) {
      spdlog::info("pipeline       {}/{} scan pairs", done, total);
      last = done;
    }
  });
  t.add("mapping", sw.lap_ms());
  const PointCloud& map = mapped.map;
  const std::vector<StampedPose> truth_poses = io::read_stamped_poses(rd.truth_dir() / "cabin_poses.tum");
  const eval::TrajectoryError ate_raw = eval::trajectory_error(mapped.raw_trajectory, truth_poses);
  const eval::TrajectoryError ate_mapped = eval::trajectory_error(mapped.trajectory, truth_poses);
  spdlog::info("pipeline       ATE raw state estimate {:.2f} cm -> mapped {:.2f} cm ({} nodes, {} map points)",
               100 * ate_raw.ate_rmse, 100 * ate_mapped.ate_rmse, mapped.stats.nodes, map.size());

  // 3. Registration of the drone cloud into the map (when the run has a drone survey).
  const eval::RegistrationTruth reg_truth = eval::load_registration_truth(rd, int(cfg.simulation.site.stones.count));
  sw.lap_ms();
  nlohmann::json registration = "skipped (no drone survey)";
  PointCloud merged = map;
  if (!rd.drone_cloud.empty()) {
    spdlog::info("pipeline [3/5] registering the drone cloud into the map (scale Sec. 4.1, segments Sec. 4.4)");
    const eval::MetricDrone drone = eval::load_metric_drone(rd, cfg.scale);
    t.add("scale_recovery", sw.lap_ms());
    const GlobalRegistrationResult r = register_global(drone.cloud, map, cfg.segmentation, cfg.registration);
    t.add("registration", sw.lap_ms());
    r.timings.log("pipeline   registration:");
    const eval::ScoredRegistration scored = eval::score_registration(r, drone, reg_truth);
    registration = scored.to_json();
    registration["scale"] = drone.scale.T_metric_sfm.scale;
    registration["scale_error"] = drone.scale_error;
    registration["rmse_m"] = r.rmse;
    registration["overlap"] = r.overlap;
    registration["matched_segments"] = r.matched_segments.size();
    nlohmann::json rt;
    for (const auto& [name, ms] : r.timings.stages) rt[name] = ms;
    registration["timings_ms"] = rt;
    if (!r.success) registration["reason"] = r.reason;
    if (r.success) {
      const eval::MapRelativeError rel =
          eval::error_against_map(r.T_target_source, drone, reg_truth, eval::ObjectSurfaceTruth(reg_truth.snapshot), map);
      registration["error_vs_map"] = {{"rotation_deg", rel.error.rotation_deg},
                                      {"translation_m", rel.error.translation_m},
                                      {"map_offset_at_stones_m", rel.map_offset_m}};
      merged = r.merged_map;
      PointCloud aligned = r.source_voxelised;
      transform_cloud(aligned, r.T_target_source);
      io::write_ply(out / "drone_aligned.ply", aligned);
      spdlog::info("pipeline       drone cloud registered: {:.3f} deg, {:.1f} mm from the truth ({:.3f} deg, {:.1f} mm "
                   "from the map, whose stones sit {:.1f} mm off), rmse {:.1f} mm, {} segments matched, {}/{} "
                   "stones single objects",
                   scored.error.rotation_deg, 1000 * scored.error.translation_m, rel.error.rotation_deg,
                   1000 * rel.error.translation_m, 1000 * rel.map_offset_m, 1000 * r.rmse,
                   r.matched_segments.size(), scored.single_stones, reg_truth.num_stones);
    } else {
      spdlog::warn("pipeline       registration refused: {} (the map is segmented alone)", r.reason);
    }
    t.add("write_registration", sw.lap_ms());
  }

  spdlog::info("pipeline [4/5] segmenting the {}-point {} (Sec. 4.3)", merged.size(),
               merged.size() == map.size() ? "map" : "merged map");
  const SegmentationResult seg = segment(merged, cfg.segmentation);
  t.add("segmentation", sw.lap_ms());
  seg.timings.log("pipeline   segmentation:");

  spdlog::info("pipeline [5/5] scoring against ground truth and writing {}", a.out);
  const SegmentationScore score = eval::score_against_truth(merged, seg.labels, reg_truth);
  write_segmentation(out, merged, seg, seg.labels);
  io::write_ply(out / "map.ply", map);
  if (merged.size() != map.size()) io::write_ply(out / "merged_map.ply", merged);
  write_trajectory(out / "trajectory.txt", mapped.trajectory);
  std::vector<Rgb> colors(merged.size());
  for (std::size_t i = 0; i < merged.size(); ++i) colors[i] = label_color(seg.labels[i]);
  write_png(out / "top_view.png", render_top_view(merged, colors, kTopViewPixelsPerMetre));
  t.add("write", sw.lap_ms());

  nlohmann::json timings;
  for (const auto& [name, ms] : t.stages) timings[name] = ms;
  nlohmann::json mapping_timings;
  for (const auto& [name, ms] : mapped.timings.stages) mapping_timings[name] = ms;
  nlohmann::json summary{{"scenario", a.scenario},
                         {"seed", a.seed},
                         {"duration_s", a.duration},
                         {"stones", reg_truth.num_stones},
                         {"sweeps", s.sweeps},
                         {"lidar_points", s.points},
                         {"drone_points", s.drone_points},
                         {"nodes", mapped.stats.nodes},
                         {"map_points", map.size()},
                         {"mapping_pairs_per_second",
                          mapped.seconds > 0 ? double(mapped.stats.pairs) / mapped.seconds : 0.0},
                         {"ate_raw", ate_json(ate_raw)},
                         {"ate_mapped", ate_json(ate_mapped)},
                         {"segments", seg.num_objects()},
                         {"score", score.to_json()},
                         {"registration", registration},
                         {"segmented_points", merged.size()},
                         {"timings_ms", timings},
                         {"mapping_timings_ms", mapping_timings},
                         {"out", a.out}};
  std::ofstream(out / "summary.json") << summary.dump(2) << "\n";
  std::cout << summary.dump(2) << std::endl;
  spdlog::info("pipeline: {} of {} stones found as single complete segments, {} terrain segments; picture: {}",
               score.found(), reg_truth.num_stones, score.terrain_segments, (out / "top_view.png").string());
  return kExitOk;
}

}  // namespace

void add_pipeline_command(CLI::App& app, std::function<int()>& run) {
  auto args = std::make_shared<PipelineArgs>();
  auto* cmd = app.add_subcommand("pipeline",
                                 "The perception chain on the built-in simulated site through files: simulate, map (Sec. 4.2), register the "
                                 "drone cloud (Sec. 4.1, 4.4), segment (Sec. 4.3), score against ground truth");
  std::string names;
  for (const auto& n : sim::scenario_names()) names.append(names.empty() ? "" : ", ").append(n);
  cmd->add_option("--out", args->out, "output directory (the run directory goes to OUT/run)")->capture_default_str();
  cmd->add_option("--scenario", args->scenario, "scenario: " + names)->capture_default_str();
  cmd->add_option("--seed", args->seed, "scenario seed (same seed, same site and sensor data)")->capture_default_str();
  cmd->add_option("--duration", args->duration, "simulated time of cabin swinging [s]")
      ->capture_default_str()
      ->check(CLI::Range(2.0, 600.0));
  cmd->add_option("--stones", args->stones, "number of stones (default: the scenario's)")->check(CLI::Range(1, 30));
  cmd->add_flag("--no-drone", args->no_drone, "skip the drone survey");
  args->common.add_to(*cmd);
  cmd->callback([&run, args] { run = [args] { return run_pipeline(*args); }; });
}

}  // namespace cairn::app
