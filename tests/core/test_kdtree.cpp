#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
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

// nearest_within is nearest() cut at a bound: the same index and distance whenever the nearest
// point is within it (ties between duplicated points resolved alike), +inf otherwise. Every
// threshold caller (ICP, the scale check, map edits, association) relies on that equality.
TEST(KdTree, NearestWithinIsNearestCutAtTheBound) {
  auto finite = random_points(4000, 5);
  for (std::size_t i = 0; i < 400; ++i) finite.push_back(finite[i * 7]);  // exact duplicates: ties
  auto with_nan = finite;
  with_nan.push_back(Vec3f(std::nanf(""), 0, 0));  // never found (the tree indexes a compact copy)
  const auto queries = random_points(500, 6);
  for (const auto* pts : {&finite, &with_nan}) {
    const KdTree tree(*pts);
    std::size_t inside = 0, outside = 0;
    for (const float bound : {0.0f, 1e-4f, 2.5e-3f, 0.01f, 1.0f}) {
      for (std::size_t k = 0; k < queries.size(); ++k) {
        const Vec3f q = k % 5 == 0 ? (*pts)[k] : queries[k];  // some queries on points: distance 0
        float d_all = -1.0f, d_cut = -1.0f;
        const std::uint32_t i_all = tree.nearest(q, &d_all);
        const std::uint32_t i_cut = tree.nearest_within(q, bound, &d_cut);
        if (d_all <= bound) {
          ++inside;
          EXPECT_EQ(i_cut, i_all);
          EXPECT_EQ(d_cut, d_all);
        } else {
          ++outside;
          EXPECT_TRUE(std::isinf(d_cut));
        }
      }
    }
    EXPECT_GT(inside, 300u);
    EXPECT_GT(outside, 300u);
    // A point exactly at the bound is found (the bound is inclusive, as the callers' tests are).
    float d = -1.0f;
    const Vec3f q = (*pts)[3] + Vec3f(0.0f, 0.0f, 0.01f);
    const float exact = ((*pts)[tree.nearest(q)] - q).squaredNorm();
    EXPECT_EQ(tree.nearest_within(q, exact, &d), tree.nearest(q));
    EXPECT_EQ(d, exact);
    (void)tree.nearest_within({std::nanf(""), 0, 0}, 1.0f, &d);  // a NaN query finds nothing
    EXPECT_TRUE(std::isinf(d));
    (void)tree.nearest_within(queries[0], -1.0f, &d);  // nor a negative bound
    EXPECT_TRUE(std::isinf(d));
  }
  float d = 0.0f;
  const std::vector<Vec3f> none;
  (void)KdTree(none).nearest_within({0, 0, 0}, 1.0f, &d);
  EXPECT_TRUE(std::isinf(d));
}

TEST(KdTree, SqDistBoundIsTheSmallestFloatNotBelowTheSquare) {
  for (const double r : {0.03, 0.05, 0.1, 0.15, 0.4, 1.0 / 3.0, 2.5}) {
    const float b = sq_dist_bound(r);
    EXPECT_GE(double(b), r * r) << r;
    EXPECT_LT(double(std::nextafter(b, 0.0f)), r * r) << r;
  }
}
