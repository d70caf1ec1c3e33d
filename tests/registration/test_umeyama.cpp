// Umeyama similarity / rigid fits on known answers, degeneracy handling, RANSAC variant.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "cairn/core/error.hpp"
#include "cairn/registration/umeyama.hpp"

using namespace cairn;

namespace {

Similarity random_similarity(std::mt19937_64& rng, bool with_scale = true) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const Eigen::Quaterniond q = Eigen::Quaterniond(u(rng), u(rng), u(rng), u(rng)).normalized();
  return {with_scale ? 0.2 + 5.0 * std::abs(u(rng)) : 1.0, q.toRotationMatrix(),
          Eigen::Vector3d(u(rng), u(rng), u(rng)) * 50.0};
}

std::vector<Vec3d> random_points(std::mt19937_64& rng, std::size_t n, double extent = 10.0) {
  std::uniform_real_distribution<double> u(-extent, extent);
  std::vector<Vec3d> p(n);
  for (auto& x : p) x = {u(rng), u(rng), u(rng)};
  return p;
}

std::vector<Vec3d> map_points(const Similarity& S, const std::vector<Vec3d>& pts) {
  std::vector<Vec3d> out;
  for (const auto& p : pts) out.push_back(S * p);
  return out;
}

void expect_near(const Similarity& a, const Similarity& b, double tol) {
  EXPECT_NEAR(a.scale, b.scale, tol * b.scale);
  EXPECT_LT((a.rotation - b.rotation).norm(), tol);
  EXPECT_LT((a.translation - b.translation).norm(), tol * (1.0 + b.translation.norm()));
}

}  // namespace

TEST(Umeyama, ExactSimilarities) {
  std::mt19937_64 rng(42);
  for (int i = 0; i < 50; ++i) {
    const Similarity S = random_similarity(rng);
    const auto src = random_points(rng, 3 + std::size_t(i % 10));
    const UmeyamaResult r = umeyama(src, map_points(S, src));
    expect_near(r.transform, S, 1e-9);
    EXPECT_LT(r.rms, 1e-8);
  }
}

TEST(Umeyama, RigidModeKeepsScaleOne) {
  std::mt19937_64 rng(43);
  const Similarity S = random_similarity(rng, false);
  const auto src = random_points(rng, 20);
  const UmeyamaResult r = umeyama(src, map_points(S, src), {.with_scale = false});
  EXPECT_EQ(r.transform.scale, 1.0);
  expect_near(r.transform, S, 1e-9);
  // Rigid fit of scaled data: scale stays 1, residual is reported.
  const Similarity S2{2.0, S.rotation, S.translation};
  EXPECT_GT(umeyama(src, map_points(S2, src), {.with_scale = false}).rms, 1.0);
}

TEST(Umeyama, NoisyCameraPositionsRecoverScale) {
  // Sec. 4.1: SfM camera positions (arbitrary scale) vs metric VINS positions with 2 cm noise.
  std::mt19937_64 rng(44);
  std::normal_distribution<double> g(0.0, 0.02);
  const Similarity S{0.37, Eigen::AngleAxisd(1.1, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix(),
                     {4.0, -2.0, 10.0}};
  auto src = random_points(rng, 200, 20.0);
  auto dst = map_points(S, src);
  for (auto& p : dst) p += Vec3d(g(rng), g(rng), g(rng));
  const UmeyamaResult r = umeyama(src, dst);
  EXPECT_NEAR(r.transform.scale, 0.37, 0.37 * 2e-3);
  EXPECT_LT(Eigen::AngleAxisd(r.transform.rotation.transpose() * S.rotation).angle(), 1e-3);
  EXPECT_NEAR(r.rms, 0.02 * std::sqrt(3.0), 0.006);
}

TEST(Umeyama, PlanarPointsGiveARotationNotAReflection) {
  std::mt19937_64 rng(45);
  std::uniform_real_distribution<double> u(-5.0, 5.0);
  std::vector<Vec3d> src;
  for (int i = 0; i < 10; ++i) src.emplace_back(u(rng), u(rng), 0.0);
  const Similarity S = random_similarity(rng);
  const UmeyamaResult r = umeyama(src, map_points(S, src));
  EXPECT_NEAR(r.transform.rotation.determinant(), 1.0, 1e-12);
  expect_near(r.transform, S, 1e-9);
  // Three points (the minimal case) too.
  const std::vector<Vec3d> tri = {{0, 0, 0}, {1, 0, 0}, {0, 2, 0}};
  expect_near(umeyama(tri, map_points(S, tri)).transform, S, 1e-9);
}

TEST(Umeyama, RefusesDegenerateAndBadInput) {
  const std::vector<Vec3d> two = {{0, 0, 0}, {1, 0, 0}};
  EXPECT_THROW((void)umeyama(two, two), InputError);
  const std::vector<Vec3d> line = {{0, 0, 0}, {1, 1, 1}, {2, 2, 2}, {-3, -3, -3}};
  const std::vector<Vec3d> good = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  EXPECT_THROW((void)umeyama(line, good), InputError);
  EXPECT_THROW((void)umeyama(good, line), InputError);
  const std::vector<Vec3d> same(5, Vec3d(1, 2, 3));
  const std::vector<Vec3d> good5 = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 1, 1}};
  EXPECT_THROW((void)umeyama(same, good5), InputError);
  std::vector<Vec3d> nan = good;
  nan[2].y() = NAN;
  EXPECT_THROW((void)umeyama(nan, good), InputError);
  EXPECT_THROW((void)umeyama(good, good5), InputError);  // size mismatch
  try {
    (void)umeyama(line, good);
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("collinear"), std::string::npos) << e.what();
  }
  EXPECT_THROW((void)umeyama(good, good, {.degeneracy_ratio = 2.0}), ConfigError);
}

TEST(Umeyama, RobustVariantRejectsOutliersDeterministically) {
  std::mt19937_64 rng(46);
  std::normal_distribution<double> g(0.0, 0.02);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const Similarity S{2.5, Eigen::AngleAxisd(-0.7, Eigen::Vector3d(0, 1, 1).normalized()).toRotationMatrix(),
                     {1.0, 2.0, 3.0}};
  auto src = random_points(rng, 60, 5.0);
  auto dst = map_points(S, src);
  std::vector<bool> outlier(src.size());
  for (std::size_t i = 0; i < dst.size(); ++i) {
    dst[i] += Vec3d(g(rng), g(rng), g(rng));
    if (u(rng) < 0.3) {
      outlier[i] = true;
      dst[i] += Vec3d(g(rng), g(rng), g(rng)).normalized() * (2.0 + 8.0 * u(rng));
    }
  }
  const RobustUmeyamaConfig cfg{.inlier_threshold = 0.15, .iterations = 500, .seed = 7};
  const RobustUmeyamaResult r = robust_umeyama(src, dst, cfg);
  expect_near(r.transform, S, 5e-3);
  for (const auto i : r.inliers) EXPECT_FALSE(outlier[i]) << i;
  EXPECT_GT(r.inliers.size(), 35u);
  EXPECT_LT(r.rms, 0.06);
  // The plain least-squares fit is ruined by the same outliers.
  EXPECT_GT(std::abs(umeyama(src, dst).transform.scale - 2.5), 0.02);
  const RobustUmeyamaResult again = robust_umeyama(src, dst, cfg);
  EXPECT_EQ(again.inliers, r.inliers);
  EXPECT_EQ(again.transform.matrix(), r.transform.matrix());
}

TEST(Umeyama, RobustVariantSmallSetsAndFailure) {
  // Five pairs: all 10 triplets are tried (no randomness needed).
  std::mt19937_64 rng(47);
  const Similarity S = random_similarity(rng);
  const auto src = random_points(rng, 5);
  const RobustUmeyamaResult r = robust_umeyama(src, map_points(S, src), {.inlier_threshold = 0.01});
  EXPECT_EQ(r.inliers.size(), 5u);
  EXPECT_EQ(r.hypotheses, 10);
  // Pure noise: nothing agrees on a transform with 10 inliers.
  const auto a = random_points(rng, 30), b = random_points(rng, 30);
  EXPECT_THROW((void)robust_umeyama(a, b, {.inlier_threshold = 0.01, .min_inliers = 10}), InputError);
  EXPECT_THROW((void)robust_umeyama(a, b, {.inlier_threshold = 0.0}), ConfigError);
}
