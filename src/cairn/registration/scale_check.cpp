#include "cairn/registration/scale_check.hpp"

#include <tbb/parallel_for.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <optional>
#include <vector>

#include "cairn/core/error.hpp"
#include "cairn/core/kdtree.hpp"
#include "cairn/registration/umeyama.hpp"

namespace cairn {

void ScaleCheckConfig::validate() const {
  if (!(max_scale_error > 0.0 && max_scale_error < 1.0))
    throw ConfigError("registration.scale_check.max_scale_error must be in (0, 1)");
  if (estimate_passes < 1) throw ConfigError("registration.scale_check.estimate_passes must be >= 1");
  if (!(estimate_tolerance > 0.0 && estimate_tolerance <= max_scale_error))
    throw ConfigError("registration.scale_check.estimate_tolerance must be in (0, max_scale_error]");
  if (!(correspondence_distance > 0.0)) throw ConfigError("registration.scale_check.correspondence_distance must be > 0");
  if (!(trim > 0.0 && trim <= 1.0)) throw ConfigError("registration.scale_check.trim must be in (0, 1]");
  if (iterations < 1 || rounds < 1) throw ConfigError("registration.scale_check.iterations and rounds must be >= 1");
  if (!(tolerance > 0.0)) throw ConfigError("registration.scale_check.tolerance must be > 0");
  if (!(min_extent >= 0.0)) throw ConfigError("registration.scale_check.min_extent must be >= 0");
  if (min_segments < 3) throw ConfigError("registration.scale_check.min_segments must be >= 3");
  if (!(segment_inlier_distance > 0.0)) throw ConfigError("registration.scale_check.segment_inlier_distance must be > 0");
}

namespace {

constexpr std::size_t kMinSegmentPoints = 10;  // fewer pairs move no segment
constexpr int kRansacIterations = 200;         // triplets of segments (all of them when fewer)
constexpr double kFirstRoundSlack = 4.0;       // the first round's inlier distance, in segment_inlier_distance

constexpr double kMinConditioning = 1e-3;  // point-to-plane: smallest/largest eigenvalue of Σ n nᵀ

struct Residual {
  float sq_dist = 0.0f;
  Vec3d offset;  // target point − source point
  Vec3d normal;  // the target's (zero without normals)
};

/// One step of the translation: point-to-plane (Σ n nᵀ d = Σ n nᵀ offset) when the normals span
/// all directions, else the mean offset (point-to-point).
Vec3d translation_step(std::span<const Residual> kept) {
  Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
  Vec3d b = Vec3d::Zero(), mean = Vec3d::Zero();
  for (const Residual& r : kept) {
    A += r.normal * r.normal.transpose();
    b += r.normal * r.normal.dot(r.offset);
    mean += r.offset;
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(A);
  if (eig.eigenvalues()(2) > 0.0 && eig.eigenvalues()(0) > kMinConditioning * eig.eigenvalues()(2))
    return A.ldlt().solve(b);
  return mean / double(kept.size());
}

/// Where a trimmed translation ICP puts `source` on the target (its tree and normals): the
/// translation, or nothing when too few points pair up.
std::optional<Vec3d> align_translation(const std::vector<Vec3d>& source, const KdTree& tree,
                                       std::span<const Vec3f> normals, const ScaleCheckConfig& c) {
  Vec3d d = Vec3d::Zero();
  const float max_sq = float(c.correspondence_distance * c.correspondence_distance);
  std::vector<Residual> residuals;
  for (int it = 0; it < c.iterations; ++it) {
    residuals.clear();
    for (const Vec3d& p : source) {
      float d2 = 0.0f;
      const Vec3d q = p + d;
      const std::uint32_t j = tree.nearest_within(q.cast<float>(), max_sq, &d2);
      if (d2 <= max_sq)
        residuals.push_back({d2, tree.points()[j].cast<double>() - q,
                             normals.empty() ? Vec3d::Zero() : Vec3d(normals[j].cast<double>())});
    }
    const std::size_t keep = std::size_t(c.trim * double(residuals.size()));
    if (keep < kMinSegmentPoints) return std::nullopt;
    std::nth_element(residuals.begin(), residuals.begin() + std::ptrdiff_t(keep - 1), residuals.end(),
                     [](const Residual& a, const Residual& b) { return a.sq_dist < b.sq_dist; });
    const Vec3d step = translation_step(std::span<const Residual>(residuals).first(keep));
    d += step;
    if (step.norm() < c.tolerance) break;
  }
  return d;
}

Vec3d mean_of(const std::vector<Vec3d>& points) {
  Vec3d c = Vec3d::Zero();
  for (const Vec3d& p : points) c += p;
  return c / double(points.size());
}

}  // namespace

ScaleFit fit_scale(std::span<const SegmentPair> pairs, const ScaleCheckConfig& config) {
  config.validate();
  std::vector<KdTree> trees;
  std::vector<std::span<const Vec3f>> normals;
  std::vector<std::vector<Vec3d>> sources;
  for (const SegmentPair& p : pairs) {
    for (const auto* cloud : {&p.source, &p.target})
      for (const Vec3f& q : *cloud)
        if (!q.allFinite()) throw InputError("fit_scale: non-finite point");
    if (p.source.size() < kMinSegmentPoints || p.target.size() < kMinSegmentPoints) continue;
    if (!p.target_normals.empty() && p.target_normals.size() != p.target.size())
      throw InputError("fit_scale: a target segment has normals for some points only");
    trees.emplace_back(p.target);
    normals.emplace_back(p.target_normals);
    sources.emplace_back();
    for (const Vec3f& q : p.source) sources.back().push_back(q.cast<double>());
  }
  ScaleFit fit;
  for (int round = 0; round < config.rounds; ++round) {
    // Each segment aligned on its own (in parallel; the results are gathered in segment order).
    std::vector<std::optional<Vec3d>> aligned(sources.size());
    tbb::parallel_for(std::size_t{0}, sources.size(), [&](std::size_t k) {
      std::vector<Vec3d> moved;
      for (const Vec3d& q : sources[k]) moved.push_back(fit.correction * q);
      const std::optional<Vec3d> d = align_translation(moved, trees[k], normals[k], config);
      if (d) aligned[k] = mean_of(moved) + *d;
    });
    std::vector<Vec3d> from, to;  // segment centroids (as fitted so far) -> aligned
    for (std::size_t k = 0; k < sources.size(); ++k) {
      if (!aligned[k]) continue;
      from.push_back(mean_of(sources[k]));
      to.push_back(*aligned[k]);
    }
    if (from.size() < std::size_t(config.min_segments)) return ScaleFit{};
    // RANSAC over triplets: a segment paired with a piece of its stone (or a stone seen from one
    // side only) is moved by decimetres that no similarity explains.
    RobustUmeyamaResult robust;
    try {
      // The first round starts from the rigid fit, where a large scale error leaves the segments'
      // own alignments only roughly consistent (a stone 10 % too large); later rounds start from the
      // similarity.
      const double inlier = config.segment_inlier_distance * (round == 0 ? kFirstRoundSlack : 1.0);
      robust = robust_umeyama(from, to, {.fit = {.with_scale = true}, .inlier_threshold = inlier,
                                         .iterations = kRansacIterations, .min_inliers = config.min_segments, .seed = 1});
    } catch (const InputError&) {  // no consensus, or collinear centroids: not observable
      return ScaleFit{};
    }
    fit.correction = robust.transform;
    fit.segments = robust.inliers.size();
    Vec3d c = Vec3d::Zero();
    for (std::uint32_t i : robust.inliers) c += from[i];
    c /= double(robust.inliers.size());
    fit.extent = 0.0;
    for (std::uint32_t i : robust.inliers) fit.extent = std::max(fit.extent, (from[i] - c).norm());
  }
  fit.scale = fit.correction.scale;
  fit.observable = fit.extent >= config.min_extent;
  return fit;
}

}  // namespace cairn
