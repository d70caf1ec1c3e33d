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

void LocalMap::add(const Eigen::Vector3d& p_world) {
  if (!p_world.allFinite()) return;
  if (!has_origin_) {
    origin_ = p_world.array().floor().matrix();  // whole metres: keys stay small, floats precise
    has_origin_ = true;
  }
  const Eigen::Vector3d p = p_world - origin_;
  Voxel& v = voxels_[key_of(p)];
  v.sum += p;
  ++v.count;
}

void LocalMap::insert(const PointCloud& cloud) {
  for (std::size_t i = 0; i < cloud.size(); ++i) add(cloud.world(i));
}

void LocalMap::insert(std::span<const Vec3f> points, const Eigen::Isometry3d& T_world_F) {
  for (const Vec3f& p : points) add(T_world_F * p.cast<double>());
}

std::size_t LocalMap::crop(const Vec3d& center) {
  const double r2 = config_.R_map * config_.R_map;
  std::size_t removed = 0;
  for (auto it = voxels_.begin(); it != voxels_.end();) {
    const Eigen::Vector3d c = origin_ + it->second.sum / it->second.count;
    if ((c - center).head<2>().squaredNorm() > r2) {
      it = voxels_.erase(it);
      ++removed;
    } else {
      ++it;
    }
  }
  return removed;
}

std::size_t LocalMap::remove_sphere(const Vec3d& center, double radius) {
  std::size_t removed = 0;
  for (auto it = voxels_.begin(); it != voxels_.end();) {
    const Eigen::Vector3d c = origin_ + it->second.sum / it->second.count;
    if ((c - center).squaredNorm() <= radius * radius) {
      it = voxels_.erase(it);
      ++removed;
    } else {
      ++it;
    }
  }
  return removed;
}

void LocalMap::clear() { voxels_.clear(); }

PointCloud LocalMap::snapshot() const {
  PointCloud out;
  out.origin = origin_;
  out.reserve(voxels_.size());
  ScalarField count{"count", {}};
  count.values.reserve(voxels_.size());
  for (const auto& [key, v] : voxels_) {
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
