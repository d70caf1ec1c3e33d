#include <gtest/gtest.h>

#include <numbers>
#include <random>

#include "cairn/core/normals.hpp"
#include "cairn/core/plane.hpp"

using namespace cairn;

TEST(Normals, SphereNormalsAreRadialAndFaceViewpoint) {
  std::mt19937_64 rng(11);
  std::normal_distribution<float> g(0.0f, 1.0f);
  std::vector<Vec3f> pts;
  for (int i = 0; i < 20000; ++i) {
    Vec3f d(g(rng), g(rng), g(rng));
    pts.push_back(d.normalized());
  }
  const KdTree tree(pts);
  const NormalResult r = estimate_normals(pts, tree, {.radius = 0.1});  // viewpoint = centre
  EXPECT_EQ(r.num_invalid, 0u);
  double worst = 0;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    worst = std::max(worst, std::acos(std::clamp(double(r.normals[i].dot(-pts[i])), -1.0, 1.0)));
    EXPECT_LT(r.curvature[i], 0.01f);
  }
  EXPECT_LT(worst * 180 / std::numbers::pi, 2.0);  // inward, towards the centre viewpoint
}

TEST(Normals, TooFewNeighboursGiveZeroNormal) {
  const std::vector<Vec3f> pts{{0, 0, 0}, {10, 0, 0}};
  const KdTree tree(pts);
  const NormalResult r = estimate_normals(pts, tree, {.radius = 0.5});
  EXPECT_EQ(r.num_invalid, 2u);
  EXPECT_EQ(r.normals[0], Vec3f::Zero());
}

TEST(Plane, RansacFindsExactInlierSetNoiseFree) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<Vec3f> pts;
  const Vec3f n = Vec3f(0.1f, -0.2f, 1.0f).normalized();
  const float d = -0.3f;
  std::vector<std::uint32_t> expect;
  for (int i = 0; i < 3000; ++i) {
    Vec3f p(u(rng), u(rng), 0);
    p.z() = (-d - n.x() * p.x() - n.y() * p.y()) / n.z();  // on the plane
    expect.push_back(std::uint32_t(pts.size()));
    pts.push_back(p);
    if (i % 3 == 0) pts.emplace_back(u(rng), u(rng), 2.0f + u(rng));  // far off the plane
  }
  std::mt19937_64 gen(42);
  const PlaneFit fit = fit_plane_ransac(pts, {}, {.distance = 0.01}, gen);
  ASSERT_TRUE(fit.found);
  EXPECT_EQ(fit.inliers, expect);
  EXPECT_GT(std::abs(fit.plane.normal.dot(n)), 0.99999f);
  EXPECT_NEAR(std::abs(fit.plane.d), std::abs(d), 1e-4f);
}

TEST(Plane, AxisConstraintSelectsTheGroundNotTheWall) {
  std::vector<Vec3f> pts;
  for (int i = 0; i < 60; ++i)
    for (int j = 0; j < 60; ++j) {
      pts.emplace_back(i * 0.05f, j * 0.05f, 0.0f);                // ground, 3600 points
      if (j < 30 || i < 40) pts.emplace_back(0.0f, i * 0.05f, j * 0.05f + 0.1f);  // wall, larger
    }
  std::mt19937_64 gen(1);
  RansacPlaneConfig cfg{.distance = 0.01};
  cfg.axis = Vec3f::UnitZ();
  cfg.max_tilt = 0.3;
  const PlaneFit fit = fit_plane_ransac(pts, {}, cfg, gen);
  ASSERT_TRUE(fit.found);
  EXPECT_GT(std::abs(fit.plane.normal.z()), 0.99f);
  EXPECT_EQ(fit.inliers.size(), 3600u);
}

TEST(Plane, LeastSquaresAndDegenerateInput) {
  const std::vector<Vec3f> line{{0, 0, 0}, {1, 1, 1}, {2, 2, 2}};
  const std::vector<std::uint32_t> idx{0, 1, 2};
  EXPECT_FALSE(fit_plane(line, idx).has_value());
  std::mt19937_64 gen(3);
  EXPECT_FALSE(fit_plane_ransac(line, {}, {}, gen).found);
}
