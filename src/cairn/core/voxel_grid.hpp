#pragma once
// Voxel-grid downsampling (Sec. 4.2: res_voxel, n_min), same voxel semantics as PCL's VoxelGrid:
// voxel index = floor(p / leaf) (float arithmetic), one output point per occupied voxel at the
// centroid of its points, voxels with fewer than n_min points dropped, output ordered by voxel.
#include <cstdint>
#include <span>
#include <vector>

#include "cairn/core/point_cloud.hpp"

namespace cairn {

struct VoxelGridConfig {
  double res_voxel = 0.03;  // Table 3: voxel grid resolution [m]
  int n_min = 1;            // Table 3: min. point count per voxel

  template <class V>
  void visit(V& v) {
    v("res_voxel", res_voxel, "voxel grid resolution [m] (Table 3)");
    v("n_min", n_min, "minimum number of points for a voxel to be occupied (Table 3)");
  }
};

/// Occupied voxels: for each voxel (in ascending key order) the indices of its points.
struct VoxelPartition {
  std::vector<std::uint32_t> order;   // point indices grouped by voxel
  std::vector<std::uint32_t> offsets;  // voxel v holds order[offsets[v] .. offsets[v+1])
  [[nodiscard]] std::size_t num_voxels() const { return offsets.empty() ? 0 : offsets.size() - 1; }
  [[nodiscard]] std::span<const std::uint32_t> voxel(std::size_t v) const {
    return {order.data() + offsets[v], offsets[v + 1] - offsets[v]};
  }
};

/// Groups points by voxel; a point with a NaN or infinite coordinate belongs to no voxel (PCL's
/// VoxelGrid drops them too). Throws ConfigError if leaf <= 0 or the extent needs > 2^21 voxels
/// per axis.
[[nodiscard]] VoxelPartition voxelize(std::span<const Vec3f> points, double leaf);

/// Downsamples a cloud: positions, normals (re-normalised), colours, times and fields averaged,
/// labels by majority. Keeps the origin.
[[nodiscard]] PointCloud voxel_downsample(const PointCloud& cloud, const VoxelGridConfig& config);

}  // namespace cairn
