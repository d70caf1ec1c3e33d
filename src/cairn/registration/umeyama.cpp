#include "cairn/registration/umeyama.hpp"

#include <Eigen/SVD>
#include <algorithm>
#include <array>
#include <cmath>
#include <optional>
#include <random>
#include <string>

#include "cairn/core/error.hpp"

namespace cairn {
namespace {

/// Mean and covariance of a point set.
struct Moments {
  Vec3d mean = Vec3d::Zero();
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
};

template <class Get>
Moments moments(std::size_t n, Get&& get) {
  Moments m;
  for (std::size_t i = 0; i < n; ++i) m.mean += get(i);
  m.mean /= double(n);
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3d d = get(i) - m.mean;
    m.cov.noalias() += d * d.transpose();
  }
  m.cov /= double(n);
  return m;
}

/// Empty when the set is coincident or collinear; otherwise a short description is not needed.
std::optional<std::string> degeneracy(const Eigen::Matrix3d& cov, double ratio) {
  const Eigen::Vector3d sv = Eigen::JacobiSVD<Eigen::Matrix3d>(cov).singularValues();  // descending
  if (!(sv(0) > 0.0)) return "all points coincide";
  if (!(sv(1) > ratio * sv(0)))
    return "the points are collinear (covariance singular values " + std::to_string(sv(0)) + ", " +
           std::to_string(sv(1)) + ", " + std::to_string(sv(2)) + ")";
  return std::nullopt;
}

/// Umeyama's closed form on the pairs selected by `idx` (all pairs when idx is empty). Returns
/// nullopt (with *why set) for a degenerate configuration.
std::optional<Similarity> fit(std::span<const Vec3d> src, std::span<const Vec3d> dst, std::span<const std::uint32_t> idx,
                              const UmeyamaConfig& cfg, std::string* why) {
  const std::size_t n = idx.empty() ? src.size() : idx.size();
  const auto at = [&](std::size_t i) { return idx.empty() ? i : std::size_t(idx[i]); };
  const Moments ms = moments(n, [&](std::size_t i) { return src[at(i)]; });
  const Moments md = moments(n, [&](std::size_t i) { return dst[at(i)]; });
  if (auto d = degeneracy(ms.cov, cfg.degeneracy_ratio)) {
    if (why) *why = "source: " + *d;
    return std::nullopt;
  }
  if (auto d = degeneracy(md.cov, cfg.degeneracy_ratio)) {
    if (why) *why = "target: " + *d;
    return std::nullopt;
  }
  // Umeyama Eq. (38)–(42): Σ_xy = 1/n Σ (y − μ_y)(x − μ_x)ᵀ = U D Vᵀ, R = U S Vᵀ,
  // c = tr(D S) / σ_x², t = μ_y − c R μ_x.
  Eigen::Matrix3d sigma = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < n; ++i) sigma.noalias() += (dst[at(i)] - md.mean) * (src[at(i)] - ms.mean).transpose();
  sigma /= double(n);
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(sigma, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Vector3d S = Eigen::Vector3d::Ones();
  if (svd.matrixU().determinant() * svd.matrixV().determinant() < 0.0) S(2) = -1.0;  // no reflection
  Similarity T;
  T.rotation = svd.matrixU() * S.asDiagonal() * svd.matrixV().transpose();
  const double var_src = ms.cov.trace();
  T.scale = cfg.with_scale ? svd.singularValues().dot(S) / var_src : 1.0;
  if (!(T.scale > 0.0) || !std::isfinite(T.scale)) {
    if (why) *why = "the estimated scale is not positive (the point sets do not correspond)";
    return std::nullopt;
  }
  T.translation = md.mean - T.scale * (T.rotation * ms.mean);
  return T;
}

void check_input(std::span<const Vec3d> source, std::span<const Vec3d> target) {
  if (source.size() != target.size())
    throw InputError("umeyama: " + std::to_string(source.size()) + " source points but " +
                     std::to_string(target.size()) + " target points");
  if (source.size() < 3)
    throw InputError("umeyama: need at least 3 point pairs, got " + std::to_string(source.size()));
  for (std::size_t i = 0; i < source.size(); ++i)
    if (!source[i].allFinite() || !target[i].allFinite())
      throw InputError("umeyama: point pair " + std::to_string(i) + " is not finite");
}

void check_config(const UmeyamaConfig& c) {
  if (!(c.degeneracy_ratio >= 0.0 && c.degeneracy_ratio < 1.0))
    throw ConfigError("umeyama.degeneracy_ratio must be in [0, 1)");
}

double rms_of(std::span<const Vec3d> src, std::span<const Vec3d> dst, std::span<const std::uint32_t> idx,
              const Similarity& T) {
  const std::size_t n = idx.empty() ? src.size() : idx.size();
  double sum = 0.0;
  for (std::size_t k = 0; k < n; ++k) {
    const std::size_t i = idx.empty() ? k : idx[k];
    sum += (dst[i] - T * src[i]).squaredNorm();
  }
  return std::sqrt(sum / double(n));
}

std::vector<std::uint32_t> inliers_of(std::span<const Vec3d> src, std::span<const Vec3d> dst, const Similarity& T,
                                      double threshold) {
  std::vector<std::uint32_t> in;
  const double t2 = threshold * threshold;
  for (std::size_t i = 0; i < src.size(); ++i)
    if ((dst[i] - T * src[i]).squaredNorm() < t2) in.push_back(std::uint32_t(i));
  return in;
}

}  // namespace

UmeyamaResult umeyama(std::span<const Vec3d> source, std::span<const Vec3d> target, const UmeyamaConfig& config) {
  check_config(config);
  check_input(source, target);
  std::string why;
  const auto T = fit(source, target, {}, config, &why);
  if (!T) throw InputError("umeyama: degenerate configuration: " + why);
  return {*T, rms_of(source, target, {}, *T)};
}

RobustUmeyamaResult robust_umeyama(std::span<const Vec3d> source, std::span<const Vec3d> target,
                                   const RobustUmeyamaConfig& config) {
  check_config(config.fit);
  if (!(config.inlier_threshold > 0.0)) throw ConfigError("robust_umeyama.inlier_threshold must be positive");
  if (config.iterations < 1) throw ConfigError("robust_umeyama.iterations must be at least 1");
  if (config.min_inliers < 3) throw ConfigError("robust_umeyama.min_inliers must be at least 3");
  check_input(source, target);

  const std::size_t n = source.size();
  // All triplets when there are no more of them than iterations, else seeded random triplets.
  std::vector<std::array<std::uint32_t, 3>> triplets;
  const double all = double(n) * double(n - 1) * double(n - 2) / 6.0;
  if (all <= double(config.iterations)) {
    for (std::uint32_t a = 0; a < n; ++a)
      for (std::uint32_t b = a + 1; b < n; ++b)
        for (std::uint32_t c = b + 1; c < n; ++c) triplets.push_back({a, b, c});
  } else {
    std::mt19937_64 rng(config.seed);
    std::uniform_int_distribution<std::uint32_t> pick(0, std::uint32_t(n - 1));
    while (triplets.size() < std::size_t(config.iterations)) {
      const std::uint32_t a = pick(rng), b = pick(rng), c = pick(rng);
      if (a != b && b != c && a != c) triplets.push_back({a, b, c});
    }
  }

  RobustUmeyamaResult best;
  double best_rms = 0.0;
  for (const auto& tri : triplets) {
    const auto T = fit(source, target, tri, config.fit, nullptr);
    if (!T) continue;
    ++best.hypotheses;
    auto in = inliers_of(source, target, *T, config.inlier_threshold);
    if (in.size() < 3) continue;
    const double rms = rms_of(source, target, in, *T);
    if (in.size() > best.inliers.size() || (in.size() == best.inliers.size() && rms < best_rms)) {
      best.inliers = std::move(in);
      best.transform = *T;
      best_rms = rms;
    }
  }
  if (best.inliers.size() < std::size_t(config.min_inliers))
    throw InputError("robust_umeyama: no transform has " + std::to_string(config.min_inliers) + " inliers within " +
                     std::to_string(config.inlier_threshold) + " (best: " + std::to_string(best.inliers.size()) +
                     " of " + std::to_string(n) + ", " + std::to_string(best.hypotheses) +
                     " non-degenerate triplets)");
  // Least-squares refit on the consensus set, re-select inliers, refit once more.
  for (int round = 0; round < 2; ++round) {
    std::string why;
    const auto T = fit(source, target, best.inliers, config.fit, &why);
    if (!T) throw InputError("robust_umeyama: degenerate inlier set: " + why);
    auto in = inliers_of(source, target, *T, config.inlier_threshold);
    best.transform = *T;
    if (in.size() < std::size_t(config.min_inliers)) break;  // keep the previous consensus set
    best.inliers = std::move(in);
  }
  best.rms = rms_of(source, target, best.inliers, best.transform);
  return best;
}

}  // namespace cairn
