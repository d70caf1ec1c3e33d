#pragma once
// Least-squares similarity / rigid transform between matched 3-D point sets (Umeyama 1991,
// "Least-squares estimation of transformation parameters between two point patterns").
// Sec. 4.1: the scale of the SfM reconstruction is recovered from the similarity between the SfM
// camera positions and the VINS-Mono camera positions; a seeded RANSAC variant copes with
// outlier-contaminated camera positions.
#include <cstdint>
#include <span>
#include <vector>

#include "cairn/core/point_cloud.hpp"
#include "cairn/core/transform.hpp"

namespace cairn {

struct UmeyamaConfig {
  bool with_scale = true;  // false: rigid transform (scale fixed to 1)
  /// A point set whose covariance has σ₂ / σ₁ below this (σ = singular values, descending) is
  /// collinear (or coincident): the rotation about its line is undetermined and the fit refused.
  double degeneracy_ratio = 1e-8;

  template <class V>
  void visit(V& v) {
    v("with_scale", with_scale, "estimate a uniform scale (similarity) or not (rigid)");
    v("degeneracy_ratio", degeneracy_ratio,
      "refuse point sets whose covariance singular values have sigma2/sigma1 below this (collinear)");
  }
};

struct UmeyamaResult {
  Similarity transform;  // target ≈ transform * source
  double rms = 0.0;      // [target units] RMS of |target_i − transform(source_i)|
};

/// The similarity (or rigid transform) minimising Σ |target_i − (s R source_i + t)|².
/// Throws InputError when the sets differ in size, have fewer than 3 points, contain non-finite
/// values, or either set is degenerate (coincident or collinear points).
[[nodiscard]] UmeyamaResult umeyama(std::span<const Vec3d> source, std::span<const Vec3d> target,
                                    const UmeyamaConfig& config = {});

struct RobustUmeyamaConfig {
  UmeyamaConfig fit;
  double inlier_threshold = 0.5;  // [target units] a pair is an inlier when |target − S(source)| < this
  int iterations = 1000;          // random triplets (all triplets when there are fewer)
  int min_inliers = 3;            // fewer inliers in the best hypothesis: refused
  std::uint64_t seed = 42;

  template <class V>
  void visit(V& v) {
    v("fit", fit, "least-squares fit of each hypothesis and of the final inlier set");
    v("inlier_threshold", inlier_threshold, "a pair is an inlier when its residual is below this");
    v("iterations", iterations, "number of random triplets (all triplets when fewer)");
    v("min_inliers", min_inliers, "minimum number of inliers of an accepted transform");
    v("seed", seed, "seed of the triplet sampler");
  }
};

struct RobustUmeyamaResult {
  Similarity transform;
  double rms = 0.0;                     // over the inliers
  std::vector<std::uint32_t> inliers;   // ascending indices of the inlier pairs
  int hypotheses = 0;                   // non-degenerate triplets evaluated
};

/// RANSAC over triplets, then a least-squares refit on the consensus set (twice, re-selecting
/// the inliers). Deterministic for a given seed. Throws InputError on bad input (as umeyama) or
/// when no hypothesis reaches min_inliers; ConfigError on a bad config.
[[nodiscard]] RobustUmeyamaResult robust_umeyama(std::span<const Vec3d> source, std::span<const Vec3d> target,
                                                 const RobustUmeyamaConfig& config = {});

}  // namespace cairn
