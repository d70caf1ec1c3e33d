// The steps of segment-based global registration (registration/global_steps.hpp) on known
// answers, each alone: centroid matching, centroid hypotheses, the mutual overlap, the acceptance
// test, the refine-and-accept loop's choice and the merge of the registered objects.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "cairn/core/units.hpp"
#include "cairn/registration/global_steps.hpp"

namespace cairn::global_steps_test {

Eigen::Isometry3d yaw_shift(double yaw_deg, const Vec3d& t) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(yaw_deg * kDeg, Vec3d::UnitZ()).toRotationMatrix();
  T.translation() = t;
  return T;
}

std::vector<Vec3f> moved(const std::vector<Vec3f>& points, const Eigen::Isometry3d& T) {
  std::vector<Vec3f> out;
  for (const Vec3f& p : points) out.push_back((T * p.cast<double>()).cast<float>());
  return out;
}

/// Six centroids of an 8 m site, no two pairs of the same horizontal length.
std::vector<Vec3f> site_centroids() {
  return {{-3.0f, -2.5f, 0.3f}, {2.5f, -3.1f, 0.4f}, {0.4f, 3.0f, 0.35f},
          {-3.3f, 2.1f, 0.3f},  {3.6f, 1.2f, 0.5f},  {0.1f, 0.2f, 0.3f}};
}

TEST(MatchCentroids, PairsEachSourceCentroidWithItsNearestTargetOneToOne) {
  const std::vector<Vec3f> target = site_centroids();
  const Eigen::Isometry3d T = yaw_shift(30.0, {1.0, -2.0, 0.1});
  std::vector<Vec3f> source = moved(target, T.inverse());
  source[2] += Vec3f(0.3f, 0.0f, 0.0f);   // 0.3 m off: matched when d_match > 0.3
  source.push_back({20.0f, 20.0f, 0.0f});  // far from every target centroid: unmatched
  const CentroidMatch m = match_centroids(source, target, T, 0.5);
  EXPECT_EQ(m.inliers, 6);
  ASSERT_EQ(m.pairs.size(), 6u);
  for (std::size_t i = 0; i < m.pairs.size(); ++i) EXPECT_EQ(m.pairs[i], (std::pair<std::int32_t, std::int32_t>(std::int32_t(i), std::int32_t(i))));
  EXPECT_NEAR(m.max_distance, 0.3, 1e-5);
  EXPECT_EQ(match_centroids(source, target, T, 0.25).inliers, 5);  // the shifted one is out
  // One-to-one: two source centroids near the same target centroid take it once, the closer.
  const std::vector<Vec3f> two = {{0.0f, 0.0f, 0.0f}, {0.1f, 0.0f, 0.0f}};
  const std::vector<Vec3f> one = {{0.09f, 0.0f, 0.0f}};
  const CentroidMatch o = match_centroids(two, one, Eigen::Isometry3d::Identity(), 0.5);
  ASSERT_EQ(o.inliers, 1);
  EXPECT_EQ(o.pairs[0], (std::pair<std::int32_t, std::int32_t>(1, 0)));
}

TEST(CentroidHypotheses, TheBestRecoversTheYawAndTheTranslation) {
  const std::vector<Vec3f> target = site_centroids();
  const Eigen::Isometry3d truth = yaw_shift(-115.0, {4.0, 7.5, 0.0});
  const std::vector<Vec3f> source = moved(target, truth.inverse());
  GlobalRegistrationConfig cfg;
  const auto h = centroid_hypotheses(source, target, cfg);
  ASSERT_FALSE(h.empty());
  EXPECT_EQ(h.front().second.inliers, 6);
  EXPECT_LT((h.front().first.translation() - truth.translation()).norm(), 1e-4);
  EXPECT_LT(rotation_angle(h.front().first.linear().transpose() * truth.linear()), 1e-5);
  for (std::size_t k = 1; k < h.size(); ++k) {  // sorted, distinct
    EXPECT_LE(h[k].second.inliers, h[k - 1].second.inliers);
    EXPECT_GT((h[k].first.translation() - h.front().first.translation()).norm() +
                  rotation_angle(h[k].first.linear().transpose() * h.front().first.linear()),
              1e-3);
  }
  // Fewer centroids than the acceptance test needs: no hypothesis.
  cfg.acceptance.min_matched_segments = 7;
  EXPECT_TRUE(centroid_hypotheses(source, target, cfg).empty());
}

/// A 1 m x 1 m grid of points every 5 cm at height z.
std::vector<Vec3f> patch(float x0, float z) {
  std::vector<Vec3f> out;
  for (int i = 0; i <= 20; ++i)
    for (int j = 0; j <= 20; ++j) out.emplace_back(x0 + 0.05f * float(i), 0.05f * float(j), z);
  return out;
}

TEST(MutualOverlap, CountsThePointsWithACounterpartAndTheirRmse) {
  const std::vector<Vec3f> a = patch(0.0f, 0.0f);
  const Overlap same = mutual_overlap(a, a, Eigen::Isometry3d::Identity(), 0.05);
  EXPECT_DOUBLE_EQ(same.share, 1.0);
  EXPECT_NEAR(same.rmse, 0.0, 1e-9);
  // Lifted by 2 cm: everything overlaps at 2 cm.
  const Overlap lifted = mutual_overlap(a, patch(0.0f, 0.02f), Eigen::Isometry3d::Identity(), 0.05);
  EXPECT_DOUBLE_EQ(lifted.share, 1.0);
  EXPECT_NEAR(lifted.rmse, 0.02, 1e-6);
  // Half of the patch shifted away (0.5 m along x) and moved back by T: only the shared half
  // overlaps without T, all of it with T.
  const std::vector<Vec3f> b = patch(0.5f, 0.0f);
  const Overlap half = mutual_overlap(a, b, Eigen::Isometry3d::Identity(), 0.01);
  EXPECT_NEAR(half.share, 11.0 / 21.0, 1e-9);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Vec3d(0.5, 0.0, 0.0);
  EXPECT_DOUBLE_EQ(mutual_overlap(a, b, T, 0.01).share, 1.0);
  // Nothing within the distance: no overlap, an infinite RMSE.
  const Overlap none = mutual_overlap(a, patch(0.0f, 1.0f), Eigen::Isometry3d::Identity(), 0.05);
  EXPECT_EQ(none.share, 0.0);
  EXPECT_TRUE(std::isinf(none.rmse));
}

TEST(Acceptance, NeedsTheRmseTheOverlapAndEnoughMatchedSegments) {
  const RegistrationAcceptanceConfig c;  // e_icp 3 cm, min_overlap 0.45, 3 segments
  EXPECT_TRUE(passes_acceptance({.rmse = 0.02, .share = 0.6}, 3, c));
  EXPECT_FALSE(passes_acceptance({.rmse = 0.03, .share = 0.6}, 3, c));  // e_icp is strict
  EXPECT_TRUE(passes_acceptance({.rmse = 0.02, .share = 0.45}, 3, c));  // min_overlap is not
  EXPECT_FALSE(passes_acceptance({.rmse = 0.02, .share = 0.44}, 3, c));
  EXPECT_FALSE(passes_acceptance({.rmse = 0.02, .share = 0.6}, 2, c));
  EXPECT_TRUE(passes_acceptance({.rmse = 0.02, .share = 0.6}, std::nullopt, c));  // whole clouds
  EXPECT_FALSE(passes_acceptance({.rmse = std::numeric_limits<double>::infinity(), .share = 0.0}, std::nullopt, c));
}

/// Reports whose refinement gives the overlap in `shares` (rmse 1 cm) at rank k.
struct LoopFixture {
  std::vector<CandidateReport> reports;
  std::vector<double> shares;
  std::vector<std::size_t> refined_ranks;
  explicit LoopFixture(std::vector<double> s) : shares(std::move(s)) {
    for (std::size_t k = 0; k < shares.size(); ++k) {
      CandidateReport r;
      r.T_target_source = yaw_shift(10.0 * double(k), {double(k), 0.0, 0.0});  // distinct basins
      reports.push_back(r);
    }
  }
  std::optional<std::size_t> run(const RefineRule& rule, std::size_t eligible = 100) {
    int refined = 0;
    const auto result = refine_and_accept(
        reports, [&](std::size_t k) { return k < eligible; },
        [&](std::size_t k, const Eigen::Isometry3d& T0) {
          refined_ranks.push_back(k);
          return Refinement{.T = T0, .icp_rmse = 0.01, .overlap = {.rmse = 0.01, .share = shares[k]}, .matched = std::nullopt};
        },
        [](const Eigen::Isometry3d& T) { return T; }, RegistrationAcceptanceConfig{}, rule, refined);
    EXPECT_EQ(std::size_t(refined), refined_ranks.size());
    return result;
  }
};

TEST(RefineAndAccept, FirstAcceptedStopsTheLoopLargestOverlapRefinesAll) {
  {
    LoopFixture f({0.2, 0.5, 0.9, 0.6});
    EXPECT_EQ(f.run({.largest_overlap = false, .refine_all = false, .max_refinements = 10}), 1u);
    EXPECT_EQ(f.refined_ranks, (std::vector<std::size_t>{0, 1}));
    EXPECT_TRUE(f.reports[1].accepted && f.reports[1].refined);
    EXPECT_FALSE(f.reports[0].accepted);
    EXPECT_FALSE(f.reports[2].refined);
  }
  {
    LoopFixture f({0.2, 0.5, 0.9, 0.6});
    EXPECT_EQ(f.run({.largest_overlap = false, .refine_all = true, .max_refinements = 10}), 1u);  // first still wins
    EXPECT_EQ(f.refined_ranks.size(), 4u);
  }
  {
    LoopFixture f({0.2, 0.5, 0.9, 0.6});
    EXPECT_EQ(f.run({.largest_overlap = true, .refine_all = false, .max_refinements = 10}), 2u);
  }
  {
    LoopFixture f({0.2, 0.3, 0.9});
    EXPECT_EQ(f.run({.largest_overlap = true, .refine_all = false, .max_refinements = 2}), std::nullopt);
    EXPECT_EQ(f.refined_ranks.size(), 2u);  // max_refinements
  }
  {
    LoopFixture f({0.2, 0.3, 0.9});
    EXPECT_EQ(f.run({.largest_overlap = true, .refine_all = false, .max_refinements = 10}, 2), std::nullopt);
    EXPECT_EQ(f.refined_ranks.size(), 2u);  // not eligible from rank 2 on
  }
  {  // a candidate in the basin of an earlier one is not refined again
    LoopFixture f({0.2, 0.3, 0.9});
    f.reports[1].T_target_source = f.reports[0].T_target_source * yaw_shift(0.5, {0.05, 0.0, 0.0});
    EXPECT_EQ(f.run({.largest_overlap = true, .refine_all = false, .max_refinements = 10}), 2u);
    EXPECT_EQ(f.refined_ranks, (std::vector<std::size_t>{0, 2}));
  }
}

TEST(MergeObjects, MatchedPairsMergeTouchingPiecesJoinOthersStayApart) {
  // Source: segments 0 (1 m patch at x 0), 1 (a piece touching it at x 1.05), 2 (far away).
  // Target: segments 0 (the same patch as source 0), 1 (far away, unmatched).
  const std::vector<Vec3f> p0 = patch(0.0f, 0.0f), p1 = patch(1.05f, 0.0f), p2 = patch(10.0f, 0.0f);
  SegmentSet src, tgt;
  const auto add = [](SegmentSet& s, const std::vector<Vec3f>& pts, std::int32_t id) {
    s.ids.push_back(id);
    s.members.emplace_back();
    for (const Vec3f& p : pts) {
      s.members.back().push_back(std::uint32_t(s.points.size()));
      s.points.push_back(p);
    }
  };
  add(src, p0, 10);
  add(src, p1, 11);
  add(src, p2, 12);
  const Eigen::Isometry3d T = yaw_shift(0.0, {0.0, 0.0, 0.01});  // source 1 cm below the target
  add(tgt, moved(p0, T), 20);
  add(tgt, patch(-10.0f, 0.0f), 21);
  CentroidMatch m;
  m.pairs = {{0, 0}};
  m.inliers = 1;
  GlobalRegistrationConfig cfg;
  GlobalRegistrationResult r;
  merge_objects(src, tgt, m, T, Vec3d::Zero(), cfg, r);
  ASSERT_EQ(r.merged_segments.size(), 1u);
  ASSERT_EQ(r.objects.size(), 3u);
  EXPECT_EQ(r.objects[0].source_segment, 10);
  EXPECT_EQ(r.objects[0].target_segment, 20);
  EXPECT_EQ(r.objects[1].source_segment, 12);
  EXPECT_EQ(r.objects[1].target_segment, -1);
  EXPECT_EQ(r.objects[2].source_segment, -1);
  EXPECT_EQ(r.objects[2].target_segment, 21);
  // The merged pair lies where both are (voxelised), the touching piece joined it.
  float max_x = -1e9f;
  for (const Vec3f& p : r.objects[0].cloud.points) max_x = std::max(max_x, p.x());
  EXPECT_GT(max_x, 1.9f);
  float min_x = 1e9f;
  for (const Vec3f& p : r.merged_segments[0].points) min_x = std::min(min_x, p.x());
  EXPECT_LT(min_x, 0.05f);
  for (const Vec3f& p : r.merged_segments[0].points) EXPECT_LT(p.x(), 1.05f);
}

}  // namespace cairn::global_steps_test
