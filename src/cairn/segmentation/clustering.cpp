#include "cairn/segmentation/clustering.hpp"

#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include <atomic>

#include <algorithm>
#include <cmath>
#include <numeric>

#include "cairn/core/cell_map.hpp"
#include "cairn/core/error.hpp"

namespace cairn {

namespace {

/// Lock-free union-find (compare-and-swap linking of the larger root under the smaller): safe
/// for concurrent unite calls, and the final root of a component is always its smallest index,
/// whatever the order of the unions — so results do not depend on thread scheduling.
class ConcurrentDisjointSets {
 public:
  explicit ConcurrentDisjointSets(std::size_t n) : parent_(n) {
    for (std::size_t i = 0; i < n; ++i) parent_[i].store(std::uint32_t(i), std::memory_order_relaxed);
  }
  std::uint32_t find(std::uint32_t a) {
    while (true) {
      std::uint32_t p = parent_[a].load(std::memory_order_relaxed);
      if (p == a) return a;
      const std::uint32_t g = parent_[p].load(std::memory_order_relaxed);
      if (g != p) parent_[a].compare_exchange_weak(p, g, std::memory_order_relaxed);  // path halving
      a = g;
    }
  }
  void unite(std::uint32_t a, std::uint32_t b) {
    while (true) {
      a = find(a);
      b = find(b);
      if (a == b) return;
      if (a < b) std::swap(a, b);
      std::uint32_t expected = a;
      if (parent_[a].compare_exchange_strong(expected, b, std::memory_order_acq_rel)) return;
    }
  }

 private:
  std::vector<std::atomic<std::uint32_t>> parent_;
};

struct Cell {
  std::uint32_t begin, end;  // range in the sorted member array
  Eigen::Array3i coord;
};

/// Whether every point of the cell already belongs to the component rooted at `root`.
bool all_in(ConcurrentDisjointSets& sets, const std::vector<std::pair<std::uint64_t, std::uint32_t>>& keyed,
            const Cell& cell, std::uint32_t root) {
  for (auto k = cell.begin; k < cell.end; ++k)
    if (sets.find(keyed[k].second) != root) return false;
  return true;
}

}  // namespace

std::vector<std::vector<std::uint32_t>> euclidean_clusters(std::span<const Vec3f> points,
                                                           std::span<const std::uint32_t> indices,
                                                           const ClusterConfig& config) {
  if (!(config.tolerance > 0.0)) throw ConfigError("clustering: tolerance must be > 0");
  std::vector<std::uint32_t> all;
  if (indices.empty()) {
    all.resize(points.size());
    std::iota(all.begin(), all.end(), 0u);
    indices = all;
  }
  const std::size_t n = indices.size();
  const float tol = float(config.tolerance);
  const float tol2 = tol * tol;
  const float inv = 1.0f / tol;

  // Hash grid with cells of edge `tolerance`: neighbours of a point lie in the 27 cells around it.
  const auto cell_of = [inv](const Vec3f& p) {
    return Eigen::Array3i(int(std::floor(p.x() * inv)), int(std::floor(p.y() * inv)), int(std::floor(p.z() * inv)));
  };
  std::vector<std::pair<std::uint64_t, std::uint32_t>> keyed(n);  // (cell key, local index)
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Array3i c = cell_of(points[indices[i]]);
    keyed[i] = {CellMap::key(c[0], c[1], c[2]), std::uint32_t(i)};
  }
  tbb::parallel_sort(keyed.begin(), keyed.end());
  std::vector<Cell> cells;
  for (std::uint32_t i = 0; i < n;) {
    std::uint32_t j = i;
    while (j < n && keyed[j].first == keyed[i].first) ++j;
    cells.push_back({i, j, cell_of(points[indices[keyed[i].second]])});
    i = j;
  }
  CellMap lookup(cells.size());
  for (std::uint32_t c = 0; c < cells.size(); ++c) lookup.insert(keyed[cells[c].begin].first, c);

  // Union every pair closer than the tolerance; each cell pair visited once (13 forward offsets).
  ConcurrentDisjointSets sets(n);
  tbb::parallel_for(std::size_t{0}, cells.size(), [&](std::size_t ci) {
    const Cell& cell = cells[ci];
    const Eigen::Array3i& c = cell.coord;
    bool united = false;  // all points of this cell in one component (once true, stays true)
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int order = dz * 9 + dy * 3 + dx;
          if (order < 0) continue;  // the mirrored pair is handled from the other cell
          const std::uint32_t o = order == 0 ? std::uint32_t(ci)
                                             : lookup.find(CellMap::key(c[0] + dx, c[1] + dy, c[2] + dz));
          if (o == CellMap::kAbsent) continue;
          const Cell& other = cells[o];
          if (order != 0) {  // the self pair (order 0) comes first
            const std::uint32_t root = sets.find(keyed[cell.begin].second);
            united = united || all_in(sets, keyed, cell, root);
            if (united && all_in(sets, keyed, other, root))
              continue;  // both cells already in one component: every cross pair is connected
          }
          for (auto a = cell.begin; a < cell.end; ++a) {
            const std::uint32_t ia = keyed[a].second;
            const Vec3f& pa = points[indices[ia]];
            for (auto b = (order == 0 ? a + 1 : other.begin); b < other.end; ++b) {
              const std::uint32_t ib = keyed[b].second;
              if ((pa - points[indices[ib]]).squaredNorm() < tol2) sets.unite(ia, ib);
            }
          }
        }
  });

  // Components by root (roots are the smallest member index, so this is deterministic).
  std::vector<std::uint32_t> root_size(n, 0);
  for (std::uint32_t i = 0; i < n; ++i) ++root_size[sets.find(i)];
  const std::size_t min_pts = std::size_t(std::max(config.min_points, 1));
  const std::size_t max_pts = config.max_points > 0 ? std::size_t(config.max_points) : SIZE_MAX;
  std::vector<std::uint32_t> slot(n, CellMap::kAbsent);
  std::vector<std::vector<std::uint32_t>> clusters;
  for (std::uint32_t i = 0; i < n; ++i) {
    const std::uint32_t r = sets.find(i);
    if (root_size[r] < min_pts || root_size[r] > max_pts) continue;
    if (slot[r] == CellMap::kAbsent) {
      slot[r] = std::uint32_t(clusters.size());
      clusters.emplace_back().reserve(root_size[r]);
    }
    clusters[slot[r]].push_back(indices[i]);
  }
  for (auto& cl : clusters) std::sort(cl.begin(), cl.end());
  std::sort(clusters.begin(), clusters.end(), [](const auto& a, const auto& b) {
    return a.size() != b.size() ? a.size() > b.size() : a.front() < b.front();
  });
  return clusters;
}

}  // namespace cairn
