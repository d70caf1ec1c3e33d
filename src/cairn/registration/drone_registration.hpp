#pragma once
// Registering a drone cloud into the LiDAR map as the CLI (`cairn register`) and the ROS node
// (cairn_registration) both do it: the metric scale recovered from the camera positions when the
// SfM model and the metric trajectory are given (Sec. 4.1), then segment-based global
// registration (Sec. 4.4); one JSON contract (docs/registration.md) for both.
#include <Eigen/Core>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>

#include "cairn/core/transform.hpp"
#include "cairn/registration/global_registration.hpp"
#include "cairn/registration/scale_recovery.hpp"

namespace cairn {

struct DroneRegistration {
  std::optional<ScaleRecoveryResult> scale;  // when an SfM model and a metric trajectory were given
  double scale_ms = 0.0;
  /// 7-DoF (scale_check.estimate): the scale the source was multiplied by after a refusal for its
  /// scale (1: rigid), and the registrations run.
  double estimated_scale = 1.0;
  int passes = 1;
  GlobalRegistrationResult result;
  /// The ORIGINAL source (SfM frame with scale recovery, else metric) into the target: a
  /// similarity when the scale was recovered.
  Similarity T_target_source;
};

/// Scale recovery from `sfm` (COLMAP text model) and `metric` (TUM trajectory) when both are
/// non-empty (one without the other is an InputError), then register_global(source, target).
/// With registration.scale_check.estimate (7-DoF), while the fitted scale is farther than
/// estimate_tolerance from 1 (on success or a refusal for the scale) the source is rescaled about
/// its centroid by it and registered again (at most scale_check.estimate_passes registrations).
[[nodiscard]] DroneRegistration register_drone(PointCloud source, const PointCloud& target,
                                               const std::filesystem::path& sfm, const std::filesystem::path& metric,
                                               const SegmentationConfig& segmentation,
                                               const GlobalRegistrationConfig& registration, const ScaleRecoveryConfig& scale);

/// The `cairn register` contract: success, T_target_source, rmse, overlap, matched_segments,
/// candidates, centroid_candidates, timings_ms, counts, reason (on failure), candidate_reports,
/// scale (with scale recovery), scale_check {scale, observable, segments, extent_m, estimated_scale,
/// passes}.
[[nodiscard]] nlohmann::json to_json(const DroneRegistration& r);

/// `error` {rotation_deg, translation_m, scale_ratio} of `r` against the true T_target_source,
/// evaluated at `at` (target frame; where the matched segments are).
[[nodiscard]] nlohmann::json error_json(const DroneRegistration& r, const Similarity& truth, const Vec3d& at);

}  // namespace cairn
