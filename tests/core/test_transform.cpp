#include <gtest/gtest.h>

#include <random>

#include "cairn/core/error.hpp"
#include "cairn/core/transform.hpp"

using namespace cairn;

namespace {
Similarity random_similarity(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const Eigen::Quaterniond q = Eigen::Quaterniond(u(rng), u(rng), u(rng), u(rng)).normalized();
  return {0.5 + std::abs(u(rng)) * 3.0, q.toRotationMatrix(), Eigen::Vector3d(u(rng), u(rng), u(rng)) * 10.0};
}
}  // namespace

TEST(Transform, ComposeInverseAndMatrixRoundTrip) {
  std::mt19937_64 rng(3);
  for (int i = 0; i < 50; ++i) {
    const Similarity a = random_similarity(rng), b = random_similarity(rng);
    const Eigen::Vector3d p(1.5, -2.0, 0.25);
    EXPECT_LT(((a * b) * p - a * (b * p)).norm(), 1e-9);
    EXPECT_LT((a.inverse() * (a * p) - p).norm(), 1e-9);
    const Similarity back = Similarity::from_matrix(a.matrix());
    EXPECT_NEAR(back.scale, a.scale, 1e-12);
    EXPECT_LT((back.rotation - a.rotation).norm(), 1e-12);
    EXPECT_LT((matrix_from_json(matrix_to_json(a.matrix())) - a.matrix()).norm(), 1e-15);
  }
}

TEST(Transform, CloudPositionsAndNormals) {
  PointCloud c;
  c.points = {{1, 0, 0}, {0, 2, 0}};
  c.normals = {{1, 0, 0}, {0, 0, 1}};
  const Similarity S{2.0, Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix(), {1, 1, 1}};
  transform_cloud(c, S);
  EXPECT_LT((c.world(0) - Eigen::Vector3d(1, 3, 1)).norm(), 1e-6);
  EXPECT_LT((c.world(1) - Eigen::Vector3d(-3, 1, 1)).norm(), 1e-6);
  EXPECT_LT((c.normals[0] - Vec3f(0, 1, 0)).norm(), 1e-6f);  // rotated, not scaled
  EXPECT_LT((c.normals[1] - Vec3f(0, 0, 1)).norm(), 1e-6f);
}

TEST(Transform, GeoreferencedCloudKeepsPrecision) {
  PointCloud c;
  c.origin = {394554.0, 5400000.0, 790.0};
  c.points = {{0.917f, 0.123f, 0.5f}, {100.25f, 50.125f, 3.0f}};
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(-394000.0, -5400000.0, -700.0);
  T.linear() = Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const Eigen::Vector3d expect = T * c.world(1);
  transform_cloud(c, T);
  EXPECT_LT((c.world(1) - expect).norm(), 1e-4);  // float positions relative to a double origin
}

TEST(Transform, RejectsBadMatrices) {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m(0, 0) = -1;  // reflection
  EXPECT_THROW((void)Similarity::from_matrix(m), InputError);
  m = Eigen::Matrix4d::Identity();
  m(0, 1) = 0.5;  // shear
  EXPECT_THROW((void)Similarity::from_matrix(m), InputError);
  EXPECT_THROW((void)matrix_from_json(nlohmann::json::array({1, 2, 3})), InputError);
  EXPECT_NEAR(rotation_angle(Eigen::AngleAxisd(0.25, Eigen::Vector3d::UnitX()).toRotationMatrix()), 0.25, 1e-12);
}
