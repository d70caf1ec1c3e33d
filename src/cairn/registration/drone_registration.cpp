#include "cairn/registration/drone_registration.hpp"

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
  out.result = register_global(source, target, segmentation, registration);
  out.T_target_source = Similarity::from_isometry(out.result.T_target_source) * T_metric_sfm;
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
  return j;
}

nlohmann::json error_json(const DroneRegistration& r, const Similarity& truth, const Vec3d& at) {
  const RegistrationError e = registration_error(r.T_target_source, truth, at);
  return {{"rotation_deg", e.rotation_deg}, {"translation_m", e.translation_m}, {"scale_ratio", e.scale_ratio}};
}

}  // namespace cairn
