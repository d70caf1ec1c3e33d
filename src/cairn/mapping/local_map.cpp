#include "cairn/mapping/local_map.hpp"

#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>

#include <Eigen/Eigenvalues>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "cairn/core/cell_map.hpp"
#include "cairn/core/kdtree.hpp"
#include "cairn/core/voxel_grid.hpp"

namespace cairn {

LocalMap::LocalMap(LocalMapConfig config) : config_(std::move(config)) {}

std::uint64_t LocalMap::key_of(const Eigen::Vector3d& p) const {
  const double r = config_.voxel.res_voxel;
  return CellMap::key(std::int64_t(std::floor(p.x() / r)), std::int64_t(std::floor(p.y() / r)),
                      std::int64_t(std::floor(p.z() / r)));
}

void LocalMap::rebuild_index() {
  index_.clear(voxels_.size());
  for (std::size_t i = 0; i < voxels_.size(); ++i) index_.insert(voxels_[i].key, std::uint32_t(i));
}

void LocalMap::add(const Eigen::Vector3d& p_world) {
  if (!p_world.allFinite()) return;
  if (!has_origin_) {
    origin_ = p_world.array().floor().matrix();  // whole metres: keys stay small, floats precise
    has_origin_ = true;
  }
  const Eigen::Vector3d p = p_world - origin_;
  const std::uint64_t key = key_of(p);
  const auto next = std::uint32_t(voxels_.size());
  const std::uint32_t at = index_.insert(key, next);
  if (at == next) voxels_.push_back({.sum = Eigen::Vector3d::Zero(), .count = 0, .key = key});
  Voxel& v = voxels_[at];
  v.sum += p;
  ++v.count;
  ++revision_;
}

void LocalMap::insert(const PointCloud& cloud) {
  for (std::size_t i = 0; i < cloud.size(); ++i) add(cloud.world(i));
}

void LocalMap::insert(std::span<const Vec3f> points, const Eigen::Isometry3d& T_world_F) {
  for (const Vec3f& p : points) add(T_world_F * p.cast<double>());
}

template <class Keep>
std::size_t LocalMap::filter(Keep keep) {
  const std::size_t before = voxels_.size();
  std::erase_if(voxels_, [&](const Voxel& v) { return !keep(Eigen::Vector3d(origin_ + v.sum / v.count)); });
  if (voxels_.size() != before) {
    rebuild_index();
    ++revision_;
  }
  return before - voxels_.size();
}

std::size_t LocalMap::crop(const Vec3d& center) {
  const double r2 = config_.R_map * config_.R_map;
  return filter([&](const Eigen::Vector3d& c) { return (c - center).head<2>().squaredNorm() <= r2; });
}

std::size_t LocalMap::remove_sphere(const Vec3d& center, double radius) {
  return filter([&](const Eigen::Vector3d& c) { return (c - center).squaredNorm() > radius * radius; });
}

std::size_t LocalMap::apply(const MapEdit& edit) {
  edit.validate();
  if (edit.kind == MapEdit::Kind::insert) {
    insert(edit.points);
    return 0;
  }
  const MapEditRegion region(edit);
  return filter([&](const Eigen::Vector3d& c) { return !region.removes(c); });
}

void LocalMap::clear() {
  ++revision_;
  voxels_.clear();
  index_.clear();
}

PointCloud LocalMap::snapshot() const {
  const std::lock_guard lock(cache_.mutex);
  if (!cache_.cloud || cache_.revision != revision_) {
    // Isolated: the lock is held while smoothing runs TBB tasks, so this thread must not pick up
    // an outside task that could ask for the same snapshot.
    tbb::this_task_arena::isolate([&] { cache_.cloud = std::make_shared<const PointCloud>(compute_snapshot()); });
    cache_.revision = revision_;
  }
  return *cache_.cloud;
}

PointCloud LocalMap::compute_snapshot() const {
  PointCloud out;
  out.origin = origin_;
  out.reserve(voxels_.size());
  ScalarField count{"count", {}};
  count.values.reserve(voxels_.size());
  for (const Voxel& v : voxels_) {
    if (v.count < std::uint32_t(config_.voxel.n_min)) continue;
    out.points.push_back((v.sum / v.count).cast<float>());
    count.values.push_back(float(v.count));
  }
  out.fields.push_back(std::move(count));
  if (config_.smoothing_radius <= 0.0) return out;
  return smooth_surface(out, config_);
}

namespace {

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
bool fit_weighted_plane(const PointCloud& cloud, const float* count, const Eigen::Vector3d& anchor,
                        const LocalMapConfig& c, SmoothingScratch& s, LocalSurface& f) {
  // Gaussian weights (sigma = radius / 2) times the number of returns of the voxel: a centroid of
  // n returns carries 1/n of a single return's range-noise variance.
  const double inv_two_sigma2 = 2.0 / (c.smoothing_radius * c.smoothing_radius);
  s.weights.resize(s.nb.size());
  double wsum = 0.0, sx = 0.0, sy = 0.0, sz = 0.0, xx = 0.0, xy = 0.0, xz = 0.0, yy = 0.0, yz = 0.0, zz = 0.0;
  for (std::size_t k = 0; k < s.nb.size(); ++k) {
    const Vec3f& p = cloud.points[s.nb.indices[k]];
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
void fit_height_field(const PointCloud& cloud, const LocalMapConfig& c, const SmoothingScratch& s, LocalSurface& f) {
  constexpr int n = kHeightTerms;
  // The lower triangle of Σ w φ φᵀ and Σ w h φ, as Eigen's rankUpdate formed them.
  double A_sum[n][n] = {}, b_sum[n] = {};
  for (std::size_t k = 0; k < s.nb.size(); ++k) {
    const Eigen::Vector3d d = cloud.points[s.nb.indices[k]].cast<double>() - f.mean;
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

LocalSurface fit_local_surface(const PointCloud& cloud, const float* count, const KdTree& tree,
                               const Eigen::Vector3d& anchor, const LocalMapConfig& c, SmoothingScratch& s) {
  constexpr std::size_t kMinPlane = 6, kMinQuadratic = 10;  // 3 and 6 unknowns, with margin
  LocalSurface f;
  tree.radius(anchor.cast<float>(), float(c.smoothing_radius), s.nb);
  if (s.nb.size() < (c.smoothing_quadratic ? kMinQuadratic : kMinPlane)) return f;
  if (!fit_weighted_plane(cloud, count, anchor, c, s, f)) return f;
  f.valid = true;
  if (c.smoothing_quadratic) fit_height_field(cloud, c, s, f);
  return f;
}

}  // namespace

PointCloud smooth_surface(const PointCloud& cloud, const LocalMapConfig& config) {
  PointCloud out;
  out.origin = cloud.origin;
  out.points = cloud.points;
  if (cloud.empty()) return out;
  const float* count = nullptr;
  for (const ScalarField& f : cloud.fields)
    if (f.name == "count" && f.values.size() == cloud.size()) count = f.values.data();
  const KdTree tree(cloud.points);
  // Groups of points that share one fitted surface: the cubes of side smoothing_block, each fitted
  // around the mean of its points (or every point alone around itself).
  std::vector<std::pair<std::uint64_t, std::uint32_t>> order(cloud.size());
  const double block = config.smoothing_block;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const Vec3f& p = cloud.points[i];
    const std::uint64_t key = block > 0.0 ? CellMap::key(std::int64_t(std::floor(p.x() / block)),
                                                         std::int64_t(std::floor(p.y() / block)),
                                                         std::int64_t(std::floor(p.z() / block)))
                                          : std::uint64_t(i);
    order[i] = {key, std::uint32_t(i)};
  }
  if (block > 0.0) std::sort(order.begin(), order.end());
  std::vector<std::size_t> starts;
  for (std::size_t i = 0; i < order.size(); ++i)
    if (i == 0 || order[i].first != order[i - 1].first) starts.push_back(i);
  starts.push_back(order.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, starts.size() - 1, 256), [&](const auto& r) {
    SmoothingScratch scratch;
    for (std::size_t g = r.begin(); g != r.end(); ++g) {
      Eigen::Vector3d anchor = Eigen::Vector3d::Zero();
      for (std::size_t k = starts[g]; k < starts[g + 1]; ++k) anchor += cloud.points[order[k].second].cast<double>();
      anchor /= double(starts[g + 1] - starts[g]);
      const LocalSurface f = fit_local_surface(cloud, count, tree, anchor, config, scratch);
      if (!f.valid) continue;
      for (std::size_t k = starts[g]; k < starts[g + 1]; ++k) {
        const std::uint32_t i = order[k].second;
        out.points[i] = f.project(cloud.points[i], config.smoothing_radius);
      }
    }
  });
  return voxel_downsample(out, {.res_voxel = config.voxel.res_voxel, .n_min = 1});
}

}  // namespace cairn
