#include "cairn/registration/drone_registration.hpp"

#include <cmath>
#include <optional>

#include "cairn/core/error.hpp"
#include "cairn/core/io/colmap.hpp"
#include "cairn/core/io/trajectory.hpp"
#include "cairn/core/log.hpp"

namespace cairn {

DroneRegistration register_drone(PointCloud source, const PointCloud& target, const std::filesystem::path& sfm,
                                 const std::filesystem::path& metric, const SegmentationConfig& segmentation,
                                 const GlobalRegistrationConfig& registration, const ScaleRecoveryConfig& scale) {
  if (sfm.empty() != metric.empty())
    throw InputError("register: the SfM model and the metric trajectory go together (scale recovery, Sec. 4.1)");
  DroneRegistration out;
  Similarity T_metric_sfm;
  if (!sfm.empty()) {
    Stopwatch sw;
    out.scale = recover_scale(io::read_colmap_text(sfm), io::read_tum_trajectory(metric), scale);
    T_metric_sfm = out.scale->T_metric_sfm;
    transform_cloud(source, T_metric_sfm);
    out.scale_ms = sw.elapsed_ms();
  }
  // 7-DoF (scale_check.estimate): rescale by the fitted scale and register again while it is off.
  Similarity T_scaled = T_metric_sfm;
  std::optional<DroneRegistration> last_success;  // a later pass that fails does not undo it
  for (;; ++out.passes) {
    out.result = register_global(source, target, segmentation, registration);
    out.T_target_source = Similarity::from_isometry(out.result.T_target_source) * T_scaled;
    if (!out.result.success && last_success) return std::move(*last_success);
    if (out.result.success) last_success = out;
    const ScaleFit& fit = out.result.scale_fit;
    const ScaleCheckConfig& check = registration.scale_check;
    const bool scale_refused = !out.result.success && fit.observable && std::abs(fit.scale - 1.0) > check.max_scale_error;
    const bool off = fit.observable && std::abs(fit.scale - 1.0) > check.estimate_tolerance;
    if (!check.estimate || !(out.result.success || scale_refused) || !off || out.passes >= check.estimate_passes) break;
    // The fitted scale holds in the target frame; about the source's centroid it is the same.
    const Vec3d c = source.origin + centroid(source.points).cast<double>();
    Similarity S;
    S.scale = fit.scale;
    S.translation = c - fit.scale * c;
    transform_cloud(source, S);
    T_scaled = S * T_scaled;
    out.estimated_scale *= fit.scale;
  }
  return out;
}

namespace {

nlohmann::json timings_json(const Timings& t, double scale_ms) {
  nlohmann::json j;
  for (const auto& [stage, ms] : t.stages) j[stage] = ms;
  if (scale_ms > 0) j["scale_recovery"] = scale_ms;
  j["total"] = t.total() + scale_ms;
  return j;
}

}  // namespace

nlohmann::json to_json(const DroneRegistration& d) {
  const GlobalRegistrationResult& r = d.result;
  nlohmann::json j;
  if (d.scale)
    j["scale"] = {{"scale", d.scale->T_metric_sfm.scale},
                  {"cameras", d.scale->cameras},
                  {"inliers", d.scale->inliers.size()},
                  {"rms_m", d.scale->rms}};
  j["success"] = r.success;
  j["T_target_source"] = matrix_to_json(d.T_target_source.matrix());
  j["rmse"] = r.rmse;
  j["overlap"] = r.overlap;
  j["matched_segments"] = r.matched_segments.size();
  j["candidates"] = r.candidates;
  j["centroid_candidates"] = r.centroid_candidates;
  j["timings_ms"] = timings_json(r.timings, d.scale_ms);
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
  j["scale_check"] = {{"scale", r.scale_fit.scale},          {"observable", r.scale_fit.observable},
                      {"segments", r.scale_fit.segments},    {"extent_m", r.scale_fit.extent},
                      {"estimated_scale", d.estimated_scale}, {"passes", d.passes}};
  return j;
}

nlohmann::json error_json(const DroneRegistration& r, const Similarity& truth, const Vec3d& at) {
  const RegistrationError e = registration_error(r.T_target_source, truth, at);
  return {{"rotation_deg", e.rotation_deg}, {"translation_m", e.translation_m}, {"scale_ratio", e.scale_ratio}};
}

}  // namespace cairn
