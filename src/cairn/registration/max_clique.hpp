#pragma once
// Maximum-clique inlier selection for descriptor correspondences without segments (issue #20
// item 5; TEASER++'s max-clique step, Yang, Shi & Carlone 2021). Two correspondences of a rigid
// motion keep their pairwise distance: (s_a, t_a) and (s_b, t_b) are consistent when
// | |s_a − s_b| − |t_a − t_b| | ≤ 2 · noise_bound. The inliers of the true motion are pairwise
// consistent, a clique of that graph; outliers rarely are, so the largest clique is the inlier
// set, found exactly (branch and bound over the degeneracy order with a colouring bound, as
// PMC/MCQ do) within a node budget — `exact` says whether it is certified maximum. The rigid
// transform is fitted to the clique (Umeyama) and refitted on the members within noise_bound.
//
// Unlike geometric consistency grouping (consistency_grouping.hpp: greedy clusters in descriptor
// order), the clique's size does not depend on the order of the matches (which of several
// equally large cliques is returned, and which pairs a tie in descriptor distance lets into the
// capped graph, do), and one consistent set is returned, not b candidates. With
// registration.max_clique.enabled it replaces the grouping on both paths (with and without
// segments); on the segmented path that is one candidate instead of b.
#include <cstdint>
#include <span>
#include <vector>

#include "cairn/features/matching.hpp"
#include "cairn/registration/consistency_grouping.hpp"

namespace cairn {

inline constexpr int kMaxCorrespondences = 20000;

struct MaxCliqueConfig {
  bool enabled = false;              // registration: candidates from the clique instead of the grouping
  double noise_bound = 0.05;         // [m] keypoint position noise; pairs agree within twice this
  int max_correspondences = 2000;    // the best-matching pairs (descriptor distance) taken into the graph
                                     // (at most kMaxCorrespondences: memory n²/8 bytes)
  int min_inliers = 4;               // a smaller clique gives no candidate
  std::int64_t node_budget = 2'000'000;  // branch-and-bound nodes before the best clique so far is returned
                                         // (a bound on work, not time: each node costs O(n/64))

  template <class V>
  void visit(V&& v) {
    v("enabled", enabled, "descriptor candidates from the maximum clique instead of the consistency grouping (beyond the paper)");
    v("noise_bound", noise_bound, "keypoint noise bound [m]: correspondences agree when their pairwise distances differ by <= 2x this");
    v("max_correspondences", max_correspondences, "correspondences with the smallest descriptor distance kept for the graph");
    v("min_inliers", min_inliers, "smallest clique that gives a transform candidate");
    v("node_budget", node_budget, "branch-and-bound nodes before the search stops with the best clique so far (then not certified)");
  }

  /// Throws ConfigError naming the key if a value is out of range.
  void validate() const;
};

/// An undirected graph on n vertices as adjacency bit rows (row i, bit j set: i and j adjacent).
class BitGraph {
 public:
  explicit BitGraph(std::size_t n);
  void add_edge(std::size_t a, std::size_t b);  // a == b is ignored (no loops)
  [[nodiscard]] bool adjacent(std::size_t a, std::size_t b) const { return (row(a)[b >> 6] >> (b & 63)) & 1u; }
  [[nodiscard]] std::size_t size() const { return n_; }
  [[nodiscard]] std::size_t words() const { return words_; }
  [[nodiscard]] const std::uint64_t* row(std::size_t i) const { return bits_.data() + i * words_; }

 private:
  std::size_t n_, words_;
  std::vector<std::uint64_t> bits_;
};

struct Clique {
  std::vector<std::uint32_t> vertices;  // ascending
  bool exact = true;                    // the search finished: no larger clique exists
  std::int64_t nodes = 0;               // branch-and-bound nodes visited
};

/// The largest clique of g (the first found among equals; deterministic), exact unless the node
/// budget ran out.
[[nodiscard]] Clique maximum_clique(const BitGraph& g, std::int64_t node_budget);

struct CliqueEstimate {
  std::vector<TransformCandidate> candidates;  // at most one: the clique's transform
  std::vector<Correspondence> pairs;           // the graph's vertices: the best-matching correspondences
  std::size_t edges = 0;
  Clique clique;                               // indices into `pairs`
};

/// The rigid transform of the largest set of pairwise consistent correspondences.
/// Correspondence::source indexes source_keypoints, ::target target_keypoints. Deterministic.
/// Throws ConfigError on a bad config, InputError on an out-of-range keypoint index.
[[nodiscard]] CliqueEstimate max_clique_registration(std::span<const Vec3f> source_keypoints,
                                                     std::span<const Vec3f> target_keypoints,
                                                     std::span<const Correspondence> matches, const MaxCliqueConfig& cfg);

}  // namespace cairn
