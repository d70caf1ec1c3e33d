// Piles of touching stones (issue #21): the seam splitting of segmentation/split.hpp on hand-made
// clusters and on the simulator's pile scenario; spread sites are never split.
#include <gtest/gtest.h>

#include <cmath>
#include <algorithm>
#include <cstdlib>
#include <map>
#include <optional>
#include <random>
#include <string>

#include "cairn/core/error.hpp"
#include "cairn/segmentation/evaluation.hpp"
#include "cairn/segmentation/segmenter.hpp"
#include "cairn/sim/procedural_site.hpp"
#include "cairn/sim/simulation.hpp"

using namespace cairn;

namespace {

constexpr double kGroundHalfWidth = 3.0;  // [m] flat ground around the hand-made stones
constexpr double kSpacing = 0.03;         // [m] point spacing of the hand-made clouds

struct Ball {
  Eigen::Vector3d centre;
  double radius;
};

/// Flat ground at z = 0 plus the visible surface (above the ground, outside the other balls) of
/// each ball, σ = 1 cm noise; truth = ball index, -1 ground. Balls sunk ~10 cm into the ground,
/// as the simulator's stones: a ball touching the ground at one point has a rim lower than the
/// ground margin d_plane, which no segmentation can tell from the ground. (The simulator's
/// scenario stones rest on the ground since they are settled in the physics; the unsettled
/// generator sinks them by embed_depth.)
sim::SampledSite balls_on_ground(const std::vector<Ball>& balls, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<float> noise(0.0f, 0.01f);
  sim::SampledSite s;
  const auto inside_other = [&](const Eigen::Vector3d& p, std::size_t self) {
    for (std::size_t k = 0; k < balls.size(); ++k)
      if (k != self && (p - balls[k].centre).norm() < balls[k].radius) return true;
    return false;
  };
  const auto add = [&](const Eigen::Vector3d& p, std::int32_t label) {
    s.cloud.points.emplace_back(p.cast<float>() + Vec3f(noise(rng), noise(rng), noise(rng)));
    s.truth.push_back(label);
  };
  for (double x = -kGroundHalfWidth; x <= kGroundHalfWidth + 2.0; x += kSpacing)
    for (double y = -kGroundHalfWidth; y <= kGroundHalfWidth; y += kSpacing)
      if (!inside_other({x, y, 0.0}, balls.size())) add({x, y, 0.0}, -1);
  for (std::size_t k = 0; k < balls.size(); ++k) {
    const Ball& b = balls[k];
    const int n = int(4.0 * M_PI * b.radius * b.radius / (kSpacing * kSpacing));
    for (int i = 0; i < n; ++i) {  // Fibonacci sphere
      const double z = 1.0 - 2.0 * (i + 0.5) / n, r = std::sqrt(1.0 - z * z), phi = i * M_PI * (3.0 - std::sqrt(5.0));
      const Eigen::Vector3d p = b.centre + b.radius * Eigen::Vector3d(r * std::cos(phi), r * std::sin(phi), z);
      if (p.z() > 0.0 && !inside_other(p, k)) add(p, std::int32_t(k));
    }
  }
  s.cloud.labels = s.truth;
  return s;
}

/// The simulator's pile scenario (procedural and, when found, real stone shapes) on a 12 m site,
/// sampled with the visibility of the machine's ring of viewpoints and the drone.
struct PileSite {
  sim::Site site;
  sim::SampledSite sampled;
};
PileSite pile_site(std::uint64_t seed, const std::string& scenario = "pile") {
  sim::SimulationConfig c = sim::scenario_config(scenario, sim::default_real_mesh_dir());
  if (scenario == "pile") c.site.terrain.size_x = c.site.terrain.size_y = 12.0;  // the pile's surroundings
  PileSite p{sim::make_site(c, seed), {}};
  p.sampled = sim::sample_site(p.site, {}, seed);
  return p;
}

/// The site's segmentation as the paper's (no splitting of touching stones), scored.
SegmentationScore score_without_splitting(const PileSite& p) {
  SegmentationConfig off;
  off.split.enabled = false;
  return score_segmentation(segment(p.sampled.cloud, off).labels, p.sampled.truth, int(p.site.stones.size()));
}

/// The site, or none when it cannot be made (printed; before 2026-12-07 some spread seeds jammed).
std::optional<PileSite> try_pile_site(std::uint64_t seed, const std::string& scenario) {
  try {
    return pile_site(seed, scenario);
  } catch (const ConfigError& e) {
    std::printf("%s seed %llu: no site (%s)\n", scenario.c_str(), static_cast<unsigned long long>(seed), e.what());
    return std::nullopt;
  }
}

/// Seeds of the study tests: `CAIRN_STUDY_SEEDS=first-last` replaces them (tuned on 1-6 and
/// 101-140; the figures of docs/segmentation.md on fresh seeds 201-300).
std::vector<std::uint64_t> study_seeds(std::uint64_t first, std::uint64_t last) {
  if (const char* env = std::getenv("CAIRN_STUDY_SEEDS")) {
    const std::string s(env);
    const auto dash = s.find('-');
    first = std::stoull(s.substr(0, dash));
    last = dash == std::string::npos ? first : std::stoull(s.substr(dash + 1));
  }
#if defined(__SANITIZE_ADDRESS__)
  else last = first;  // the path once under the sanitizers; the figures in Release
#endif
  std::vector<std::uint64_t> seeds;
  for (auto k = first; k <= last; ++k) seeds.push_back(k);
  return seeds;
}

}  // namespace

TEST(SplitTouchingStones, TwoTouchingBallsAreTwoSegments) {
  const auto s = balls_on_ground({{{0.0, 0.0, 0.4}, 0.5}, {{0.98, 0.0, 0.35}, 0.5}}, 1);
  const SegmentationResult r = segment(s.cloud, {});
  const SegmentationScore e = score_segmentation(r.labels, s.truth, 2);
  EXPECT_EQ(r.num_objects(), 2u);
  // Each ball's segment holds >= 85 % of it (the rest: its rim within d_plane of the ground,
  // ~6 %, and voxels at the seam) and is >= 90 % that ball (the purity for piles).
  EXPECT_EQ(e.single(0.85, 0.9), 2u);
  for (const Segment& seg : r.segments) {
    EXPECT_TRUE(seg.split);
    EXPECT_GT(seg.seam_depth, 0.2) << "two balls of 1 m meet well below their tops";
  }
  SegmentationConfig off;
  off.split.enabled = false;
  EXPECT_EQ(segment(s.cloud, off).num_objects(), 1u) << "without splitting the balls are one cluster";
}

TEST(SplitTouchingStones, ThreeStonesInARowAreThreeSegments) {
  const auto s = balls_on_ground({{{0.0, 0.0, 0.3}, 0.45}, {{0.85, 0.1, 0.4}, 0.45}, {{1.7, 0.0, 0.25}, 0.5}}, 2);
  const SegmentationResult r = segment(s.cloud, {});
  const SegmentationScore e = score_segmentation(r.labels, s.truth, 3);
  EXPECT_EQ(r.num_objects(), 3u);
  EXPECT_EQ(e.single(0.85, 0.9), 3u);
}

TEST(SplitTouchingStones, OneLumpyStoneIsNeverSplit) {
  // One stone per site, procedural (round and flat) and real shapes: the bumps of one stone are
  // shallower than min_seam_depth, so the splitting leaves it whole.
  sim::SiteConfig c = sim::scenario_config("exp1", sim::default_real_mesh_dir()).site;
  c.terrain.size_x = c.terrain.size_y = 8.0;
  c.stones.count = 1;
  c.stones.keep_out_radius = 0.0;
  c.stones.placement_radius = 1.0;
  c.stones.real_fraction = 0.5;
  for (std::uint64_t seed = 1; seed <= 12; ++seed) {
    const sim::Site site = sim::generate_site(c, seed);
    const sim::SampledSite s = sim::sample_site(site, {}, seed);
    const SegmentationResult r = segment(s.cloud, {});
    EXPECT_EQ(r.num_objects(), 1u) << "seed " << seed << " (" << site.stones[0].source
                                   << (site.stones[0].flat ? ", flat" : "") << ")";
    for (const Segment& seg : r.segments) EXPECT_FALSE(seg.split) << "seed " << seed;
  }
}

TEST(SplitTouchingStones, BadConfigurationIsAnError) {
  const auto s = balls_on_ground({{{0.0, 0.0, 0.5}, 0.5}}, 3);
  SegmentationConfig c;
  c.split.voxel_size = 0.0;
  EXPECT_THROW((void)segment(s.cloud, c), ConfigError);
  c = {};
  c.split.min_seam_depth = std::nan("");
  EXPECT_THROW((void)segment(s.cloud, c), ConfigError);
}

// Issue #21: on the pile scenario >= 90 % of the stones are single (one segment holding >= 90 %
// of the stone's points, >= 90 % pure), over many seeds.
TEST(PileSegmentation, MostStonesOfAPileAreSingleSegments) {
  std::size_t stones = 0, single = 0, single_unsplit = 0;
  for (const std::uint64_t seed : study_seeds(1, 6)) {
    const PileSite p = pile_site(seed);
    const int n = int(p.site.stones.size());
    const SegmentationResult seg = segment(p.sampled.cloud, {});
    const SegmentationScore e = score_segmentation(seg.labels, p.sampled.truth, n);
    const SegmentationScore before = score_without_splitting(p);
    stones += std::size_t(n);
    single += e.single();
    single_unsplit += before.single();
    std::printf("pile seed %3llu: %zu/%d single (%zu without splitting); completeness/purity:",
                static_cast<unsigned long long>(seed), e.single(), n, before.single());
    for (const ObjectScore& o : e.objects) std::printf(" %.2f/%.2f", o.completeness(), o.purity());
    std::printf("\n");
  }
  std::printf("pile: %zu of %zu stones single (%.1f %%), %zu without splitting\n", single, stones,
              100.0 * double(single) / double(stones), single_unsplit);
  EXPECT_GE(double(single), 0.9 * double(stones));
}

/// Where stone k's points went: each segment's share of them and what the rest of that segment is.
void print_shares(int k, const std::vector<std::int32_t>& labels, const std::vector<std::int32_t>& truth) {
  std::map<std::int32_t, std::size_t> mine;
  std::map<std::int32_t, std::map<std::int32_t, std::size_t>> content;  // segment -> truth -> points
  std::size_t total = 0;
  for (std::size_t i = 0; i < labels.size(); ++i) {
    content[labels[i]][truth[i]]++;
    if (truth[i] == k) ++mine[labels[i]], ++total;
  }
  for (const auto& [segment, count] : mine) {
    if (count * 20 < total) continue;
    std::printf("  stone %d: %.1f %% in segment %d, which holds", k, 100.0 * double(count) / double(total), segment);
    for (const auto& [t, c] : content[segment]) std::printf(" %zu of %d", c, t);
    std::printf("\n");
  }
}

// Issue #21: spread sites stay as they were — no stone split, no stones merged.
TEST(PileSegmentation, SpreadSitesAreNotSplit) {
  for (const std::string scenario : {"exp1", "exp2"})
    for (const std::uint64_t seed : study_seeds(1, 3)) {
      const std::optional<PileSite> site = try_pile_site(seed, scenario);
      if (!site) continue;
      const PileSite& p = *site;
      const int n = int(p.site.stones.size());
      const SegmentationResult r = segment(p.sampled.cloud, {});
      const SegmentationScore e = score_segmentation(r.labels, p.sampled.truth, n);
      const SegmentationScore before = score_without_splitting(p);
      std::size_t split = 0;
      for (const Segment& s : r.segments) split += s.split;
      std::printf("%s seed %llu: %zu/%d found (%zu without splitting), %zu split parts\n", scenario.c_str(),
                  static_cast<unsigned long long>(seed), e.found(), n, before.found(), split);
      for (int k = 0; k < n; ++k) {
        const ObjectScore& o = e.objects[std::size_t(k)];
        EXPECT_EQ(o.significant_segments, 1u) << scenario << " seed " << seed << ": stone " << k << " ("
                                              << p.site.stones[std::size_t(k)].source << ") is split";
        if (o.significant_segments > 1) print_shares(k, r.labels, p.sampled.truth);
      }
      EXPECT_GE(e.found(), before.found()) << scenario << " seed " << seed;
      if (e.found() < before.found())
        for (int k = 0; k < n; ++k)
          std::printf("  stone %d (%s%s): completeness %.3f -> %.3f, purity %.3f -> %.3f\n", k,
                      p.site.stones[std::size_t(k)].source.c_str(), p.site.stones[std::size_t(k)].flat ? ", flat" : "",
                      before.objects[std::size_t(k)].completeness(), e.objects[std::size_t(k)].completeness(),
                      before.objects[std::size_t(k)].purity(), e.objects[std::size_t(k)].purity());
      EXPECT_LE(e.terrain_segments, before.terrain_segments) << scenario << " seed " << seed;
    }
}

// Issue #21: a single stone is never split. The evidence of every touching pair of fine hills
// (both large enough to be a part) on pile and spread sites, by the truth: hills of one stone
// (bumps and dips) against hills of two stones (seams). Prints the margin; a one-stone pair that
// looks like a seam must end in one segment.
TEST(PileSegmentation, ConcavitiesOfOneStoneAreNoSeam) {
  const SplitConfig c;
  struct Pair {
    HillContacts::Contact k;
    std::string where;  // scenario, seed and stone(s), for the printout
    bool split = false;  // the two hills end in different segments of segment()
  };
  std::vector<Pair> same, seams;
  const auto majority = [](const std::vector<std::uint32_t>& hill, const std::vector<std::int32_t>& truth) {
    std::map<std::int32_t, std::size_t> votes;
    for (auto i : hill) ++votes[truth[i]];
    return std::max_element(votes.begin(), votes.end(), [](auto& x, auto& y) { return x.second < y.second; })->first;
  };
  for (const std::string scenario : {"pile", "exp2"})
    for (const std::uint64_t seed : study_seeds(1, 4)) {
      const std::optional<PileSite> site = try_pile_site(seed, scenario);
      if (!site) continue;
      const PileSite& p = *site;
      const std::vector<std::int32_t> final_labels = segment(p.sampled.cloud, {}).labels;
      for (const HillContacts& cluster : split_evidence(p.sampled.cloud, {}))
        for (const auto& k : cluster.contacts) {
          // hills smaller than a part are merged into a neighbour whatever their contact
          const auto min_points = std::size_t(c.min_part_points);
          if (cluster.hills[k.a].size() < min_points || cluster.hills[k.b].size() < min_points) continue;
          const std::int32_t a = majority(cluster.hills[k.a], p.sampled.truth);
          const std::int32_t b = majority(cluster.hills[k.b], p.sampled.truth);
          std::string where = scenario + " seed " + std::to_string(seed) + " stone " + std::to_string(a);
          if (a != b) where.append("/").append(std::to_string(b));
          const bool split = majority(cluster.hills[k.a], final_labels) != majority(cluster.hills[k.b], final_labels);
          if (a >= 0 && b >= 0) (a == b ? same : seams).push_back({k, where, split});
        }
    }
  const auto is_seam = [&](const HillContacts::Contact& k) {
    return k.depth >= c.min_seam_depth || (k.depth >= c.min_crease_depth && k.crease_share >= c.min_crease_share);
  };
  double same_share = 0, same_depth = 0;
  std::size_t false_seams = 0, found = 0;
  for (const auto& [k, where, split] : same) {
    same_share = std::max(same_share, k.crease_share);
    same_depth = std::max(same_depth, k.depth);
    false_seams += is_seam(k);
    if (!is_seam(k)) continue;
    std::printf("one stone's hills taken for two (%s): depth %.3f m, crease share %.2f, %zu contact edges; %s\n",
                where.c_str(), k.depth, k.crease_share, k.edges, split ? "the two end in two segments" : "merged again");
    // The fine level is evidence, not the answer: such a pair must not split its stone in the end.
    EXPECT_FALSE(split) << where;
  }
  std::vector<double> seam_share;
  for (const auto& [k, where, split] : seams) {
    seam_share.push_back(k.crease_share);
    found += is_seam(k);
  }
  std::sort(seam_share.begin(), seam_share.end());
  ASSERT_FALSE(seam_share.empty());
  std::printf("one stone: %zu contacts, crease share <= %.2f, depth <= %.3f m; two stones: %zu contacts, crease share "
              "median %.2f, %zu of them a seam; thresholds: crease share %.2f, depth %.2f m\n",
              same.size(), same_share, same_depth, seams.size(), seam_share[seam_share.size() / 2], found,
              c.min_crease_share, c.min_seam_depth);
  // The margin at the fine level is thin, not a hard gap (docs/segmentation.md: on fresh seeds 2
  // of 183 one-stone pairs before the sites were settled in the physics, 1 of 170 since; on these
  // seeds 1 of 9 since): at most 2 % of the one-stone pairs (one on the default seeds), and none
  // ends in two segments (above).
  EXPECT_LE(double(false_seams), std::max(1.0, 0.02 * double(same.size())));
  EXPECT_GT(seam_share[seam_share.size() / 2], 2 * c.min_crease_share) << "the seams' median share";
}
