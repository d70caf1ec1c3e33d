// cairn map RUN_DIR|--bag RUN.bag --out MAP.ply [--trajectory OUT.txt]: LiDAR mapping (Sec. 4.2) of
// a run directory or a rosbag. Progress and a per-stage timing summary on stderr, one JSON summary
// on stdout.
#include <spdlog/spdlog.h>

#include <filesystem>
#include <iostream>
#include <optional>

#include "app_config.hpp"
#include "bag_support.hpp"
#include "cairn/core/error.hpp"
#include "cairn/core/io/io.hpp"
#include "cairn/core/io/run_dir.hpp"
#include "cairn/core/io/trajectory.hpp"
#include "cairn/eval/map_scoring.hpp"
#include "cairn/mapping/mapper.hpp"
#include "commands.hpp"

namespace cairn::app {
namespace {

void write_trajectory(const std::filesystem::path& file, const std::vector<StampedPose>& poses) {
  std::vector<io::TrajectoryPose> tum;
  for (const StampedPose& p : poses)
    tum.push_back({.timestamp = p.time, .position = p.pose.translation(),
                   .orientation = Eigen::Quaterniond(p.pose.linear()).normalized()});
  io::write_tum_trajectory(file, tum);
}

nlohmann::json error_json(const eval::TrajectoryError& e) {
  return {{"ate_rmse_m", e.ate_rmse}, {"ate_rmse_without_mean_m", e.ate_rmse_without_mean}, {"mean_error_m", {e.mean_error.x(), e.mean_error.y(), e.mean_error.z()}},
          {"ate_max_m", e.ate_max}, {"rotation_rmse_deg", e.rotation_rmse_deg},
          {"poses", e.num}};
}

}  // namespace

void add_map_command(CLI::App& app, std::function<int()>& run) {
  struct Args {
    CommonOptions common;
    std::string run_dir, bag, out, trajectory;
  };
  auto args = std::make_shared<Args>();
  auto* cmd = app.add_subcommand("map", "LiDAR mapping of a run directory or a rosbag (Sec. 4.2): map cloud + trajectory");
  auto* dir_opt = cmd->add_option("RUN_DIR", args->run_dir, "run directory written by `cairn simulate`");
  auto* bag_opt = cmd->add_option("--bag", args->bag, "map a rosbag instead (topics: bag.* settings, docs/ros.md)");
  dir_opt->excludes(bag_opt);
  bag_opt->excludes(dir_opt);
  cmd->add_option("--out", args->out, "output map cloud (.ply, .pcd, .xyz)")->required();
  cmd->add_option("--trajectory", args->trajectory, "optimised cabin trajectory T_world_cabin (TUM format)");
  args->common.add_to(*cmd);
  cmd->callback([&run, args] {
    run = [args] {
      const AppConfig cfg = args->common.load();
      cfg.mapping.validate();
      if (args->run_dir.empty() == args->bag.empty()) throw InputError("map: give RUN_DIR or --bag RUN.bag");
      std::size_t last = 0;
      const MappingProgress progress = [&last](std::size_t done, std::size_t total) {
        if (done == total || done >= last + 50) {
          spdlog::info("map: {}/{} scan pairs", done, total);
          last = done;
        }
      };
      std::optional<io::RunDirectory> rd;
      MapRunResult r;
      if (!args->bag.empty()) {
        spdlog::info("map: rosbag {}", args->bag);
        r = map_from_bag(args->bag, cfg.mapping, progress, cfg.bag);
      } else {
        rd = io::open_run_directory(args->run_dir);
        spdlog::info("map: {} ({} sweeps, {:.1f} s)", args->run_dir, rd->scans.size(), rd->duration);
        r = map_run(*rd, cfg.mapping, progress);
      }
      r.timings.log("map:");
      io::save_cloud(args->out, r.map);
      if (!args->trajectory.empty()) write_trajectory(args->trajectory, r.trajectory);
      nlohmann::json timings;
      for (const auto& [stage, ms] : r.timings.stages) timings[stage] = ms;
      nlohmann::json j{{"run", args->bag.empty() ? args->run_dir : args->bag},
                       {"out", args->out},
                       {"sweeps", r.stats.sweeps},
                       {"pairs", r.stats.pairs},
                       {"nodes", r.stats.nodes},
                       {"scan_matching_edges", r.stats.scan_edges},
                       {"loop_closure_edges", r.stats.loop_edges},
                       {"submaps", r.stats.submaps},
                       {"icp_rejected", r.stats.icp_rejected},
                       {"empty_sweeps", r.stats.empty_sweeps},
                       {"time_gaps", r.stats.time_gaps},
                       {"points_in", r.stats.points_in},
                       {"points_self_filtered", r.stats.points_self_filtered},
                       {"map_points", r.map.size()},
                       {"seconds", r.seconds},
                       {"pairs_per_second", r.seconds > 0 ? double(r.stats.pairs) / r.seconds : 0.0},
                       {"timings_ms", timings}};
      const auto truth_file = rd ? rd->truth_dir() / "cabin_poses.tum" : std::filesystem::path{};
      if (rd && std::filesystem::exists(truth_file)) {
        const std::vector<StampedPose> truth = io::read_stamped_poses(truth_file);
        j["ate_raw"] = error_json(eval::trajectory_error(r.raw_trajectory, truth));
        j["ate_mapped"] = error_json(eval::trajectory_error(r.trajectory, truth));
      }
      std::cout << j.dump(2) << std::endl;
      return kExitOk;
    };
  });
}

}  // namespace cairn::app
