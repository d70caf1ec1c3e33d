#include "cairn/mapping/local_map.hpp"

#include <cmath>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "cairn/core/cell_map.hpp"
#include "cairn/core/kdtree.hpp"
#include "cairn/core/normals.hpp"
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
  return smooth_surface(out, config_.smoothing_radius, config_.smoothing_max_curvature, config_.voxel.res_voxel);
}

PointCloud smooth_surface(const PointCloud& cloud, double radius, double max_curvature, double res_voxel) {
  PointCloud out;
  out.origin = cloud.origin;
  out.points.resize(cloud.size());
  if (cloud.empty()) return out;
  const KdTree tree(cloud.points);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, cloud.size(), 1024), [&](const auto& r) {
    Neighbors nb;
    for (std::size_t i = r.begin(); i != r.end(); ++i) {
      const Vec3f& p = cloud.points[i];
      out.points[i] = p;
      tree.radius(p, float(radius), nb);
      if (nb.size() < 6) continue;
      const PcaFrame f = pca(cloud.points, nb.indices);
      const float sum = f.eigenvalues.sum();
      if (!(sum > 0.0f) || f.eigenvalues[0] / sum > max_curvature) continue;
      const Vec3f n = f.eigenvectors.col(0);
      out.points[i] = p - n * n.dot(p - f.mean);
    }
  });
  return voxel_downsample(out, {.res_voxel = res_voxel, .n_min = 1});
}

}  // namespace cairn
