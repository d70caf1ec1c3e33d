// cairn register SOURCE TARGET [--config FILE] [--out DIR]: segment-based global registration
// (Sec. 4.4) of SOURCE (e.g. the drone cloud) to TARGET (e.g. the LiDAR map). One JSON object on
// stdout; exit 0 on success, 3 when no transform passes the acceptance test, 2 on bad input.
#include <spdlog/spdlog.h>

#include <fstream>
#include <iostream>

#include "app_config.hpp"
#include "cairn/core/io/io.hpp"
#include "cairn/registration/drone_registration.hpp"
#include "commands.hpp"

namespace cairn::app {
namespace {

struct RegisterArgs {
  CommonOptions common;
  std::string source, target, out, sfm, metric, truth;
  bool gravity_aligned = false, estimate_scale = false;
};

int run_register(const RegisterArgs& a) {
  AppConfig cfg = a.common.load();
  if (a.gravity_aligned) cfg.registration.gravity_aligned = true;
  if (a.estimate_scale) cfg.registration.scale_check.estimate = true;
  cfg.registration.validate();
  if (a.sfm.empty() != a.metric.empty()) throw InputError("register: --sfm and --metric go together");
  PointCloud source = io::load_cloud(a.source);
  const PointCloud target = io::load_cloud(a.target);
  spdlog::info("register: source {} ({} points) -> target {} ({} points)", a.source, source.size(), a.target,
               target.size());
  const DroneRegistration d = register_drone(std::move(source), target, a.sfm, a.metric, cfg.segmentation,
                                             cfg.registration, cfg.scale);
  const GlobalRegistrationResult& r = d.result;
  if (d.passes > 1)
    spdlog::info("register: scale estimated {:.4f} in {} passes", d.estimated_scale, d.passes);
  if (d.scale)
    spdlog::info("register: scale recovered from {} cameras: {:.5f} (residual RMS {:.3f} m)", d.scale->cameras,
                 d.scale->T_metric_sfm.scale, d.scale->rms);
  nlohmann::json j = to_json(d);
  if (!a.truth.empty()) {
    std::ifstream in(a.truth);
    if (!in) throw InputError("register: cannot read --truth file '" + a.truth + "'");
    nlohmann::json tj;
    try {
      tj = nlohmann::json::parse(in);
    } catch (const nlohmann::json::exception& e) {
      throw InputError("register: --truth '" + a.truth + "' is not JSON: " + e.what());
    }
    // A bare 4x4, {"T_target_source": ...}, or a simulator run's truth/drone.json (T_map_drone).
    const nlohmann::json& m = tj.contains("T_target_source") ? tj["T_target_source"]
                              : tj.contains("T_map_drone")   ? tj["T_map_drone"]
                                                             : tj;
    // Errors at the target's centre (where the matched segments are), not at the source's origin.
    const Vec3d at = target.origin + centroid(target.points).cast<double>();
    j["error"] = error_json(d, Similarity::from_matrix(matrix_from_json(m)), at);
  }
  if (!a.out.empty()) {
    const std::filesystem::path out(a.out);
    // Files of an earlier run in DIR must not stand beside this run's result.
    for (const char* stale : {"source_aligned.ply", "merged.ply", "merged_segments.json", "segments"})
      std::filesystem::remove_all(out / stale);
    std::filesystem::create_directories(out / "segments");
    if (r.success) {
      PointCloud aligned = r.source_voxelised;
      transform_cloud(aligned, r.T_target_source);
      io::write_ply(out / "source_aligned.ply", aligned);
      io::write_ply(out / "merged.ply", r.merged_map);
      nlohmann::json segs = nlohmann::json::array();
      for (std::size_t k = 0; k < r.merged_segments.size(); ++k) {
        char name[48];
        std::snprintf(name, sizeof name, "segment_%03zu.ply", k);
        io::write_ply(out / "segments" / name, r.merged_segments[k]);
        const Vec3f c = centroid(r.merged_segments[k].points);
        const Vec3d cw = r.merged_segments[k].origin + c.cast<double>();
        segs.push_back({{"id", k}, {"source_segment", r.matched_segments[k].first},
                        {"target_segment", r.matched_segments[k].second}, {"num_points", r.merged_segments[k].size()},
                        {"centroid", {cw.x(), cw.y(), cw.z()}}, {"file", std::string("segments/") + name}});
      }
      std::ofstream(out / "merged_segments.json") << segs.dump(2) << "\n";
    }
    std::ofstream result(out / "result.json");
    result << j.dump(2) << "\n";
    if (!result) throw InputError("register: cannot write " + (out / "result.json").string());
  }
  r.timings.log("register:");
  spdlog::info("register: {} ({} candidates, {} matched segments, rmse {:.4f} m, overlap {:.2f})",
               r.success ? "success" : "no transform passes the acceptance test: " + r.reason, r.candidates,
               r.matched_segments.size(), r.rmse, r.overlap);
  std::cout << j.dump(2) << std::endl;
  return r.success ? kExitOk : kExitNoResult;
}

}  // namespace

void add_register_command(CLI::App& app, std::function<int()>& run) {
  auto args = std::make_shared<RegisterArgs>();
  auto* cmd = app.add_subcommand("register",
                                 "Segment-based global registration (Sec. 4.4) of SOURCE (e.g. drone cloud) to TARGET "
                                 "(e.g. LiDAR map); exit 0 success, 3 no acceptable transform, 2 bad input");
  cmd->add_option("SOURCE", args->source, "source cloud (metric, or SfM with --sfm/--metric)")->required();
  cmd->add_option("TARGET", args->target, "target cloud (the map)")->required();
  cmd->add_option("--out", args->out, "write the aligned source, the merged map and the merged segments here");
  cmd->add_option("--sfm", args->sfm, "COLMAP text model of SOURCE: recover its metric scale first (Sec. 4.1)");
  cmd->add_option("--metric", args->metric, "metric camera trajectory (TUM) for --sfm");
  cmd->add_flag("--gravity-aligned", args->gravity_aligned, "SOURCE's z axis is up: 4-DoF registration");
  cmd->add_flag("--estimate-scale", args->estimate_scale,
                "7-DoF: a SOURCE whose scale is off is rescaled and registered again, the scale reported "
                "(without it such a SOURCE is refused, exit 3)");
  cmd->add_option("--truth", args->truth, "JSON with the true T_target_source (4x4, or a run's truth/drone.json): report the errors");
  args->common.add_to(*cmd);
  cmd->callback([&run, args] { run = [args] { return run_register(*args); }; });
}

}  // namespace cairn::app
