// Maximum-clique inlier selection (registration/max_clique.hpp): exact against enumeration on
// small graphs, certified or not by its node budget, and the transform of a correspondence set
// that is mostly outliers.
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <numeric>
#include <random>
#include <string>

#include "cairn/core/error.hpp"
#include "cairn/core/units.hpp"
#include "cairn/registration/max_clique.hpp"

using namespace cairn;

namespace {

bool is_clique(const BitGraph& g, const std::vector<std::uint32_t>& v) {
  for (std::size_t a = 0; a < v.size(); ++a)
    for (std::size_t b = a + 1; b < v.size(); ++b)
      if (!g.adjacent(v[a], v[b])) return false;
  return true;
}

/// The clique number by enumerating every vertex subset (n <= 20).
std::size_t clique_number(const BitGraph& g) {
  const std::size_t n = g.size();
  std::size_t best = 0;
  for (std::uint32_t mask = 1; mask < (1u << n); ++mask) {
    const std::size_t k = std::size_t(std::popcount(mask));
    if (k <= best) continue;
    std::vector<std::uint32_t> v;
    for (std::uint32_t i = 0; i < n; ++i)
      if (mask >> i & 1u) v.push_back(i);
    if (is_clique(g, v)) best = k;
  }
  return best;
}

/// The clique number by plain Bron–Kerbosch with pivoting (sets as sorted vectors): a reference
/// independent of the bit rows and the colouring bound, for graphs spanning several 64-bit words.
void bron_kerbosch(const BitGraph& g, std::vector<std::uint32_t>& r, std::vector<std::uint32_t> p,
                   std::vector<std::uint32_t> x, std::size_t& best) {
  if (p.empty() && x.empty()) best = std::max(best, r.size());
  if (r.size() + p.size() <= best) return;
  const auto neighbours = [&](std::uint32_t v, const std::vector<std::uint32_t>& s) {
    std::vector<std::uint32_t> out;
    for (const std::uint32_t w : s)
      if (g.adjacent(v, w)) out.push_back(w);
    return out;
  };
  const std::uint32_t pivot = !p.empty() ? p.front() : x.front();
  for (const std::uint32_t v : std::vector<std::uint32_t>(p)) {
    if (g.adjacent(pivot, v)) continue;
    r.push_back(v);
    bron_kerbosch(g, r, neighbours(v, p), neighbours(v, x), best);
    r.pop_back();
    p.erase(std::find(p.begin(), p.end(), v));
    x.push_back(v);
  }
}

std::size_t clique_number_bk(const BitGraph& g) {
  std::vector<std::uint32_t> r, p(g.size());
  std::iota(p.begin(), p.end(), 0u);
  std::size_t best = 0;
  bron_kerbosch(g, r, p, {}, best);
  return best;
}

BitGraph random_graph(std::size_t n, double p, std::mt19937& rng) {
  BitGraph g(n);
  std::bernoulli_distribution edge(p);
  for (std::size_t a = 0; a < n; ++a)
    for (std::size_t b = a + 1; b < n; ++b)
      if (edge(rng)) g.add_edge(a, b);
  return g;
}

/// The search is certified and returns a clique of the reference's size.
void expect_maximum(const BitGraph& g, std::size_t clique_number, std::int64_t budget, const std::string& what) {
  const Clique c = maximum_clique(g, budget);
  EXPECT_TRUE(c.exact) << what;
  EXPECT_TRUE(is_clique(g, c.vertices)) << what;
  EXPECT_EQ(c.vertices.size(), clique_number) << what;
}

}  // namespace

TEST(MaxClique, EqualsEnumerationOnSmallRandomGraphs) {
  std::mt19937 rng(7);
  for (const double p : {0.2, 0.5, 0.8}) {
    for (int trial = 0; trial < 10; ++trial) {
      const BitGraph g = random_graph(18, p, rng);
      expect_maximum(g, clique_number(g), 1'000'000, "p " + std::to_string(p) + " trial " + std::to_string(trial));
    }
  }
}

TEST(MaxClique, EqualsBronKerboschOnGraphsOfSeveralWords) {
  std::mt19937 rng(9);
  for (const std::size_t n : {65u, 130u, 200u})
    for (const double p : {0.1, 0.3, 0.5}) {
      const BitGraph g = random_graph(n, p, rng);
      expect_maximum(g, clique_number_bk(g), 100'000'000, "n " + std::to_string(n) + " p " + std::to_string(p));
    }
}

TEST(MaxClique, FindsAPlantedCliqueAcrossWordBoundaries) {
  std::mt19937 rng(3);
  BitGraph g = random_graph(300, 0.1, rng);
  const std::vector<std::uint32_t> planted{5, 63, 64, 65, 127, 128, 190, 250, 299};  // 64-bit word edges
  for (std::size_t a = 0; a < planted.size(); ++a)
    for (std::size_t b = a + 1; b < planted.size(); ++b) g.add_edge(planted[a], planted[b]);
  const Clique c = maximum_clique(g, 10'000'000);
  EXPECT_TRUE(c.exact);
  EXPECT_EQ(c.vertices, planted);  // a G(300, 0.1) holds no other clique of 9 (expected number ~1e-14)
}

TEST(MaxClique, ABudgetTooSmallIsNotCertified) {
  std::mt19937 rng(11);
  const BitGraph g = random_graph(120, 0.6, rng);
  const Clique full = maximum_clique(g, 50'000'000);
  const Clique cut = maximum_clique(g, 5);
  EXPECT_TRUE(full.exact);
  EXPECT_FALSE(cut.exact);
  EXPECT_TRUE(is_clique(g, cut.vertices));
  EXPECT_LE(cut.vertices.size(), full.vertices.size());
  EXPECT_GE(cut.vertices.size(), 1u);
  EXPECT_TRUE(maximum_clique(BitGraph(0), 10).vertices.empty());
  // Certified exactly when the search fits the budget.
  EXPECT_TRUE(maximum_clique(g, full.nodes).exact);
  EXPECT_FALSE(maximum_clique(g, full.nodes - 1).exact);
}

// 60 true correspondences of a rigid motion (1 cm noise) among 240 random ones: the clique is the
// 60 (an outlier would have to keep its distance to all of them), the transform within millimetres.
TEST(MaxClique, RegistersCorrespondencesThatAreMostlyOutliers) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-1.5f, 1.5f);
  std::normal_distribution<float> noise(0.0f, 0.01f);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(0.7, Eigen::Vector3d(0.2, -0.3, 1.0).normalized()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(0.8, -2.0, 0.3);
  std::vector<Vec3f> src, tgt;
  for (int i = 0; i < 300; ++i) {
    const Vec3f s(u(rng), u(rng), u(rng));
    src.push_back(s);
    tgt.push_back((T * s.cast<double>()).cast<float>() + Vec3f(noise(rng), noise(rng), noise(rng)));
  }
  std::vector<Correspondence> matches;
  std::uniform_int_distribution<std::uint32_t> any(0, 299);
  std::uniform_real_distribution<float> dist(0.0f, 1.0f);
  for (std::uint32_t i = 0; i < 300; ++i)  // the first 60 right, the rest to random targets
    matches.push_back({.source = i, .target = i < 60 ? i : any(rng), .squared_distance = dist(rng)});
  MaxCliqueConfig cfg;
  cfg.noise_bound = 0.03;
  const CliqueEstimate e = max_clique_registration(src, tgt, matches, cfg);
  ASSERT_EQ(e.candidates.size(), 1u);
  EXPECT_TRUE(e.clique.exact);
  std::size_t right = 0;
  for (const Correspondence& c : e.candidates[0].inliers) right += c.source == c.target;
  EXPECT_GE(right, 58u);
  EXPECT_LE(e.candidates[0].inliers.size(), right + 1);
  const Eigen::Isometry3d D = e.candidates[0].T_target_source.inverse() * T;
  EXPECT_LT(Eigen::AngleAxisd(D.linear()).angle(), 0.5 * kDeg);
  EXPECT_LT(D.translation().norm(), 0.01);
  // Only the 20 best-matching pairs (descriptor distance) enter the graph: the 60 right ones come
  // first in the input but match worse than every outlier, so none of them is among the 20.
  cfg.max_correspondences = 20;
  cfg.min_inliers = 6;
  for (auto& m : matches) m.squared_distance = m.source < 60 ? 1.0f : 0.5f;
  const CliqueEstimate capped = max_clique_registration(src, tgt, matches, cfg);
  EXPECT_TRUE(capped.candidates.empty());
  ASSERT_EQ(capped.pairs.size(), 20u);
  for (const Correspondence& c : capped.pairs) EXPECT_GE(c.source, 60u);
  cfg.max_correspondences = 80;  // the 60 right ones now match best
  for (auto& m : matches) m.squared_distance = m.source < 60 ? 0.5f : 1.0f;
  const CliqueEstimate best = max_clique_registration(src, tgt, matches, cfg);
  ASSERT_EQ(best.candidates.size(), 1u);
  EXPECT_GE(best.candidates[0].inliers.size(), 58u);
}

TEST(MaxClique, BadInputIsAnError) {
  const std::vector<Vec3f> pts{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  const std::vector<Correspondence> out_of_range{{.source = 0, .target = 3, .squared_distance = 0}};
  EXPECT_THROW((void)max_clique_registration(pts, pts, out_of_range, {}), InputError);
  MaxCliqueConfig bad;
  bad.noise_bound = 0;
  EXPECT_THROW((void)max_clique_registration(pts, pts, {}, bad), ConfigError);
  bad = {};
  bad.min_inliers = 2;
  EXPECT_THROW((void)max_clique_registration(pts, pts, {}, bad), ConfigError);
}
