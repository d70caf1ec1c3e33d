#include <gtest/gtest.h>

#include <algorithm>
#include <random>

#include "cairn/core/kdtree.hpp"

using namespace cairn;

namespace {
std::vector<Vec3f> random_points(std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<Vec3f> p(n);
  for (auto& q : p) q = {u(rng), u(rng), u(rng)};
  return p;
}
}  // namespace

TEST(KdTree, KnnMatchesBruteForce) {
  const auto pts = random_points(5000, 1);
  const auto queries = random_points(200, 2);
  const KdTree tree(pts);
  Neighbors nb;
  for (const auto& q : queries) {
    tree.knn(q, 8, nb);
    std::vector<std::pair<float, std::uint32_t>> all;
    for (std::uint32_t i = 0; i < pts.size(); ++i) all.emplace_back((pts[i] - q).squaredNorm(), i);
    std::partial_sort(all.begin(), all.begin() + 8, all.end());
    ASSERT_EQ(nb.size(), 8u);
    for (int k = 0; k < 8; ++k) {
      EXPECT_EQ(nb.indices[k], all[k].second);
      EXPECT_FLOAT_EQ(nb.sq_dists[k], all[k].first);
    }
  }
}

TEST(KdTree, RadiusMatchesBruteForce) {
  const auto pts = random_points(5000, 3);
  const auto queries = random_points(200, 4);
  const KdTree tree(pts);
  Neighbors nb;
  const float r = 0.15f;
  for (const auto& q : queries) {
    tree.radius(q, r, nb, true);
    std::vector<std::uint32_t> expect;
    for (std::uint32_t i = 0; i < pts.size(); ++i)
      if ((pts[i] - q).squaredNorm() < r * r) expect.push_back(i);
    std::vector<std::uint32_t> got = nb.indices;
    EXPECT_TRUE(std::is_sorted(nb.sq_dists.begin(), nb.sq_dists.end()));
    std::sort(got.begin(), got.end());
    EXPECT_EQ(got, expect);
  }
}

TEST(KdTree, NearestAndSmallTrees) {
  const std::vector<Vec3f> pts{{0, 0, 0}, {1, 0, 0}, {0, 2, 0}};
  const KdTree tree(pts);
  float d2 = -1;
  EXPECT_EQ(tree.nearest({0.9f, 0.1f, 0}, &d2), 1u);
  EXPECT_NEAR(d2, 0.02f, 1e-6f);
  Neighbors nb;
  tree.knn({0, 0, 0}, 10, nb);  // more than available
  EXPECT_EQ(nb.size(), 3u);
  const std::vector<Vec3f> none;
  const KdTree empty(none);
  empty.radius({0, 0, 0}, 1.0f, nb);
  EXPECT_EQ(nb.size(), 0u);
  empty.knn({0, 0, 0}, 3, nb);
  EXPECT_EQ(nb.size(), 0u);
}
