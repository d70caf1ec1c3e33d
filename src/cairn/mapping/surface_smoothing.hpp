#pragma once
// Moving-least-squares smoothing of the local map's snapshots (a deviation from the paper, see
// docs/mapping.md): from scratch (smooth_surface) or incrementally, refitting only where the map
// changed since the previous snapshot (SurfaceSmoother).
#include <memory>
#include <optional>
#include <span>

#include "cairn/core/point_cloud.hpp"
#include "cairn/mapping/config.hpp"

namespace cairn {

/// Moving-least-squares smoothing of a voxel-grid cloud (config.smoothing_*): every point whose
/// neighbours within smoothing_radius form a surface (curvature λ0/(λ0+λ1+λ2) below
/// smoothing_max_curvature; edges and corners are kept) is moved onto the weighted least-squares
/// plane of the neighbourhood, or with smoothing_quadratic onto a quadratic height field over that
/// plane (no flattening of curved stone surfaces). Weights: Gaussian in the distance (σ = radius/2)
/// times the "count" field when present (points per voxel). One surface is fitted per cube of side
/// smoothing_block (around the mean of its points) and moves all of them; 0 fits one per point.
/// Then re-voxelised at config.voxel.res_voxel (merged duplicates). TBB-parallel, deterministic.
[[nodiscard]] PointCloud smooth_surface(const PointCloud& cloud, const LocalMapConfig& config);

/// smooth_surface of a cloud that changes a little between calls (the local map's snapshots: a
/// grasp removes one stone's voxels, a short sweep touches part of the site). It keeps the surface
/// fitted for every block (cube of side smoothing_block) and refits a block only where one of the
/// `changed` positions can be in its neighbourhood; every other block moves its points, which are
/// the same as before, onto its kept surface. A block's fit depends on its own points and those
/// within smoothing_radius of its anchor (the mean of its points, inside the cube), so every point
/// that can matter lies within smoothing_block/2 + smoothing_radius (per axis) of the cube's centre:
/// on a grid of that side, in the cell of the centre or one of its 26 neighbours. Blocks whose
/// centre cell is next to a cell holding a changed position are refitted (a superset of the blocks
/// that must be), the rest reused. The result is smooth_surface's up to rounding: neighbour lists
/// come from a tree over other points (sums in another order; a neighbour within float rounding
/// of the radius may be found by one search and not the other), and re-voxelising can turn such a
/// difference into another merge of two points. So a snapshot depends, at that level, on which
/// changes were smoothed together, not only on the map's state.
class SurfaceSmoother {
 public:
  struct Stats {
    std::size_t blocks = 0;       // fitted surfaces (cubes holding points)
    std::size_t refitted = 0;     // of them fitted in this call (all of them in a full pass)
    std::size_t tree_points = 0;  // points the neighbour searches ran over
    bool full = true;
  };

  explicit SurfaceSmoother(LocalMapConfig config);
  ~SurfaceSmoother();
  SurfaceSmoother(SurfaceSmoother&&) noexcept;
  SurfaceSmoother& operator=(SurfaceSmoother&&) noexcept;
  SurfaceSmoother(const SurfaceSmoother&) = delete;
  SurfaceSmoother& operator=(const SurfaceSmoother&) = delete;

  /// smooth_surface(cloud, config). `changed`: the positions (in the cloud's frame, relative to its
  /// origin) where a point appeared, vanished, moved from or to, or changed its "count" since the
  /// previous call; nullopt fits every block, as do the first call, a cloud with another origin and
  /// smoothing_block = 0 (one fit per point: no block to keep).
  [[nodiscard]] PointCloud smooth(const PointCloud& cloud, std::optional<std::span<const Vec3f>> changed);
  [[nodiscard]] const Stats& last() const { return stats_; }

 private:
  struct State;
  LocalMapConfig config_;
  std::unique_ptr<State> state_;
  Stats stats_;
};

}  // namespace cairn
