// Geometric consistency grouping (Sec. 4.4 step 4) on synthetic correspondences with a known
// transform.
#include <gtest/gtest.h>

#include <random>

#include "cairn/core/error.hpp"
#include "cairn/core/transform.hpp"
#include "cairn/registration/consistency_grouping.hpp"
#include "shapes.hpp"
#include "cairn/core/units.hpp"

using namespace cairn;

namespace {

using cairn::kDeg;

struct Problem {
  std::vector<Vec3f> source, target;
  std::vector<Correspondence> matches;
  std::vector<bool> inlier;  // per match
};

/// n_in true pairs (target = T * source) and n_out random pairs, shuffled; random descriptor
/// distances (inliers are not favoured).
Problem make_problem(const Eigen::Isometry3d& T, int n_in, int n_out, std::uint32_t seed, float extent = 4.0f) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-0.5f * extent, 0.5f * extent), dist(0.0f, 0.25f);
  Problem p;
  for (int i = 0; i < n_in + n_out; ++i) {
    const Vec3f s(u(rng), u(rng), 0.3f * u(rng));
    p.source.push_back(s);
    p.target.push_back(i < n_in ? (T * s.cast<double>()).cast<float>() : Vec3f(u(rng), u(rng), 0.3f * u(rng)));
  }
  std::vector<std::uint32_t> order(p.source.size());
  std::iota(order.begin(), order.end(), 0u);
  std::shuffle(order.begin(), order.end(), rng);
  for (auto i : order) {
    p.matches.push_back({i, i, dist(rng)});
    p.inlier.push_back(int(i) < n_in);
  }
  return p;
}

}  // namespace

TEST(Grouping, RecoversTransformWithMajorityOutliers) {
  const Eigen::Isometry3d T = test::make_pose(5 * kDeg, -10 * kDeg, 75 * kDeg, {1.5, -0.7, 0.2});
  for (std::uint32_t seed : {1u, 2u, 3u}) {
    const Problem p = make_problem(T, 60, 140, seed);  // 70 % outliers
    const auto c = geometric_consistency_grouping(p.source, p.target, p.matches, {});
    ASSERT_FALSE(c.empty());
    const Eigen::Isometry3d d = T.inverse() * c[0].T_target_source;
    const double angle = rotation_angle(d.linear()) / kDeg;
    EXPECT_LT(angle, 0.1) << "seed " << seed;
    EXPECT_LT(d.translation().norm(), 1e-3) << "seed " << seed;
    EXPECT_GE(c[0].votes, 60u);
    EXPECT_GE(c[0].inliers.size(), 60u);
    for (const auto& m : c[0].inliers) EXPECT_LT(m.source, 60u) << "an outlier survived the refit";
    EXPECT_LT(c[0].rms, 1e-5);
    for (std::size_t k = 1; k < c.size(); ++k) EXPECT_GE(c[k - 1].votes, c[k].votes);
  }
}

TEST(Grouping, NoisyKeypoints) {
  const Eigen::Isometry3d T = test::make_pose(-20 * kDeg, 3 * kDeg, -140 * kDeg, {-2.0, 0.4, 1.0});
  Problem p = make_problem(T, 150, 150, 4);
  std::mt19937 rng(5);
  std::normal_distribution<float> g(0.0f, 0.003f);  // 3 mm keypoint noise
  for (auto& t : p.target) t += Vec3f(g(rng), g(rng), g(rng));
  const auto c = geometric_consistency_grouping(p.source, p.target, p.matches, {});
  ASSERT_FALSE(c.empty());
  const Eigen::Isometry3d d = T.inverse() * c[0].T_target_source;
  EXPECT_LT(rotation_angle(d.linear()) / kDeg, 0.3);
  EXPECT_LT(d.translation().norm(), 5e-3);
}

TEST(Grouping, KeepsTheMostVotedCandidates) {
  // Five objects: separate groups of 8..16 pairs, each with its own transform, far apart.
  Problem p;
  for (int g = 0; g < 5; ++g) {
    const Eigen::Isometry3d T = test::make_pose(0.1 * g, 0.2, 0.3 * g, {10.0 * g, 0, 0});
    const Problem q = make_problem(T, 8 + 2 * g, 0, 10u + std::uint32_t(g), 1.0f);
    const auto base = std::uint32_t(p.source.size());
    for (std::size_t i = 0; i < q.source.size(); ++i) {
      p.source.push_back(q.source[i] + Vec3f(0, 10.0f * float(g), 0));
      p.target.push_back((T * (q.source[i] + Vec3f(0, 10.0f * float(g), 0)).cast<double>()).cast<float>());
    }
    for (const auto& m : q.matches) p.matches.push_back({base + m.source, base + m.target, m.squared_distance});
  }
  const auto all = geometric_consistency_grouping(p.source, p.target, p.matches, {.max_candidates = 100});
  ASSERT_EQ(all.size(), 5u);
  for (std::size_t k = 0; k < all.size(); ++k) EXPECT_EQ(all[k].votes, std::size_t(16 - 2 * k));
  const auto top3 = geometric_consistency_grouping(p.source, p.target, p.matches, {.max_candidates = 3});
  ASSERT_EQ(top3.size(), 3u);
  EXPECT_EQ(top3[0].votes, 16u);
  EXPECT_EQ(top3[2].votes, 12u);
  // min_votes is PCL's gc_threshold: a cluster needs MORE pairs than it.
  EXPECT_EQ(geometric_consistency_grouping(p.source, p.target, p.matches, {.min_votes = 14}).size(), 1u);
  EXPECT_EQ(geometric_consistency_grouping(p.source, p.target, p.matches, {.min_votes = 13}).size(), 2u);
}

TEST(Grouping, EmptyAndBadInput) {
  const std::vector<Vec3f> none;
  EXPECT_TRUE(geometric_consistency_grouping(none, none, {}, {}).empty());
  const std::vector<Vec3f> pts = {Vec3f(0, 0, 0), Vec3f(1, 0, 0)};
  const std::vector<Correspondence> bad = {{0, 5, 0.1f}};
  EXPECT_THROW((void)geometric_consistency_grouping(pts, pts, bad, {}), InputError);
  EXPECT_THROW((void)geometric_consistency_grouping(pts, pts, {}, {.consensus_size = 0.0}), ConfigError);
  EXPECT_THROW((void)geometric_consistency_grouping(pts, pts, {}, {.max_candidates = 0}), ConfigError);
  // Collinear keypoints: a consistent cluster but no unique rotation -> no candidate.
  std::vector<Vec3f> line;
  std::vector<Correspondence> m;
  for (std::uint32_t i = 0; i < 10; ++i) {
    line.push_back(Vec3f(0.1f * float(i), 0, 0));
    m.push_back({i, i, 0.01f});
  }
  EXPECT_EQ(consistency_clusters(line, line, m, {}).size(), 1u);
  EXPECT_TRUE(geometric_consistency_grouping(line, line, m, {}).empty());
}
