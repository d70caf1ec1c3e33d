#pragma once
// Planes: least-squares fit and seeded RANSAC (as PCL's SACSegmentation with SACMODEL_PLANE and
// optimised coefficients: the best hypothesis is refit to its inliers, inliers re-selected).
#include <cstdint>
#include <optional>
#include <random>
#include <span>
#include <vector>

#include "cairn/core/point_cloud.hpp"

namespace cairn {

/// n·p + d = 0 with |n| = 1.
struct Plane {
  Vec3f normal = Vec3f::UnitZ();
  float d = 0.0f;
  [[nodiscard]] float signed_distance(const Vec3f& p) const { return normal.dot(p) + d; }
  [[nodiscard]] Eigen::Vector4f coefficients() const { return {normal.x(), normal.y(), normal.z(), d}; }
};

struct RansacPlaneConfig {
  double distance = 0.10;      // inlier threshold [m] (Table 3 d_plane for the ground)
  int max_iterations = 1000;   // upper bound; adaptive termination usually stops earlier
  double probability = 0.99;   // desired probability of drawing one all-inlier sample
  /// If set, hypotheses whose normal deviates more than max_tilt from this axis are rejected.
  std::optional<Vec3f> axis;
  double max_tilt = 0.0;       // [rad]
  bool refine = true;          // least-squares refit on the inliers of the best hypothesis
  /// Hypotheses of larger inputs are scored on a fixed random subset of this many points (the
  /// final inlier set always covers all points).
  std::size_t max_scored_points = 8192;
};

struct PlaneFit {
  bool found = false;
  Plane plane;
  std::vector<std::uint32_t> inliers;  // indices into the point span, ascending
  int iterations = 0;
};

/// Least-squares plane through the given points (PCA); needs >= 3 non-collinear points.
[[nodiscard]] std::optional<Plane> fit_plane(std::span<const Vec3f> points,
                                             std::span<const std::uint32_t> indices);

/// RANSAC over `indices` of `points` (all points when indices is empty). Deterministic for a
/// given generator state.
[[nodiscard]] PlaneFit fit_plane_ransac(std::span<const Vec3f> points,
                                        std::span<const std::uint32_t> indices,
                                        const RansacPlaneConfig& config, std::mt19937_64& rng);

}  // namespace cairn
