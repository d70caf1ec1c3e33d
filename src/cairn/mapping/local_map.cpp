#include "cairn/mapping/local_map.hpp"

#include <cmath>
#include <optional>

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

namespace {
constexpr std::uint64_t kEmptyKey = ~std::uint64_t{0};  // never produced by CellMap::key
constexpr std::size_t kMinIndexSize = 1024;
std::size_t slot_of(std::uint64_t key, std::size_t mask) {
  key ^= key >> 31;  // splitmix64 finaliser
  key *= 0x7fb5d329728ea185ULL;
  key ^= key >> 27;
  key *= 0x81dadef4bc2dd44dULL;
  key ^= key >> 33;
  return std::size_t(key) & mask;
}
}  // namespace

void LocalMap::rebuild_index(std::size_t capacity) {
  std::size_t size = kMinIndexSize;
  while (size < 2 * capacity) size *= 2;
  index_keys_.assign(size, kEmptyKey);
  index_pos_.assign(size, 0);
  const std::size_t mask = size - 1;
  for (std::size_t i = 0; i < voxels_.size(); ++i) {
    std::size_t s = slot_of(voxels_[i].key, mask);
    while (index_keys_[s] != kEmptyKey) s = (s + 1) & mask;
    index_keys_[s] = voxels_[i].key;
    index_pos_[s] = std::uint32_t(i);
  }
}

void LocalMap::add(const Eigen::Vector3d& p_world) {
  if (!p_world.allFinite()) return;
  if (!has_origin_) {
    origin_ = p_world.array().floor().matrix();  // whole metres: keys stay small, floats precise
    has_origin_ = true;
  }
  const Eigen::Vector3d p = p_world - origin_;
  const std::uint64_t key = key_of(p);
  if (2 * (voxels_.size() + 1) > index_keys_.size()) rebuild_index(2 * (voxels_.size() + 1));
  const std::size_t mask = index_keys_.size() - 1;
  std::size_t s = slot_of(key, mask);
  while (index_keys_[s] != key && index_keys_[s] != kEmptyKey) s = (s + 1) & mask;
  if (index_keys_[s] == kEmptyKey) {
    index_keys_[s] = key;
    index_pos_[s] = std::uint32_t(voxels_.size());
    voxels_.push_back({.sum = Eigen::Vector3d::Zero(), .count = 0, .key = key});
  }
  Voxel& v = voxels_[index_pos_[s]];
  v.sum += p;
  ++v.count;
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
  if (voxels_.size() != before) rebuild_index(voxels_.size());
  return before - voxels_.size();
}

std::size_t LocalMap::crop(const Vec3d& center) {
  const double r2 = config_.R_map * config_.R_map;
  return filter([&](const Eigen::Vector3d& c) { return (c - center).head<2>().squaredNorm() <= r2; });
}

std::size_t LocalMap::remove_sphere(const Vec3d& center, double radius) {
  return filter([&](const Eigen::Vector3d& c) { return (c - center).squaredNorm() > radius * radius; });
}

void LocalMap::clear() {
  voxels_.clear();
  index_keys_.clear();
  index_pos_.clear();
}

PointCloud LocalMap::snapshot() const {
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

// Moving least squares at one point: the weighted plane of its neighbourhood, and over it (when
// `quadratic`) a weighted quadratic height field. Returns the point moved onto that surface, or
// nothing where the neighbourhood is too small or not a surface.
struct SmoothingScratch {
  Neighbors nb;
  std::vector<double> weights;
};

std::optional<Vec3f> mls_project(const PointCloud& cloud, const float* count, const KdTree& tree, std::size_t i,
                                 const LocalMapConfig& c, SmoothingScratch& s) {
  constexpr std::size_t kMinPlane = 6, kMinQuadratic = 10;  // 3 and 6 unknowns, with margin
  const Vec3f& p = cloud.points[i];
  tree.radius(p, float(c.smoothing_radius), s.nb);
  if (s.nb.size() < (c.smoothing_quadratic ? kMinQuadratic : kMinPlane)) return std::nullopt;
  // Gaussian weights (sigma = radius / 2) times the number of hits of the voxel: a centroid of n
  // returns carries 1/n of a single return's range-noise variance.
  const double inv_two_sigma2 = 2.0 / (c.smoothing_radius * c.smoothing_radius);
  const Eigen::Vector3d ref = p.cast<double>();
  s.weights.resize(s.nb.size());
  double wsum = 0.0;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  Eigen::Matrix3d sq = Eigen::Matrix3d::Zero();
  for (std::size_t k = 0; k < s.nb.size(); ++k) {
    const double w = std::exp(-double(s.nb.sq_dists[k]) * inv_two_sigma2) * (count ? double(count[s.nb.indices[k]]) : 1.0);
    const Eigen::Vector3d d = cloud.points[s.nb.indices[k]].cast<double>() - ref;
    s.weights[k] = w;
    wsum += w;
    sum += w * d;
    sq += w * d * d.transpose();
  }
  if (!(wsum > 0.0)) return std::nullopt;
  const Eigen::Vector3d mean = sum / wsum;  // relative to p
  const Eigen::Matrix3d cov = sq / wsum - mean * mean.transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
  const Eigen::Vector3d ev = es.eigenvalues().cwiseMax(0.0);
  if (!(ev.sum() > 0.0) || ev[0] / ev.sum() > c.smoothing_max_curvature) return std::nullopt;
  const Eigen::Vector3d n = es.eigenvectors().col(0);
  const double h_p = -n.dot(mean);  // height of p above the plane
  if (!c.smoothing_quadratic) return (ref - n * h_p).cast<float>();
  // Height field h(x, y) = a0 + a1 x + a2 y + a3 x^2 + a4 xy + a5 y^2 over the plane, x and y
  // scaled by 1/radius (conditioning), centred at the mean.
  const Eigen::Vector3d e1 = es.eigenvectors().col(2), e2 = es.eigenvectors().col(1);
  const double scale = 1.0 / c.smoothing_radius;
  Eigen::Matrix<double, 6, 6> A = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, 1> b = Eigen::Matrix<double, 6, 1>::Zero();
  for (std::size_t k = 0; k < s.nb.size(); ++k) {
    const Eigen::Vector3d d = cloud.points[s.nb.indices[k]].cast<double>() - ref - mean;
    const double x = d.dot(e1) * scale, y = d.dot(e2) * scale;
    Eigen::Matrix<double, 6, 1> phi;
    phi << 1.0, x, y, x * x, x * y, y * y;
    A.selfadjointView<Eigen::Lower>().rankUpdate(phi, s.weights[k]);
    b += s.weights[k] * d.dot(n) * phi;
  }
  A = A.selfadjointView<Eigen::Lower>();
  const Eigen::LDLT<Eigen::Matrix<double, 6, 6>> ldlt(A);
  if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) return (ref - n * h_p).cast<float>();
  const Eigen::Matrix<double, 6, 1> a = ldlt.solve(b);
  const double x = -mean.dot(e1) * scale, y = -mean.dot(e2) * scale;
  const double h_fit = a[0] + a[1] * x + a[2] * y + a[3] * x * x + a[4] * x * y + a[5] * y * y;
  if (!std::isfinite(h_fit)) return (ref - n * h_p).cast<float>();
  return (ref - n * (h_p - h_fit)).cast<float>();
}

}  // namespace

PointCloud smooth_surface(const PointCloud& cloud, const LocalMapConfig& config) {
  PointCloud out;
  out.origin = cloud.origin;
  out.points.resize(cloud.size());
  if (cloud.empty()) return out;
  const float* count = nullptr;
  for (const ScalarField& f : cloud.fields)
    if (f.name == "count" && f.values.size() == cloud.size()) count = f.values.data();
  const KdTree tree(cloud.points);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, cloud.size(), 1024), [&](const auto& r) {
    SmoothingScratch scratch;
    for (std::size_t i = r.begin(); i != r.end(); ++i)
      out.points[i] = mls_project(cloud, count, tree, i, config, scratch).value_or(cloud.points[i]);
  });
  return voxel_downsample(out, {.res_voxel = config.voxel.res_voxel, .n_min = 1});
}

}  // namespace cairn
