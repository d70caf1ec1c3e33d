// The world at rest (issue #15, item 1): every scenario's site is settled in the physics when it
// is generated, so starting the physics again from it moves nothing; the trial records what the
// machine measures (jaw opening, arm load), and low friction shows as slip in that trace.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "cairn/sim/physics/physics.hpp"
#include "cairn/sim/simulation.hpp"

namespace cairn::sim {
namespace {

using Eigen::Isometry3d;
using Eigen::Vector3d;

constexpr double kRestart = 3.0;                                  // [s] simulated after the restart
constexpr double kMaxShift = 0.01;                                // [m] issue #15: 1 cm ...
constexpr double kMaxTurn = 1.0 * std::numbers::pi / 180.0;       // ... and 1 degree

#if defined(__SANITIZE_ADDRESS__) || !defined(NDEBUG)
constexpr std::uint64_t kSeeds = 1;  // the sanitizers run the path once
#else
constexpr std::uint64_t kSeeds = 4;  // 20 per scenario: bench_physics / docs (CI time)
#endif

SimulationConfig settled_scenario(const std::string& name) {
  SimulationConfig cfg = scenario_config(name, default_real_mesh_dir());
  cfg.settle_in_physics = true;
  return cfg;
}

struct Motion {
  double shift = 0.0, turn = 0.0;
};

/// Largest centroid shift and rotation of any stone when the physics runs `seconds` from `site`
/// as it is (one scene holding every stone).
Motion restart_motion(const Site& site, const PhysicsConfig& base, double seconds) {
  PhysicsConfig c = base;
  c.settle_time = seconds;
  c.settle_speed = 1e-9;  // never "at rest" early: run the whole time
  const SettleResult r = settle_stones(site, c);
  Motion m;
  for (std::size_t k = 0; k < site.stones.size(); ++k) {
    const Isometry3d& T = r.stone_poses[k];
    m.shift = std::max(m.shift, (T * site.stones[k].centroid - site.stones[k].centroid).norm());
    m.turn = std::max(m.turn, Eigen::AngleAxisd(T.linear()).angle());
  }
  return m;
}

class WorldAtRest : public ::testing::TestWithParam<std::string> {};

TEST_P(WorldAtRest, RestartingThePhysicsMovesNoStone) {
  // A site the settle reports at rest is at rest: restarting the physics from it (one scene with
  // every stone, as a trial or the next settle starts) moves no stone more than 1 cm / 1 deg in
  // 3 s. A site that did not come to rest is reported so, never passed off as at rest.
  const SimulationConfig cfg = settled_scenario(GetParam());
  Motion worst;
  int settled = 0, unsettled = 0;
  for (std::uint64_t seed = 1; seed <= kSeeds; ++seed) {
    SiteSettleResult settle;
    const Site site = make_site(cfg, seed, &settle);
    ASSERT_TRUE(site.at_rest);
    if (!settle.settled) {
      ++unsettled;
      continue;
    }
    ++settled;
    const Motion m = restart_motion(site, cfg.physics, kRestart);
    EXPECT_LT(m.shift, kMaxShift) << GetParam() << " seed " << seed;
    EXPECT_LT(m.turn, kMaxTurn) << GetParam() << " seed " << seed;
    worst.shift = std::max(worst.shift, m.shift);
    worst.turn = std::max(worst.turn, m.turn);
  }
  std::printf("%s, seeds 1-%llu: %d at rest, largest motion in %.0f s after a restart %.2f mm, %.3f deg; %d not at rest\n",
              GetParam().c_str(), static_cast<unsigned long long>(kSeeds), settled, kRestart, 1e3 * worst.shift,
              worst.turn * 180.0 / std::numbers::pi, unsettled);
  EXPECT_EQ(unsettled, 0);  // issue #15: every scenario, every seed
}

TEST(WorldAtRest, AStoneThatRocksAtEveryRestartIsAtRestOnlyWithinTheTolerance) {
  // exp1 seed 15 holds a stone that a cold start rocks by ~1 cm and ~0.9 deg at every restart,
  // however often the island is restarted: the site is at rest within the world-at-rest
  // tolerance (1 cm, 1 deg) and says how far a restart moves it; with a 1 mm tolerance the same
  // site is reported not at rest.
  SimulationConfig cfg = settled_scenario("exp1");
  SiteSettleResult within;
  make_site(cfg, 15, &within);
  EXPECT_TRUE(within.settled);
  EXPECT_GT(within.restart_shift, 1e-3);
  EXPECT_LE(within.restart_shift, cfg.physics.restart_shift);
  EXPECT_LE(within.restart_turn, cfg.physics.restart_turn_deg * std::numbers::pi / 180.0);
  cfg.physics.restart_shift = 1e-3;
  SiteSettleResult strict;
  make_site(cfg, 15, &strict);
  EXPECT_FALSE(strict.settled);
  EXPECT_GT(strict.restart_shift, 1e-3);
}

INSTANTIATE_TEST_SUITE_P(Scenarios, WorldAtRest, ::testing::Values("exp1", "exp2", "pile"));

TEST(WorldAtRest, SettlingIsDeterministicAndMovesTheSiteOnce) {
  const SimulationConfig cfg = settled_scenario("exp1");
  SiteSettleResult a, b;
  const Site one = make_site(cfg, 3, &a);
  const Site two = make_site(cfg, 3, &b);
  ASSERT_EQ(one.stones.size(), two.stones.size());
  for (std::size_t k = 0; k < one.stones.size(); ++k) {
    EXPECT_EQ(one.stones[k].centroid, two.stones[k].centroid) << "stone " << k;
    EXPECT_TRUE(a.stone_poses[k].isApprox(b.stone_poses[k], 0.0)) << "stone " << k;
  }
  // The settle moved the generated stones onto their rest poses (the generator's quasi-static
  // tipping is not an equilibrium on the physics' height field), and the site says so.
  SimulationConfig raw = cfg;
  raw.settle_in_physics = false;
  raw.site.stones.embed_depth = 0.0;  // as make_site generates a site it settles
  const Site generated = make_site(raw, 3);
  EXPECT_FALSE(generated.at_rest);
  EXPECT_GT(a.max_displacement, 0.0);
  for (std::size_t k = 0; k < one.stones.size(); ++k) {
    const Vector3d expected = a.stone_poses[k] * generated.stones[k].centroid;
    EXPECT_LT((expected - one.stones[k].centroid).norm(), 1e-5) << "stone " << k;
  }
}

TEST(WorldAtRest, CollisionHullsHoldTheMeshes) {
  // Every stone's collision shape (the hulls of its convex parts, each from its extreme points
  // along 642 directions) holds nearly all of its mesh: not less than 99 % of the mesh volume
  // (the simplified hulls cut small caps), and not more than the decomposition's 5 % over it
  // (issue #15, item 4), real scanned stones included (their single hulls add 7.5–25 %).
  const SimulationConfig cfg = scenario_config("exp2", default_real_mesh_dir());
  const Site site = make_site(cfg, 1);
  const std::vector<double> hull = collision_hull_volumes(site, cfg.physics);
  ASSERT_EQ(hull.size(), site.stones.size());
  int real = 0;
  for (std::size_t k = 0; k < hull.size(); ++k) {
    const double ratio = hull[k] / site.stones[k].volume;
    std::printf("stone %zu (%s, %zu parts): hull / mesh volume %.3f\n", k, site.stones[k].source.c_str(),
                site.stones[k].collision_parts.size(), ratio);
    EXPECT_GT(ratio, 0.99) << "stone " << k;
    EXPECT_LT(ratio, 1.05) << "stone " << k;
    real += site.stones[k].source != "procedural";
  }
  EXPECT_EQ(real, 3);  // exp2's three real stones, decomposed
}

}  // namespace
}  // namespace cairn::sim
