#include "cairn/core/plane.hpp"

#include <cmath>
#include <numeric>

#include "cairn/core/normals.hpp"

namespace cairn {
namespace {

constexpr float kMinSampleArea = 1e-12f;  // |cross|^2 below this: collinear sample, redrawn

std::optional<Plane> plane_from_three(const Vec3f& a, const Vec3f& b, const Vec3f& c) {
  const Vec3f n = (b - a).cross(c - a);
  if (n.squaredNorm() < kMinSampleArea) return std::nullopt;
  Plane p;
  p.normal = n.normalized();
  p.d = -p.normal.dot(a);
  return p;
}

std::size_t count_inliers(std::span<const Vec3f> pts, std::span<const std::uint32_t> idx, const Plane& pl,
                          float thr) {
  std::size_t n = 0;
  for (auto i : idx) n += std::abs(pl.signed_distance(pts[i])) <= thr;
  return n;
}

std::vector<std::uint32_t> select_inliers(std::span<const Vec3f> pts,
                                          std::span<const std::uint32_t> idx, const Plane& pl,
                                          float thr) {
  std::vector<std::uint32_t> in;
  for (auto i : idx)
    if (std::abs(pl.signed_distance(pts[i])) <= thr) in.push_back(i);
  return in;
}

}  // namespace

std::optional<Plane> fit_plane(std::span<const Vec3f> points, std::span<const std::uint32_t> indices) {
  if (indices.size() < 3) return std::nullopt;
  const PcaFrame f = pca(points, indices);
  constexpr float kCollinear = 1e-6f;  // second eigenvalue relative to the largest
  if (f.eigenvalues[1] <= kCollinear * f.eigenvalues[2]) return std::nullopt;
  Plane p;
  p.normal = f.eigenvectors.col(0).normalized();
  p.d = -p.normal.dot(f.mean);
  return p;
}

PlaneFit fit_plane_ransac(std::span<const Vec3f> points, std::span<const std::uint32_t> indices,
                          const RansacPlaneConfig& config, std::mt19937_64& rng) {
  std::vector<std::uint32_t> all;
  if (indices.empty()) {
    all.resize(points.size());
    std::iota(all.begin(), all.end(), 0u);
    indices = all;
  }
  PlaneFit fit;
  const std::size_t n = indices.size();
  if (n < 3) return fit;
  const float thr = float(config.distance);
  const double cos_tilt = std::cos(config.max_tilt);
  // Hypotheses are scored on a fixed random subset of large inputs (the inlier share is what
  // matters); the final inlier set is always selected over all points.
  std::vector<std::uint32_t> subset;
  std::span<const std::uint32_t> scored = indices;
  if (n > config.max_scored_points && config.max_scored_points >= 3) {
    std::uniform_int_distribution<std::size_t> any(0, n - 1);
    subset.resize(config.max_scored_points);
    for (auto& v : subset) v = indices[any(rng)];
    scored = subset;
  }
  std::size_t best = 0;
  double needed = double(config.max_iterations);
  std::uniform_int_distribution<std::size_t> pick(0, n - 1);
  int it = 0;
  for (; it < config.max_iterations && it < needed; ++it) {
    // One draw per statement: a call's argument order is unspecified (GCC: right to left, the order
    // kept so that a seed gives the same result with every compiler and as before).
    const std::size_t c = pick(rng), b = pick(rng), a = pick(rng);
    const auto h = plane_from_three(points[indices[a]], points[indices[b]], points[indices[c]]);
    if (!h) continue;
    if (config.axis && std::abs(h->normal.dot(*config.axis)) < cos_tilt) continue;
    const std::size_t count = count_inliers(points, scored, *h, thr);
    if (count <= best) continue;
    best = count;
    fit.plane = *h;
    fit.found = true;
    // Adaptive termination: k = log(1 - p) / log(1 - w^3)
    const double w = double(best) / double(scored.size());
    const double denom = std::log(std::max(1e-12, 1.0 - w * w * w));
    needed = denom < 0.0 ? std::log(1.0 - config.probability) / denom : needed;
  }
  fit.iterations = it;
  if (!fit.found) return fit;
  fit.inliers = select_inliers(points, indices, fit.plane, thr);
  if (config.refine) {
    if (auto refined = fit_plane(points, fit.inliers)) {
      if (refined->normal.dot(fit.plane.normal) < 0.0f) {
        refined->normal = -refined->normal;
        refined->d = -refined->d;
      }
      fit.plane = *refined;
      fit.inliers = select_inliers(points, indices, fit.plane, thr);
    }
  }
  return fit;
}

}  // namespace cairn
