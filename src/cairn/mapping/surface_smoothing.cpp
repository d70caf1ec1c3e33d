#include "cairn/mapping/surface_smoothing.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <utility>
#include <vector>

#include <Eigen/Eigenvalues>

#include "cairn/core/cell_map.hpp"
#include "cairn/core/kdtree.hpp"
#include "cairn/core/voxel_grid.hpp"

namespace cairn {

namespace smoothing_detail {  // named: SurfaceSmoother::State keeps LocalSurfaces

constexpr int kHeightTerms = 6;  // a0..a5 of the quadratic height field below

// Moving least squares around one anchor: the weighted plane of the anchor's neighbourhood and,
// over it (when `quadratic`), a weighted quadratic height field h(x, y) = a0 + a1 x + a2 y +
// a3 x^2 + a4 xy + a5 y^2, with x and y scaled by 1/radius (conditioning) and centred at the
// weighted mean. Not valid where the neighbourhood is too small or not a surface.
struct LocalSurface {
  bool valid = false;
  Eigen::Vector3d mean, n, e1, e2;
  Eigen::Matrix<double, kHeightTerms, 1> a = Eigen::Matrix<double, kHeightTerms, 1>::Zero();  // zero: the plane

  /// `p` moved along the normal onto the surface.
  [[nodiscard]] Vec3f project(const Vec3f& p, double radius) const {
    const Eigen::Vector3d d = p.cast<double>() - mean;
    const double x = d.dot(e1) / radius, y = d.dot(e2) / radius;
    const double h_fit = a[0] + a[1] * x + a[2] * y + a[3] * x * x + a[4] * x * y + a[5] * y * y;
    return (p.cast<double>() - n * (d.dot(n) - h_fit)).cast<float>();
  }
};

/// The surface fitted for each block, by block key (sorted).
struct FittedBlocks {
  std::vector<std::uint64_t> keys;
  std::vector<LocalSurface> surfaces;
};

}  // namespace smoothing_detail

namespace {

using smoothing_detail::kHeightTerms;
using smoothing_detail::FittedBlocks;
using smoothing_detail::LocalSurface;

struct SmoothingScratch {
  Neighbors nb;
  std::vector<double> weights;
};

// The sums below are written out as scalars, the same products and sums per entry as Eigen's
// outer products formed them (outputs byte-identical as long as the compiler contracts nothing to
// FMA, as with the default x86-64 flags), without Eigen's temporaries: this is the hottest loop
// of the sanitizer build.

/// The weighted plane of the neighbourhood s.nb around `anchor` (f.mean, f.n, f.e1, f.e2; the
/// weights kept in s.weights). False where there is no weight or it is not a surface.
bool fit_weighted_plane(std::span<const Vec3f> points, const float* count, const Eigen::Vector3d& anchor,
                        const LocalMapConfig& c, SmoothingScratch& s, LocalSurface& f) {
  // Gaussian weights (sigma = radius / 2) times the number of returns of the voxel: a centroid of
  // n returns carries 1/n of a single return's range-noise variance.
  const double inv_two_sigma2 = 2.0 / (c.smoothing_radius * c.smoothing_radius);
  s.weights.resize(s.nb.size());
  double wsum = 0.0, sx = 0.0, sy = 0.0, sz = 0.0, xx = 0.0, xy = 0.0, xz = 0.0, yy = 0.0, yz = 0.0, zz = 0.0;
  for (std::size_t k = 0; k < s.nb.size(); ++k) {
    const Vec3f& p = points[s.nb.indices[k]];
    const double x = double(p.x()) - anchor.x(), y = double(p.y()) - anchor.y(), z = double(p.z()) - anchor.z();
    const double w = std::exp(-(x * x + y * y + z * z) * inv_two_sigma2) * (count ? double(count[s.nb.indices[k]]) : 1.0);
    s.weights[k] = w;
    wsum += w;
    const double wx = w * x, wy = w * y, wz = w * z;
    sx += wx, sy += wy, sz += wz;
    // The lower triangle, which is all the eigen solver reads.
    xx += wx * x, xy += wy * x, xz += wz * x, yy += wy * y, yz += wz * y, zz += wz * z;
  }
  if (!(wsum > 0.0)) return false;
  const Eigen::Vector3d mean = Eigen::Vector3d(sx, sy, sz) / wsum;  // relative to the anchor
  Eigen::Matrix3d sq;
  sq << xx, xy, xz, xy, yy, yz, xz, yz, zz;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(sq / wsum - mean * mean.transpose());
  const Eigen::Vector3d ev = es.eigenvalues().cwiseMax(0.0);
  if (!(ev.sum() > 0.0) || ev[0] / ev.sum() > c.smoothing_max_curvature) return false;
  f.mean = anchor + mean;
  f.n = es.eigenvectors().col(0);
  f.e1 = es.eigenvectors().col(2);
  f.e2 = es.eigenvectors().col(1);
  return true;
}

/// The weighted quadratic height field over f's plane (f.a; left zero, the plane, where the
/// normal equations are not positive definite).
void fit_height_field(std::span<const Vec3f> points, const LocalMapConfig& c, const SmoothingScratch& s, LocalSurface& f) {
  constexpr int n = kHeightTerms;
  // The lower triangle of Σ w φ φᵀ and Σ w h φ, as Eigen's rankUpdate formed them.
  double A_sum[n][n] = {}, b_sum[n] = {};
  for (std::size_t k = 0; k < s.nb.size(); ++k) {
    const Eigen::Vector3d d = points[s.nb.indices[k]].cast<double>() - f.mean;
    const double x = d.dot(f.e1) / c.smoothing_radius, y = d.dot(f.e2) / c.smoothing_radius;
    const double phi[n] = {1.0, x, y, x * x, x * y, y * y};
    const double w = s.weights[k], wh = w * d.dot(f.n);
    for (int i = 0; i < n; ++i) {
      const double wp = w * phi[i];
      for (int j = i; j < n; ++j) A_sum[j][i] += wp * phi[j];
      b_sum[i] += wh * phi[i];
    }
  }
  Eigen::Matrix<double, n, n> A;
  Eigen::Matrix<double, n, 1> b;
  for (int i = 0; i < n; ++i) {
    b[i] = b_sum[i];
    for (int j = 0; j < n; ++j) A(i, j) = i >= j ? A_sum[i][j] : A_sum[j][i];
  }
  const Eigen::LDLT<Eigen::Matrix<double, n, n>> ldlt(A);
  if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) return;  // the plane
  const Eigen::Matrix<double, n, 1> a = ldlt.solve(b);
  if (a.allFinite()) f.a = a;
}

LocalSurface fit_local_surface(std::span<const Vec3f> points, const float* count, const KdTree& tree,
                               const Eigen::Vector3d& anchor, const LocalMapConfig& c, SmoothingScratch& s) {
  constexpr std::size_t kMinPlane = 6, kMinQuadratic = 10;  // 3 and 6 unknowns, with margin
  LocalSurface f;
  tree.radius(anchor.cast<float>(), float(c.smoothing_radius), s.nb);
  if (s.nb.size() < (c.smoothing_quadratic ? kMinQuadratic : kMinPlane)) return f;
  if (!fit_weighted_plane(points, count, anchor, c, s, f)) return f;
  f.valid = true;
  if (c.smoothing_quadratic) fit_height_field(points, c, s, f);
  return f;
}


std::uint64_t cell_of(const Vec3f& p, double side) {
  return CellMap::key(std::int64_t(std::floor(p.x() / side)), std::int64_t(std::floor(p.y() / side)),
                      std::int64_t(std::floor(p.z() / side)));
}

/// The groups of points that share one fitted surface: the cubes of side `block` (sorted by
/// their keys, the points of one in index order), or every point alone (block 0, keyed by index).
struct Blocks {
  std::vector<std::pair<std::uint64_t, std::uint32_t>> order;  // (block key, point)
  std::vector<std::size_t> starts;                             // group g: order[starts[g], starts[g + 1])
  [[nodiscard]] std::size_t size() const { return starts.size() - 1; }
  [[nodiscard]] std::uint64_t key(std::size_t g) const { return order[starts[g]].first; }
};

Blocks group_into_blocks(std::span<const Vec3f> points, double block) {
  Blocks b;
  b.order.resize(points.size());
  for (std::size_t i = 0; i < points.size(); ++i)
    b.order[i] = {block > 0.0 ? cell_of(points[i], block) : std::uint64_t(i), std::uint32_t(i)};
  if (block > 0.0) tbb::parallel_sort(b.order.begin(), b.order.end());  // unique pairs: deterministic
  for (std::size_t i = 0; i < b.order.size(); ++i)
    if (i == 0 || b.order[i].first != b.order[i - 1].first) b.starts.push_back(i);
  b.starts.push_back(b.order.size());
  return b;
}

/// The cells of side `side` holding a position of `at`, grown by `rings` neighbour cells per axis.
CellMap cells_around(std::span<const Vec3f> at, double side, int rings) {
  CellMap seed;  // grows: far fewer cells than positions
  std::vector<std::array<std::int64_t, 3>> cells;
  for (const Vec3f& p : at) {
    const std::array<std::int64_t, 3> c{std::int64_t(std::floor(p.x() / side)), std::int64_t(std::floor(p.y() / side)),
                                        std::int64_t(std::floor(p.z() / side))};
    if (seed.insert(CellMap::key(c[0], c[1], c[2]), std::uint32_t(cells.size())) == cells.size()) cells.push_back(c);
  }
  const int width = 2 * rings + 1;
  CellMap grown(cells.size() * std::size_t(width * width));  // a surface: ~width^2 per cell
  for (const auto& [x, y, z] : cells)
    for (int dx = -rings; dx <= rings; ++dx)
      for (int dy = -rings; dy <= rings; ++dy)
        for (int dz = -rings; dz <= rings; ++dz) (void)grown.insert(CellMap::key(x + dx, y + dy, z + dz), 0);
  return grown;
}

/// The centre of the block holding p (cube of side `block`).
Vec3f block_centre(const Vec3f& p, double block) {
  const auto c = [&](float v) { return float((std::floor(v / block) + 0.5) * block); };
  return {c(p.x()), c(p.y()), c(p.z())};
}

}  // namespace

/// Changed positions (old and new ones: two per moved point) per point of the cloud from which on
/// everything is refitted. Chosen from experiment 1's snapshots (docs/mapping.md): at ~25 % (the
/// carry scans, 40–70 % of the surfaces refitted) the incremental pass took 0.7–1.0 s against
/// 0.9–1.4 s for a full one; the rescans' ~100 % would pay the bookkeeping for nothing.
constexpr double kMaxChangedShare = 0.5;

struct SurfaceSmoother::State {
  Vec3d origin = Vec3d::Zero();
  FittedBlocks fitted;
};

SurfaceSmoother::SurfaceSmoother(LocalMapConfig config) : config_(std::move(config)) {}
SurfaceSmoother::~SurfaceSmoother() = default;
SurfaceSmoother::SurfaceSmoother(SurfaceSmoother&&) noexcept = default;
SurfaceSmoother& SurfaceSmoother::operator=(SurfaceSmoother&&) noexcept = default;

namespace {

/// A cloud's points and counts (empty: none) in block order: a block's points are contiguous, and
/// what a fit reads lies near in memory.
struct BlockOrdered {
  std::vector<Vec3f> points;
  std::vector<float> counts;
};

BlockOrdered in_block_order(const PointCloud& cloud, const Blocks& blocks) {
  const float* count = nullptr;
  for (const ScalarField& f : cloud.fields)
    if (f.name == "count" && f.values.size() == cloud.size()) count = f.values.data();
  BlockOrdered s;
  s.points.resize(cloud.size());
  if (count) s.counts.resize(cloud.size());
  for (std::size_t k = 0; k < blocks.order.size(); ++k) {
    const std::uint32_t i = blocks.order[k].second;
    s.points[k] = cloud.points[i];
    if (count) s.counts[k] = count[i];
  }
  return s;
}

constexpr std::uint32_t kRefit = CellMap::kAbsent;
constexpr std::size_t kBlocksPerTask = 256;  // TBB grain: ~1 ms of fits per task

/// Blocks that keep a surface of `keys` (kept[g]: its index there; kRefit: fitted again) and the
/// points the refitted ones read (`read`, indices into the block-ordered points). Nothing is kept
/// when a block is new where no change was told (the changes were incomplete).
struct Reuse {
  std::vector<std::uint32_t> kept;
  std::vector<std::uint32_t> read;
};

Reuse find_reusable(const BlockOrdered& sorted, const Blocks& blocks, std::span<const std::uint64_t> keys,
                    std::span<const Vec3f> changed, const LocalMapConfig& c) {
  // Cells of side block/2 + radius: everything a block's fit reads lies in the cell of the block's
  // centre or a neighbour; `stale` holds the cells next to a changed position, `reach` the
  // neighbours of those (what the refitted blocks read).
  const double block = c.smoothing_block, side = 0.5 * block + c.smoothing_radius + 1e-3;  // margin: float rounding
  const CellMap stale = cells_around(changed, side, 1), reach = cells_around(changed, side, 2);
  Reuse r{.kept = std::vector<std::uint32_t>(blocks.size(), kRefit), .read = {}};
  std::atomic<bool> unexplained = false;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, blocks.size(), kBlocksPerTask), [&](const auto& range) {
    for (std::size_t g = range.begin(); g != range.end(); ++g) {
      if (stale.find(cell_of(block_centre(sorted.points[blocks.starts[g]], block), side)) != CellMap::kAbsent) continue;
      const auto it = std::lower_bound(keys.begin(), keys.end(), blocks.key(g));
      if (it != keys.end() && *it == blocks.key(g)) r.kept[g] = std::uint32_t(it - keys.begin());
      else unexplained = true;
    }
  });
  if (unexplained) return {};
  for (std::size_t k = 0; k < sorted.points.size(); ++k)
    if (reach.find(cell_of(sorted.points[k], side)) != CellMap::kAbsent) r.read.push_back(std::uint32_t(k));
  return r;
}

/// The points the refits read, for their neighbour searches (a full pass searches all of them).
BlockOrdered points_read(const BlockOrdered& sorted, const Reuse& reuse) {
  BlockOrdered s;
  for (const std::uint32_t k : reuse.read) {
    s.points.push_back(sorted.points[k]);
    if (!sorted.counts.empty()) s.counts.push_back(sorted.counts[k]);
  }
  return s;
}

/// Every block's surface, fitted on `searched` or, where `kept` says so, taken from `old`; the
/// points moved onto it in `out` (where the surface is valid).
FittedBlocks fit_and_project(const Blocks& blocks, const BlockOrdered& sorted, const BlockOrdered& searched,
                             std::span<const std::uint32_t> kept, const FittedBlocks* old, const LocalMapConfig& c,
                             PointCloud& out) {
  const KdTree tree(searched.points);
  const float* counts = searched.counts.empty() ? nullptr : searched.counts.data();
  FittedBlocks fitted;
  fitted.keys.resize(blocks.size());
  fitted.surfaces.resize(blocks.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, blocks.size(), kBlocksPerTask), [&](const auto& r) {
    SmoothingScratch scratch;
    for (std::size_t g = r.begin(); g != r.end(); ++g) {
      const std::size_t from = blocks.starts[g], to = blocks.starts[g + 1];
      LocalSurface f;
      if (!kept.empty() && kept[g] != kRefit) {
        f = old->surfaces[kept[g]];
      } else {
        Eigen::Vector3d anchor = Eigen::Vector3d::Zero();
        for (std::size_t k = from; k < to; ++k) anchor += sorted.points[k].cast<double>();
        anchor /= double(to - from);
        f = fit_local_surface(searched.points, counts, tree, anchor, c, scratch);
      }
      fitted.keys[g] = blocks.key(g);
      fitted.surfaces[g] = f;
      if (!f.valid) continue;
      for (std::size_t k = from; k < to; ++k)
        out.points[blocks.order[k].second] = f.project(sorted.points[k], c.smoothing_radius);
    }
  });
  return fitted;
}

}  // namespace

PointCloud SurfaceSmoother::smooth(const PointCloud& cloud, std::optional<std::span<const Vec3f>> changed) {
  stats_ = {};
  const double block = config_.smoothing_block;
  if (cloud.empty() || !(block > 0.0)) state_.reset();  // nothing to keep (block 0: a fit per point)
  if (cloud.empty()) {
    PointCloud empty;
    empty.origin = cloud.origin;
    return empty;
  }
  const Blocks blocks = group_into_blocks(cloud.points, block);
  const BlockOrdered sorted = in_block_order(cloud, blocks);
  // Where much of the cloud changed (a long sweep), finding what did not costs more than it saves.
  const bool may_reuse = changed && state_ && state_->origin == cloud.origin &&
                         double(changed->size()) < kMaxChangedShare * double(cloud.size());
  const Reuse reuse = may_reuse ? find_reusable(sorted, blocks, state_->fitted.keys, *changed, config_) : Reuse{};
  PointCloud out;
  out.origin = cloud.origin;
  out.points = cloud.points;
  const BlockOrdered read = reuse.kept.empty() ? BlockOrdered{} : points_read(sorted, reuse);
  const BlockOrdered& searched = reuse.kept.empty() ? sorted : read;
  FittedBlocks fitted = fit_and_project(blocks, sorted, searched, reuse.kept, state_ ? &state_->fitted : nullptr, config_, out);
  stats_.tree_points = searched.points.size();
  stats_.blocks = blocks.size();
  stats_.full = reuse.kept.empty();
  stats_.refitted = stats_.full ? blocks.size() : std::size_t(std::count(reuse.kept.begin(), reuse.kept.end(), kRefit));
  if (block > 0.0) state_ = std::make_unique<State>(State{.origin = cloud.origin, .fitted = std::move(fitted)});
  return voxel_downsample(out, {.res_voxel = config_.voxel.res_voxel, .n_min = 1});
}

PointCloud smooth_surface(const PointCloud& cloud, const LocalMapConfig& config) {
  return SurfaceSmoother(config).smooth(cloud, std::nullopt);
}

}  // namespace cairn
