#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <set>

#include "cairn/core/error.hpp"
#include "cairn/segmentation/evaluation.hpp"
#include "cairn/segmentation/segmenter.hpp"
#include "cairn/sim/procedural_site.hpp"

using namespace cairn;


class ProceduralSiteSegmentation : public ::testing::TestWithParam<std::uint64_t> {};

// Issue: sloped, rough terrain with 7 irregular stones of 0.5–1 m³, ~3 cm spacing, σ = 1 cm noise:
// every stone is exactly one segment with >= 95 % of its points, and no segment is terrain.
TEST_P(ProceduralSiteSegmentation, EveryStoneIsOneCompleteSegment) {
  const std::uint64_t seed = GetParam();
  const sim::Site site = sim::generate_site({}, seed);
  const sim::SampledSite sampled = sim::sample_site(site, {}, seed);
  const SegmentationResult r = segment(sampled.cloud, {});
  const int n = int(site.stones.size());
  ASSERT_EQ(n, 7);
  const SegmentationScore e = score_segmentation(r.labels, sampled.truth, n);
  EXPECT_EQ(r.num_objects(), std::size_t(n)) << "seed " << seed;
  EXPECT_EQ(e.terrain_segments, 0u) << "seed " << seed;
  EXPECT_EQ(e.merged, 0u) << "seed " << seed << ": stones merged into one segment";
  for (int k = 0; k < n; ++k) {
    const ObjectScore& s = e.objects[std::size_t(k)];
    EXPECT_GE(s.completeness(), 0.95) << "seed " << seed << " stone " << k << (site.stones[k].flat ? " (flat)" : "");
    EXPECT_EQ(s.significant_segments, 1u) << "seed " << seed << " stone " << k << " is split";
    // Purity (share of the segment that is the stone), raw clouds, seeds 1–16: worst stone
    // 0.938, per-site mean 0.973–0.997 (docs/segmentation.md).
    EXPECT_GE(s.purity(), 0.9) << "seed " << seed << " stone " << k;
  }
  double mean_purity = 0;
  for (const auto& o : e.objects) mean_purity += o.purity() / double(n);
  EXPECT_GE(mean_purity, 0.95) << "seed " << seed;
  EXPECT_EQ(e.found(), std::size_t(n));
}

INSTANTIATE_TEST_SUITE_P(Seeds, ProceduralSiteSegmentation, ::testing::Values(1, 2, 3, 4, 5, 6, 7, 8));

TEST(Segmentation, SinglePlaneGroundFailsOnUndulatingTerrainWhereGridSucceeds) {
  // The paper's single RANSAC plane cannot follow a sloped site with 25 cm undulations: terrain
  // leaks into segments and stones merge with it. The local ground model handles it.
  for (const std::uint64_t seed : {11u, 13u}) {
    const sim::Site site = sim::generate_site({}, seed);
    const sim::SampledSite sampled = sim::sample_site(site, {}, seed);
    SegmentationConfig plane_cfg;
    plane_cfg.ground.method = "plane";
    const SegmentationScore plane = score_segmentation(segment(sampled.cloud, plane_cfg).labels, sampled.truth, 7);
    const SegmentationScore grid = score_segmentation(segment(sampled.cloud, {}).labels, sampled.truth, 7);
    EXPECT_EQ(grid.terrain_segments, 0u) << seed;
    EXPECT_EQ(grid.found(), 7u) << seed;
    EXPECT_GT(plane.terrain_segments, 0u) << seed;
    EXPECT_LT(plane.found(), 7u) << seed;
  }
}

TEST(Segmentation, SteeperUndulationsStillMostlyCorrect) {
  // ±35 cm undulations (3–8 m wavelengths): ridges as steep as stone flanks. Measured over 16
  // seeds: 14 fully correct; here 8 seeds must give at least 55 of 56 stones and at most one
  // terrain segment in all.
  std::size_t found = 0, terrain = 0;
  for (std::uint64_t seed = 1; seed <= 8; ++seed) {
    sim::SiteConfig cfg;
    cfg.terrain.bump_amplitude = 0.35;
    const sim::Site site = sim::generate_site(cfg, seed);
    const sim::SampledSite sampled = sim::sample_site(site, {}, seed);
    const SegmentationScore s = score_segmentation(segment(sampled.cloud, {}).labels, sampled.truth, 7);
    found += s.found();
    terrain += s.terrain_segments;
  }
  EXPECT_GE(found, 55u);
  EXPECT_LE(terrain, 1u);
}

TEST(Segmentation, TerrainRidgeWithoutSteepSidesIsGround) {
  // A smooth ridge the ground model would cut off is not an object: no stacked points.
  PointCloud c;
  for (int i = 0; i < 200; ++i)
    for (int j = 0; j < 200; ++j) {
      const float x = float(i) * 0.03f, y = float(j) * 0.03f;
      c.points.emplace_back(x, y, 0.8f * std::exp(-(x - 3) * (x - 3) / 0.3f));  // 0.8 m high, ~1.5 m wide
    }
  SegmentationConfig cfg;
  cfg.verticality.enabled = false;
  EXPECT_GE(segment(c, cfg).num_objects(), 1u);  // without the check, the ridge is an "object"
  const SegmentationResult r = segment(c, {});
  EXPECT_EQ(r.num_objects(), 0u);
  EXPECT_EQ(r.num_ground, c.size());
}

TEST(Segmentation, DeterministicForSeed) {
  const sim::Site site = sim::generate_site({}, 3);
  const sim::SampledSite sampled = sim::sample_site(site, {}, 3);
  EXPECT_EQ(segment(sampled.cloud, {}).labels, segment(sampled.cloud, {}).labels);
}

TEST(Segmentation, PlanarSegmentsAreDroppedAndListed) {
  // A flat ground, one wall (planar) and one ball (not planar).
  PointCloud c;
  for (int i = 0; i < 100; ++i)
    for (int j = 0; j < 100; ++j) c.points.emplace_back(i * 0.05f, j * 0.05f, 0.0f);
  for (int i = 0; i < 40; ++i)
    for (int j = 0; j < 30; ++j) c.points.emplace_back(1.0f, 2.0f + i * 0.03f, 0.2f + j * 0.03f);
  for (int i = 0; i < 2000; ++i) {
    const float t = float(i) * 2.39996f, z = 1.0f - 2.0f * (float(i) + 0.5f) / 2000.0f, r = std::sqrt(1 - z * z);
    c.points.emplace_back(3.5f + 0.4f * r * std::cos(t), 3.5f + 0.4f * r * std::sin(t), 0.6f + 0.4f * z);
  }
  const SegmentationResult r = segment(c, {});
  ASSERT_EQ(r.num_objects(), 1u);
  ASSERT_EQ(r.segments.size(), 2u);
  EXPECT_TRUE(r.segments[1].planar);
  EXPECT_NEAR(r.segments[0].centroid.x(), 3.5f, 0.05f);
  for (auto i : r.segments[1].indices) EXPECT_EQ(r.labels[i], kLabelNone);
  EXPECT_EQ(r.labels[0], kLabelGround);
  EXPECT_GT(std::abs(r.ground_plane.normal.z()), 0.999f);
}

TEST(Segmentation, BadInputIsAnError) {
  EXPECT_THROW((void)segment(PointCloud{}, {}), InputError);
  PointCloud c;
  c.points = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {std::nanf(""), 0, 0}};
  EXPECT_THROW((void)segment(c, {}), InputError);
  c.points.pop_back();
  SegmentationConfig cfg;
  cfg.ground.method = "magic";
  EXPECT_THROW((void)segment(c, cfg), ConfigError);
}

TEST(Segmentation, TransferLabelsTakesTheNearestReferenceLabelWithinTheDistance) {
  PointCloud reference;
  reference.origin = Vec3d(100.0, 0.0, 0.0);  // origins differ: world coordinates are compared
  reference.points = {Vec3f(0, 0, 0), Vec3f(1, 0, 0), Vec3f(2, 0, 0)};
  reference.labels = {-1, 4, 7};
  PointCloud points;
  points.origin = Vec3d(99.0, 0.0, 0.0);
  points.points = {Vec3f(1.02f, 0, 0), Vec3f(2.04f, 0, 0), Vec3f(3.0f, 0.03f, 0), Vec3f(10.0f, 0, 0)};
  const std::vector<std::int32_t> l = transfer_labels(reference, points, 0.05);
  EXPECT_EQ(l, (std::vector<std::int32_t>{-1, 4, 7, -2}));
  EXPECT_EQ(transfer_labels(reference, points, 0.05, -9).back(), -9);
  PointCloud unlabelled = reference;
  unlabelled.labels.clear();
  EXPECT_THROW((void)transfer_labels(unlabelled, points, 0.05), InputError);
}

TEST(Segmentation, BinaryScoreCountsAgainstTheTruth) {
  //                                       tp tp fp fn fn tn
  const std::vector<std::uint8_t> predicted{1, 1, 1, 0, 0, 0};
  const std::vector<std::uint8_t> truth{1, 1, 0, 1, 1, 0};
  const BinaryScore s = score_binary(predicted, truth);
  EXPECT_EQ(s.true_positive, 2u);
  EXPECT_EQ(s.false_positive, 1u);
  EXPECT_EQ(s.false_negative, 2u);
  EXPECT_EQ(s.true_negative, 1u);
  EXPECT_DOUBLE_EQ(s.precision(), 2.0 / 3.0);
  EXPECT_DOUBLE_EQ(s.recall(), 0.5);
  EXPECT_DOUBLE_EQ(s.f1(), 2 * (2.0 / 3.0) * 0.5 / (2.0 / 3.0 + 0.5));
  const BinaryScore none = score_binary({0, 0}, {0, 0});
  EXPECT_EQ(none.precision(), 0.0);
  EXPECT_EQ(none.f1(), 0.0);
  EXPECT_THROW((void)score_binary({1}, {1, 0}), InputError);
}

// score_segmentation, which every segmentation acceptance test counts with, on a hand-made
// labelling whose answer is known: a stone found (a 4 % crumb elsewhere is not a second segment),
// a stone cut in two, two stones merged into one segment, a stone no segment holds, a terrain
// segment, and truth values outside [0, num_objects) counted as terrain.
TEST(Segmentation, ScoreSegmentationKnownAnswers) {
  std::vector<std::int32_t> labels, truth;
  const auto add = [&](std::int32_t object, std::int32_t segment, int n) {
    for (int i = 0; i < n; ++i) truth.push_back(object), labels.push_back(segment);
  };
  add(0, 10, 96);  // stone 0: 96 % in segment 10 ...
  add(0, 11, 4);   // ... and a 4 % crumb (below split_fraction 5 %) in segment 11
  add(-1, 10, 2);  // terrain in segment 10: purity 96 / 98
  add(1, 20, 60);  // stone 1 cut in two: 60 / 40
  add(1, 21, 40);
  add(2, 30, 50);  // stones 2 and 3 merged in segment 30
  add(3, 30, 50);
  add(4, -1, 30);  // stone 4: seen by no segment
  add(-1, 40, 150);  // a terrain segment ...
  add(9, 40, 5);     // ... with points of an "object" beyond num_objects: terrain too
  add(-1, -1, 500);  // unsegmented terrain
  const SegmentationScore s = score_segmentation(labels, truth, 5);
  ASSERT_EQ(s.objects.size(), 5u);
  EXPECT_EQ(s.segments, 6u);  // 10, 11, 20, 21, 30, 40
  EXPECT_EQ(s.terrain_segments, 1u);
  EXPECT_EQ(s.merged, 1u);
  const ObjectScore& o0 = s.objects[0];
  EXPECT_EQ(o0.points, 100u);
  EXPECT_EQ(o0.best_segment, 10);
  EXPECT_EQ(o0.best_overlap, 96u);
  EXPECT_EQ(o0.significant_segments, 1u);
  EXPECT_EQ(o0.segment_points, 98u);
  EXPECT_DOUBLE_EQ(o0.completeness(), 0.96);
  EXPECT_DOUBLE_EQ(o0.purity(), 96.0 / 98.0);
  EXPECT_EQ(s.objects[1].best_segment, 20);
  EXPECT_EQ(s.objects[1].significant_segments, 2u);
  EXPECT_DOUBLE_EQ(s.objects[1].completeness(), 0.6);
  EXPECT_DOUBLE_EQ(s.objects[2].completeness(), 1.0);
  EXPECT_DOUBLE_EQ(s.objects[2].purity(), 0.5);
  EXPECT_EQ(s.objects[4].best_segment, -1);
  EXPECT_EQ(s.objects[4].completeness(), 0.0);
  EXPECT_EQ(s.objects[4].purity(), 0.0);
  // Found: one segment, >= 95 % complete, not shared: stone 0 only (the crumb does not count);
  // at 0.97 not even it. Single (piles): >= 90 % complete and pure: stone 0; the merged stones are
  // complete but half pure.
  EXPECT_EQ(s.found(), 1u);
  EXPECT_EQ(s.found(0.97), 0u);
  EXPECT_EQ(s.single(), 1u);
  EXPECT_EQ(s.single(0.9, 0.5), 3u);  // stones 0, 2 and 3
  const nlohmann::json j = s.to_json();
  EXPECT_EQ(j.at("found").get<int>(), 1);
  EXPECT_EQ(j.at("merged_segments").get<int>(), 1);
  EXPECT_EQ(j.at("completeness").size(), 5u);
  labels.pop_back();
  EXPECT_THROW((void)score_segmentation(labels, truth, 5), InputError);
}

// SMRF's slope term (GroundConfig::slope_height): on a plane rising 1 m per metre the ground band
// is d_plane + slope_height × 1 (away from the border, where the filter's windows are cut), so
// points 0.3 m above the 45° slope are ground with it and not without; on flat ground the band
// stays d_plane. The surface itself is exact there although each 1 m cell's lowest point lies on
// its downhill edge (too few points for the cell's own fit: the plane through its neighbours'
// lowest points gives its centre).
TEST(Segmentation, GroundBandWidensWithTheSurfaceSlope) {
  std::vector<Vec3f> slope_pts, flat_pts;
  for (int i = 0; i < 40; ++i)
    for (int j = 0; j < 40; ++j) {
      const float x = 0.5f * float(i), y = 0.5f * float(j);  // 4 points per cell: sparse, as from the air
      const float lift = (i + j) % 7 == 0 ? 0.3f : 0.0f;  // a few points 0.3 m above the surface
      slope_pts.emplace_back(x, y, x + lift);
      flat_pts.emplace_back(x, y, lift);
    }
  GroundConfig c;
  c.cell_size = 1.0;
  c.d_plane = 0.1;
  c.slope = 1.5;  // the filter keeps 45° terrain
  std::mt19937_64 rng(1);
  const auto count_ground = [](const GroundResult& r) {
    std::size_t n = 0;
    for (std::size_t i = 0; i < r.height.size(); ++i) n += r.is_ground(i);
    return n;
  };
  const GroundResult narrow = estimate_ground(slope_pts, c, rng);
  c.slope_height = 0.5;
  const GroundResult wide = estimate_ground(slope_pts, c, rng);
  const GroundResult flat = estimate_ground(flat_pts, c, rng);
  EXPECT_TRUE(narrow.widening.empty());  // slope_height 0: d_plane everywhere, as before
  for (std::size_t i = 0; i < slope_pts.size(); ++i) {
    EXPECT_NEAR(flat.band(i), 0.1, 1e-6) << i;
    EXPECT_EQ(narrow.band(i), 0.1) << i;
    const Vec3f& p = slope_pts[i];
    if (std::min({p.x(), p.y(), 19.5f - p.x(), 19.5f - p.y()}) < 3.0f) continue;  // border
    EXPECT_NEAR(wide.band(i), 0.1 + 0.5 * 1.0, 0.02) << i;
    EXPECT_NEAR(narrow.height[i], p.z() - p.x(), 0.02) << i;  // 0, or 0.3 for the lifted points
    EXPECT_TRUE(wide.is_ground(i)) << i;
  }
  EXPECT_GT(count_ground(wide), count_ground(narrow));
  EXPECT_LT(count_ground(narrow), slope_pts.size() * 9 / 10);
  EXPECT_LT(count_ground(flat), flat_pts.size() * 9 / 10);
  c.slope_height = -1;
  EXPECT_THROW((void)estimate_ground(slope_pts, c, rng), ConfigError);
}

// Refinement (GroundConfig::refine_iterations): a mound 6 m high with 45° flanks and an 8 m top is
// terrain, but windows that tolerate only 0.3 rise per run take its top for an object (as they
// would a building's roof). Cells whose lowest point lies in the ground band of the surface around them
// rejoin the terrain round by round, up the flank and onto the top.
TEST(Segmentation, RefinementTakesBackTheHillTheWindowsCutOff) {
  const auto hill = [](float x) { return std::clamp(std::min(x - 10.0f, 30.0f - x), 0.0f, 6.0f); };
  std::vector<Vec3f> pts;
  for (int i = 0; i < 100; ++i)
    for (int j = 0; j < 40; ++j) pts.emplace_back(0.5f * float(i), 0.5f * float(j), hill(0.5f * float(i)));
  GroundConfig c;  // an airborne-like configuration (config/airborne_terrain.yaml)
  c.cell_size = 1.0;
  c.max_window = 40.0;
  c.slope = 0.3;
  c.initial_height = 0.5;
  c.max_height = 6.0;
  c.d_plane = 0.5;
  c.slope_height = 0.5;
  std::mt19937_64 rng(1);
  const auto share_on_hill = [&](const GroundResult& r) {
    std::size_t n = 0, ground = 0;
    for (std::size_t i = 0; i < pts.size(); ++i)
      if (pts[i].z() > 1.0f) ++n, ground += r.is_ground(i);
    return double(ground) / double(n);
  };
  const double once = share_on_hill(estimate_ground(pts, c, rng));
  c.refine_iterations = 20;
  const GroundResult refined = estimate_ground(pts, c, rng);
  std::printf("hill points that are ground: %.2f without refinement, %.2f with\n", once, share_on_hill(refined));
  EXPECT_LT(once, 0.5);
  EXPECT_GT(share_on_hill(refined), 0.99);
  for (std::size_t i = 0; i < pts.size(); ++i) EXPECT_TRUE(refined.is_ground(i)) << pts[i].transpose();
}

// A sparse cell whose neighbours' lowest points lie on a line (a one-point-wide strip, e.g. a
// single scan line) has no plane across it: it keeps its own lowest point instead of a plane
// extrapolated across the strip, whose tilt the 1 cm noise would set.
TEST(Segmentation, SparseCellsOnALineKeepTheirLowestPoint) {
  std::mt19937 rng(2);
  std::normal_distribution<float> noise(0.0f, 0.01f);
  std::vector<Vec3f> pts;
  for (int i = 0; i < 41; ++i) pts.emplace_back(0.5f * float(i), 0.3f, noise(rng));
  pts.emplace_back(0.0f, 0.9f, 0.0f);  // the grid one cell deep: centres 0.2 m off the line
  GroundConfig c;
  c.cell_size = 1.0;
  std::mt19937_64 gen(1);
  const GroundResult r = estimate_ground(pts, c, gen);
  for (std::size_t i = 0; i < pts.size(); ++i) {
    EXPECT_LT(std::abs(r.height[i]), 0.05f) << i;
    EXPECT_TRUE(r.is_ground(i)) << i;
  }
}
