#include "cairn/registration/max_clique.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <bit>
#include <numeric>
#include <string>

#include "cairn/core/error.hpp"

namespace cairn {

void MaxCliqueConfig::validate() const {
  if (!(noise_bound > 0.0)) throw ConfigError("max_clique.noise_bound must be positive");
  if (max_correspondences < 3 || max_correspondences > kMaxCorrespondences)
    throw ConfigError("max_clique.max_correspondences must be in [3, " + std::to_string(kMaxCorrespondences) + "]");
  if (min_inliers < 3) throw ConfigError("max_clique.min_inliers must be at least 3 (a rigid transform needs 3 pairs)");
  if (node_budget < 1) throw ConfigError("max_clique.node_budget must be at least 1");
}

BitGraph::BitGraph(std::size_t n) : n_(n), words_((n + 63) / 64), bits_(n * words_, 0) {}

void BitGraph::add_edge(std::size_t a, std::size_t b) {
  if (a == b) return;
  bits_[a * words_ + (b >> 6)] |= std::uint64_t{1} << (b & 63);
  bits_[b * words_ + (a >> 6)] |= std::uint64_t{1} << (a & 63);
}

namespace {

using Bits = std::vector<std::uint64_t>;

std::size_t count(const Bits& b) {
  std::size_t n = 0;
  for (const std::uint64_t w : b) n += std::size_t(std::popcount(w));
  return n;
}

/// Vertices in degeneracy order (repeatedly the one of least remaining degree, Matula & Beck) and
/// each vertex's core number.
void degeneracy_order(const BitGraph& g, std::vector<std::uint32_t>& order, std::vector<std::uint32_t>& core) {
  const std::size_t n = g.size();
  std::vector<std::uint32_t> degree(n);
  for (std::size_t v = 0; v < n; ++v) {
    std::size_t d = 0;
    for (std::size_t w = 0; w < g.words(); ++w) d += std::size_t(std::popcount(g.row(v)[w]));
    degree[v] = std::uint32_t(d);
  }
  std::vector<std::uint8_t> removed(n, 0);
  order.clear();
  core.assign(n, 0);
  std::uint32_t k = 0;
  for (std::size_t step = 0; step < n; ++step) {  // O(n²): n is at most a few thousand
    std::size_t best = n;
    for (std::size_t v = 0; v < n; ++v)
      if (!removed[v] && (best == n || degree[v] < degree[best])) best = v;
    k = std::max(k, degree[best]);
    core[best] = k;
    removed[best] = 1;
    order.push_back(std::uint32_t(best));
    for (std::size_t v = 0; v < n; ++v)
      if (!removed[v] && g.adjacent(best, v)) --degree[v];
  }
}

/// Branch and bound (Tomita's MCQ: greedy colouring of the candidates bounds the clique they can
/// still give).
struct Search {
  const BitGraph& g;
  std::int64_t budget;
  std::int64_t nodes = 0;
  std::vector<std::uint32_t> current, best;

  void expand(const Bits& candidates) {
    if (++nodes > budget) return;
    // Colour classes in vertex order: a vertex joins the first class with no neighbour of it.
    std::vector<std::uint32_t> vertices, colour;
    Bits uncoloured = candidates;
    std::uint32_t c = 0;
    while (count(uncoloured) > 0) {
      ++c;
      Bits q = uncoloured;
      for (std::size_t w = 0; w < q.size(); ++w)
        while (q[w] != 0) {
          const std::size_t v = w * 64 + std::size_t(std::countr_zero(q[w]));
          q[w] &= q[w] - 1;
          uncoloured[v >> 6] &= ~(std::uint64_t{1} << (v & 63));
          vertices.push_back(std::uint32_t(v));
          colour.push_back(c);
          for (std::size_t x = w; x < q.size(); ++x) q[x] &= ~g.row(v)[x];  // its neighbours leave this class
        }
    }
    Bits left = candidates;
    for (std::size_t i = vertices.size(); i-- > 0;) {  // highest colour first
      if (current.size() + colour[i] <= best.size() || nodes > budget) return;
      const std::uint32_t v = vertices[i];
      current.push_back(v);
      Bits next(left.size());
      for (std::size_t w = 0; w < left.size(); ++w) next[w] = left[w] & g.row(v)[w];
      if (count(next) == 0) {
        if (current.size() > best.size()) best = current;
      } else {
        expand(next);
      }
      current.pop_back();
      left[v >> 6] &= ~(std::uint64_t{1} << (v & 63));
    }
  }
};

}  // namespace

Clique maximum_clique(const BitGraph& g, std::int64_t node_budget) {
  Clique out;
  if (g.size() == 0) return out;
  std::vector<std::uint32_t> order, core;
  degeneracy_order(g, order, core);
  Search s{.g = g, .budget = node_budget, .nodes = 0, .current = {}, .best = {order.back()}};
  // Each vertex with the neighbours that come after it in the degeneracy order (at most its core
  // number of them): every clique is found from its first vertex in that order.
  std::vector<std::uint32_t> position(g.size());
  for (std::size_t i = 0; i < order.size(); ++i) position[order[i]] = std::uint32_t(i);
  for (std::size_t i = order.size(); i-- > 0;) {
    const std::uint32_t v = order[i];
    if (core[v] + 1 <= s.best.size()) continue;  // no clique through v beats the best
    Bits later(g.words(), 0);
    for (std::size_t w = 0; w < g.size(); ++w)
      if (position[w] > i && g.adjacent(v, w)) later[w >> 6] |= std::uint64_t{1} << (w & 63);
    s.current = {v};
    if (count(later) > 0) s.expand(later);  // alone, v is no larger than the best (size >= 1)
    if (s.nodes > s.budget) break;
  }
  out.vertices = s.best;
  std::sort(out.vertices.begin(), out.vertices.end());
  out.exact = s.nodes <= s.budget;
  out.nodes = s.nodes;
  return out;
}

CliqueEstimate max_clique_registration(std::span<const Vec3f> source_keypoints, std::span<const Vec3f> target_keypoints,
                                       std::span<const Correspondence> matches, const MaxCliqueConfig& cfg) {
  cfg.validate();
  check_correspondence_indices(source_keypoints, target_keypoints, matches, "max_clique_registration");
  // The best-matching pairs, ties in input order.
  CliqueEstimate e;
  std::vector<Correspondence>& pairs = e.pairs;
  pairs.assign(matches.begin(), matches.end());
  std::stable_sort(pairs.begin(), pairs.end(),
                   [](const Correspondence& a, const Correspondence& b) { return a.squared_distance < b.squared_distance; });
  if (pairs.size() > std::size_t(cfg.max_correspondences)) pairs.resize(std::size_t(cfg.max_correspondences));
  const std::size_t n = pairs.size();
  BitGraph g(n);
  const double agree = 2.0 * cfg.noise_bound;
  std::vector<std::vector<std::uint32_t>> later(n);  // row a: the b > a consistent with it
  tbb::parallel_for(std::size_t{0}, n, [&](std::size_t a) {
    const Vec3d sa = source_keypoints[pairs[a].source].cast<double>(), ta = target_keypoints[pairs[a].target].cast<double>();
    for (std::size_t b = a + 1; b < n; ++b) {
      const double ds = (sa - source_keypoints[pairs[b].source].cast<double>()).norm();
      const double dt = (ta - target_keypoints[pairs[b].target].cast<double>()).norm();
      if (std::abs(ds - dt) <= agree) later[a].push_back(std::uint32_t(b));
    }
  });
  for (std::size_t a = 0; a < n; ++a) {
    e.edges += later[a].size();
    for (const std::uint32_t b : later[a]) g.add_edge(a, b);
  }
  e.clique = maximum_clique(g, cfg.node_budget);
  if (e.clique.vertices.size() < std::size_t(cfg.min_inliers)) return e;
  std::vector<Correspondence> members;
  for (const std::uint32_t v : e.clique.vertices) members.push_back(pairs[v]);
  if (auto cand = fit_candidate(source_keypoints, target_keypoints, std::move(members), cfg.noise_bound, 2))
    e.candidates.push_back(std::move(*cand));
  return e;
}

}  // namespace cairn
