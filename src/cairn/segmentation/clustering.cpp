#include "cairn/segmentation/clustering.hpp"

#include <tbb/parallel_sort.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <unordered_map>

#include "cairn/core/error.hpp"

namespace cairn {

DisjointSets::DisjointSets(std::size_t n) : parent_(n) {
  std::iota(parent_.begin(), parent_.end(), 0u);
}

std::uint32_t DisjointSets::find(std::uint32_t a) {
  while (parent_[a] != a) {
    parent_[a] = parent_[parent_[a]];
    a = parent_[a];
  }
  return a;
}

void DisjointSets::unite(std::uint32_t a, std::uint32_t b) {
  a = find(a);
  b = find(b);
  if (a == b) return;
  if (a < b) std::swap(a, b);
  parent_[a] = b;
}

namespace {

constexpr int kCellBits = 21;
constexpr std::int64_t kCellBias = std::int64_t{1} << (kCellBits - 1);

std::uint64_t pack(std::int64_t x, std::int64_t y, std::int64_t z) {
  const auto m = (std::uint64_t{1} << kCellBits) - 1;
  return (std::uint64_t(z + kCellBias) & m) << (2 * kCellBits) |
         (std::uint64_t(y + kCellBias) & m) << kCellBits | (std::uint64_t(x + kCellBias) & m);
}

struct Cell {
  std::uint32_t begin, end;  // range in the sorted member array
};

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
  std::vector<std::pair<std::uint64_t, std::uint32_t>> keyed(n);  // (cell key, local index)
  std::vector<Eigen::Array3i> cell_of(n);
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3f& p = points[indices[i]];
    cell_of[i] = {int(std::floor(p.x() * inv)), int(std::floor(p.y() * inv)), int(std::floor(p.z() * inv))};
    keyed[i] = {pack(cell_of[i][0], cell_of[i][1], cell_of[i][2]), std::uint32_t(i)};
  }
  tbb::parallel_sort(keyed.begin(), keyed.end());
  std::unordered_map<std::uint64_t, Cell> cells;
  cells.reserve(n / 4 + 1);
  for (std::uint32_t i = 0; i < n;) {
    std::uint32_t j = i;
    while (j < n && keyed[j].first == keyed[i].first) ++j;
    cells.emplace(keyed[i].first, Cell{i, j});
    i = j;
  }

  // Union every pair closer than the tolerance; each cell pair visited once (13 forward offsets).
  DisjointSets sets(n);
  for (const auto& [key, cell] : cells) {
    const Eigen::Array3i c = cell_of[keyed[cell.begin].second];
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int order = dz * 9 + dy * 3 + dx;
          if (order < 0) continue;  // the mirrored pair is handled from the other cell
          const auto it = cells.find(pack(c[0] + dx, c[1] + dy, c[2] + dz));
          if (it == cells.end()) continue;
          const Cell other = it->second;
          for (auto a = cell.begin; a < cell.end; ++a) {
            const std::uint32_t ia = keyed[a].second;
            const Vec3f& pa = points[indices[ia]];
            for (auto b = (order == 0 ? a + 1 : other.begin); b < other.end; ++b) {
              const std::uint32_t ib = keyed[b].second;
              if ((pa - points[indices[ib]]).squaredNorm() < tol2) sets.unite(ia, ib);
            }
          }
        }
  }

  std::unordered_map<std::uint32_t, std::vector<std::uint32_t>> groups;
  for (std::uint32_t i = 0; i < n; ++i) groups[sets.find(i)].push_back(indices[i]);
  std::vector<std::vector<std::uint32_t>> clusters;
  const std::size_t min_pts = std::size_t(std::max(config.min_points, 1));
  const std::size_t max_pts = config.max_points > 0 ? std::size_t(config.max_points) : SIZE_MAX;
  for (auto& [root, members] : groups) {
    if (members.size() < min_pts || members.size() > max_pts) continue;
    std::sort(members.begin(), members.end());
    clusters.push_back(std::move(members));
  }
  std::sort(clusters.begin(), clusters.end(), [](const auto& a, const auto& b) {
    return a.size() != b.size() ? a.size() > b.size() : a.front() < b.front();
  });
  return clusters;
}

}  // namespace cairn
