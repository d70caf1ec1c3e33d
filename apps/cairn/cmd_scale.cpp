// cairn scale --sfm MODEL_DIR --metric TRAJ [--cloud IN --out OUT]: metric scale of a drone SfM
// reconstruction (Sec. 4.1) from the similarity between its camera centres and a metric
// visual-inertial trajectory; applies it to the dense cloud.
#include <spdlog/spdlog.h>

#include <iostream>

#include "app_config.hpp"
#include "cairn/core/io/io.hpp"
#include "cairn/registration/scale_recovery.hpp"
#include "commands.hpp"

namespace cairn::app {

void add_scale_command(CLI::App& app, std::function<int()>& run) {
  struct Args {
    CommonOptions common;
    std::string sfm, metric, cloud, out;
  };
  auto args = std::make_shared<Args>();
  auto* cmd = app.add_subcommand(
      "scale", "Metric scale of a drone SfM model (Sec. 4.1): similarity from its camera centres to a metric trajectory");
  cmd->add_option("--sfm", args->sfm, "COLMAP text model directory (cameras.txt, images.txt, points3D.txt)")->required();
  cmd->add_option("--metric", args->metric, "metric camera trajectory (TUM), one pose per image in capture order")
      ->required();
  cmd->add_option("--cloud", args->cloud, "dense cloud in the SfM frame to bring into the metric frame");
  cmd->add_option("--out", args->out, "output cloud (metric frame); needs --cloud");
  args->common.add_to(*cmd);
  cmd->callback([&run, args] {
    run = [args] {
      if (args->cloud.empty() != args->out.empty()) throw InputError("scale: --cloud and --out go together");
      const AppConfig cfg = args->common.load();
      Stopwatch sw;
      const io::ColmapModel model = io::read_colmap_text(args->sfm);
      const std::vector<io::TrajectoryPose> metric = io::read_tum_trajectory(args->metric);
      const ScaleRecoveryResult r = recover_scale(model, metric, cfg.scale);
      spdlog::info("scale: {} cameras, {} inliers, scale {:.6f}, residual RMS {:.3f} m (max {:.3f} m)", r.cameras,
                   r.inliers.size(), r.T_metric_sfm.scale, r.rms, r.max_residual);
      nlohmann::json j{{"scale", r.T_metric_sfm.scale},
                       {"T_metric_sfm", matrix_to_json(r.T_metric_sfm.matrix())},
                       {"cameras", r.cameras},
                       {"inliers", r.inliers.size()},
                       {"rms_m", r.rms},
                       {"max_residual_m", r.max_residual}};
      if (!args->cloud.empty()) {
        PointCloud cloud = io::load_cloud(args->cloud);
        transform_cloud(cloud, r.T_metric_sfm);
        io::save_cloud(args->out, cloud);
        j["points"] = cloud.size();
        j["out"] = args->out;
      }
      j["time_ms"] = sw.lap_ms();
      std::cout << j.dump(2) << std::endl;
      return kExitOk;
    };
  });
}

}  // namespace cairn::app
