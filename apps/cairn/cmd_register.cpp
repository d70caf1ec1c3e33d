// cairn register SOURCE TARGET [--config FILE] [--out DIR]: segment-based global registration
// (Sec. 4.4) of SOURCE (e.g. the drone cloud) to TARGET (e.g. the LiDAR map). One JSON object on
// stdout; exit 0 on success, 3 when no transform passes the acceptance test, 2 on bad input.
#include <spdlog/spdlog.h>

#include <fstream>
#include <iostream>

#include "app_config.hpp"
#include "cairn/core/io/io.hpp"
#include "cairn/registration/global_registration.hpp"
#include "cairn/registration/scale_recovery.hpp"
#include "commands.hpp"

namespace cairn::app {
namespace {

struct RegisterArgs {
  CommonOptions common;
  std::string source, target, out, sfm, metric, truth;
  bool gravity_aligned = false;
};

nlohmann::json timings_json(const Timings& t, double scale_ms) {
  nlohmann::json j;
  for (const auto& [stage, ms] : t.stages) j[stage] = ms;
  if (scale_ms > 0) j["scale_recovery"] = scale_ms;
  j["total"] = t.total() + scale_ms;
  return j;
}

int run_register(const RegisterArgs& a) {
  AppConfig cfg = a.common.load();
  if (a.gravity_aligned) cfg.registration.gravity_aligned = true;
  cfg.registration.validate();
  if (a.sfm.empty() != a.metric.empty()) throw InputError("register: --sfm and --metric go together");
  PointCloud source = io::load_cloud(a.source);
  const PointCloud target = io::load_cloud(a.target);
  spdlog::info("register: source {} ({} points) -> target {} ({} points)", a.source, source.size(), a.target,
               target.size());
  nlohmann::json j;
  Similarity T_metric_sfm;
  double scale_ms = 0.0;
  if (!a.sfm.empty()) {
    Stopwatch sw;
    const ScaleRecoveryResult s =
        recover_scale(io::read_colmap_text(a.sfm), io::read_tum_trajectory(a.metric), cfg.scale);
    T_metric_sfm = s.T_metric_sfm;
    transform_cloud(source, T_metric_sfm);
    scale_ms = sw.lap_ms();
    spdlog::info("register: scale recovered from {} cameras: {:.5f} (residual RMS {:.3f} m)", s.cameras,
                 s.T_metric_sfm.scale, s.rms);
    j["scale"] = {{"scale", s.T_metric_sfm.scale}, {"cameras", s.cameras}, {"inliers", s.inliers.size()}, {"rms_m", s.rms}};
  }
  const GlobalRegistrationResult r = register_global(source, target, cfg.segmentation, cfg.registration);
  // With scale recovery, the reported transform maps the ORIGINAL source (SfM frame) into the
  // target: a similarity.
  const Eigen::Matrix4d T = (Similarity::from_isometry(r.T_target_source) * T_metric_sfm).matrix();
  j["success"] = r.success;
  j["T_target_source"] = matrix_to_json(T);
  j["rmse"] = r.rmse;
  j["overlap"] = r.overlap;
  j["matched_segments"] = r.matched_segments.size();
  j["candidates"] = r.candidates;
  j["centroid_candidates"] = r.centroid_candidates;
  j["timings_ms"] = timings_json(r.timings, scale_ms);
  j["counts"] = {{"source_points", r.source_points},       {"target_points", r.target_points},
                 {"source_segments", r.source_segments},   {"target_segments", r.target_segments},
                 {"source_keypoints", r.source_keypoints}, {"target_keypoints", r.target_keypoints},
                 {"correspondences", r.correspondences}};
  if (!r.success) j["reason"] = r.reason;
  nlohmann::json reports = nlohmann::json::array();
  for (const CandidateReport& c : r.reports)
    reports.push_back({{"origin", c.origin}, {"votes", c.votes}, {"centroid_inliers", c.centroid_inliers},
                       {"max_centroid_distance_m", c.max_centroid_distance}, {"refined", c.refined},
                       {"rmse_m", c.rmse}, {"overlap", c.overlap}, {"accepted", c.accepted}});
  j["candidate_reports"] = reports;
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
    const Similarity truth = Similarity::from_matrix(matrix_from_json(m));
    // Errors at the target's centre (where the matched segments are), not at the source's origin.
    const Vec3d at = target.origin + centroid(target.points).cast<double>();
    const RegistrationError e = registration_error(Similarity::from_matrix(T), truth, at);
    j["error"] = {{"rotation_deg", e.rotation_deg}, {"translation_m", e.translation_m}, {"scale_ratio", e.scale_ratio}};
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
  cmd->add_option("--truth", args->truth, "JSON with the true T_target_source (4x4, or a run's truth/drone.json): report the errors");
  args->common.add_to(*cmd);
  cmd->callback([&run, args] { run = [args] { return run_register(*args); }; });
}

}  // namespace cairn::app
