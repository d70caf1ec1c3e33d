#pragma once
// Sec. 4.2: the robot-centric local map — a voxel grid (res_voxel = 3 cm, n_min = 1, Table 3)
// restricted to a vertical cylinder of radius R_map = 10 m around the robot, updated online.
// Each voxel keeps the running centroid of the points that fell into it (as a voxel-grid filter
// of everything seen). Other stages take snapshots; object grasps remove a sphere (Sec. 5,
// R_obj) and insertions add points (e.g. a placed stone's model).
#include <cstdint>
#include <memory>
#include <mutex>
#include <span>
#include <vector>

#include "cairn/core/cell_map.hpp"
#include "cairn/core/point_cloud.hpp"
#include "cairn/mapping/config.hpp"
#include "cairn/mapping/map_edit.hpp"
#include "cairn/mapping/surface_smoothing.hpp"

namespace cairn {

class LocalMap {
 public:
  explicit LocalMap(LocalMapConfig config = {});

  /// Adds world points (cloud.origin + point). Non-finite points are skipped.
  void insert(const PointCloud& cloud);
  /// Adds points given in frame F, with T_world_F.
  void insert(std::span<const Vec3f> points, const Eigen::Isometry3d& T_world_F);
  /// Drops voxels whose centre is farther than R_map from `center` horizontally (cylinder).
  std::size_t crop(const Vec3d& center);
  /// Removes every voxel whose centroid lies within `radius` of `center`; returns how many.
  std::size_t remove_sphere(const Vec3d& center, double radius);
  /// Applies an edit (removes the voxels whose centroid it removes, or inserts its points);
  /// returns the number of voxels removed.
  std::size_t apply(const MapEdit& edit);
  void clear();

  /// One point per voxel with at least n_min points, at the centroid (world = origin + point),
  /// then smoothed (config.smoothing_radius > 0, see smooth_surface). The "count" scalar field
  /// holds the number of points per voxel (unsmoothed snapshots only). Computed once per state
  /// of the map: asking again before the next insert, erase or clear returns the same cloud.
  /// Smoothing is incremental (SurfaceSmoother): only where voxels changed since the last
  /// snapshot are surfaces fitted again.
  [[nodiscard]] PointCloud snapshot() const;
  /// What the smoothing of the last snapshot did (refitted surfaces, full pass or not).
  [[nodiscard]] SurfaceSmoother::Stats last_smoothing() const;
  [[nodiscard]] std::size_t num_voxels() const { return voxels_.size(); }
  [[nodiscard]] const LocalMapConfig& config() const { return config_; }

 private:
  struct Voxel {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();  // relative to origin_
    std::uint32_t count = 0;
    std::uint64_t key = 0;
    // What the last snapshot showed of this voxel (its centroid and count; count 0: nothing), to
    // tell the smoother where the map changed. Written by snapshot() (under the cache's lock), so
    // a snapshot must not run while another thread copies the map.
    mutable Vec3f shown = Vec3f::Zero();
    mutable std::uint32_t shown_count = 0;
  };
  [[nodiscard]] std::uint64_t key_of(const Eigen::Vector3d& p_rel) const;
  void add(const Eigen::Vector3d& p_world);
  /// Keeps the voxels for which keep(centroid_world) holds; returns how many were dropped.
  template <class Keep>
  std::size_t filter(Keep keep);
  void rebuild_index();
  [[nodiscard]] PointCloud compute_snapshot() const;
  /// The voxel centroids with at least n_min points, with their counts; `changed` gets the
  /// positions where this differs from what the last snapshot showed (and the record is updated).
  [[nodiscard]] PointCloud voxel_centroids(std::vector<Vec3f>& changed) const;

  /// The last snapshot and the map revision it was taken at (smoothing is the expensive part of
  /// a snapshot, and several stages ask for the same state). A copy or move of the map, and the
  /// moved-from map, start without one.
  struct SnapshotCache {
    std::mutex mutex;
    std::uint64_t revision = 0;
    std::shared_ptr<const PointCloud> cloud;
    // The smoother keeps the surfaces of the last snapshot; `vanished`: where shown voxels were
    // erased since (each shown voxel at most once, so no longer than that snapshot).
    std::unique_ptr<SurfaceSmoother> smoother;
    std::vector<Vec3f> vanished;
    SnapshotCache() = default;
    SnapshotCache(const SnapshotCache& /*other*/) {}
    SnapshotCache(SnapshotCache&& other) noexcept { other.reset(); }  // the moved-from map is empty
    SnapshotCache& operator=(const SnapshotCache& /*other*/) {
      const std::lock_guard lock(mutex);
      reset();
      return *this;
    }
    SnapshotCache& operator=(SnapshotCache&& other) noexcept {
      reset();
      other.reset();
      return *this;
    }
    ~SnapshotCache() = default;
    void reset() {
      cloud.reset();
      smoother.reset();
      vanished.clear();
    }
  };

  LocalMapConfig config_;
  std::uint64_t revision_ = 0;  // bumped by every change of the voxels
  mutable SnapshotCache cache_;
  bool has_origin_ = false;
  Vec3d origin_ = Vec3d::Zero();
  // Voxels stored densely; the voxel hash (core/cell_map.hpp) maps a key to its position.
  // Erasing (crop, remove_sphere) compacts and re-indexes.
  std::vector<Voxel> voxels_;
  CellMap index_;
};

}  // namespace cairn
