#include "cairn/mapping/local_map.hpp"

#include <tbb/task_arena.h>

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>

#include "cairn/core/cell_map.hpp"
#include "cairn/core/log.hpp"

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
  const std::lock_guard lock(cache_.mutex);  // the erased voxels' shown centroids go to the cache
  std::erase_if(voxels_, [&](const Voxel& v) {
    if (keep(Eigen::Vector3d(origin_ + v.sum / v.count))) return false;
    if (v.shown_count > 0) cache_.vanished.push_back(v.shown);
    return true;
  });
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
  {
    const std::lock_guard lock(cache_.mutex);
    cache_.reset();
  }
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

PointCloud LocalMap::voxel_centroids(std::vector<Vec3f>& changed) const {
  PointCloud out;
  out.origin = origin_;
  out.reserve(voxels_.size());
  ScalarField count{"count", {}};
  count.values.reserve(voxels_.size());
  for (const Voxel& v : voxels_) {
    if (v.count < std::uint32_t(config_.voxel.n_min)) continue;
    const Vec3f p = (v.sum / v.count).cast<float>();
    if (v.shown_count != v.count || v.shown != p) {
      if (v.shown_count > 0) changed.push_back(v.shown);
      changed.push_back(p);
      v.shown = p;
      v.shown_count = v.count;
    }
    out.points.push_back(p);
    count.values.push_back(float(v.count));
  }
  out.fields.push_back(std::move(count));
  return out;
}

PointCloud LocalMap::compute_snapshot() const {
  const Stopwatch sw;
  std::vector<Vec3f> changed = std::move(cache_.vanished);
  cache_.vanished.clear();
  PointCloud raw = voxel_centroids(changed);  // the record of what was shown is updated here
  if (config_.smoothing_radius <= 0.0) return raw;
  const bool from_scratch = !cache_.smoother;
  if (from_scratch) cache_.smoother = std::make_unique<SurfaceSmoother>(config_);
  PointCloud smoothed;
  try {
    smoothed = cache_.smoother->smooth(raw, from_scratch ? std::nullopt : std::optional<std::span<const Vec3f>>(changed));
  } catch (...) {  // the changes are consumed: the kept surfaces would be stale
    cache_.smoother.reset();
    throw;
  }
  const SurfaceSmoother::Stats& st = cache_.smoother->last();
  spdlog::debug("local map snapshot: {} voxel positions changed, {} of {} surfaces refitted, {:.0f} ms", changed.size(),
                st.refitted, st.blocks, sw.elapsed_ms());
  return smoothed;
}

SurfaceSmoother::Stats LocalMap::last_smoothing() const {
  const std::lock_guard lock(cache_.mutex);
  return cache_.smoother ? cache_.smoother->last() : SurfaceSmoother::Stats{};
}

}  // namespace cairn
