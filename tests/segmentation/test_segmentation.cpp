#include <gtest/gtest.h>

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
