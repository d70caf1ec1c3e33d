#pragma once
// Euclidean clustering (Sec. 4.3): connected components of the graph linking points closer than
// a tolerance — the same partition as PCL's EuclideanClusterExtraction for the same tolerance.
#include <cstdint>
#include <span>
#include <vector>

#include "cairn/core/point_cloud.hpp"

namespace cairn {

struct ClusterConfig {
  double tolerance = 0.10;  // [m] points closer than this belong to the same cluster
  int min_points = 50;      // smaller clusters are dropped
  int max_points = 0;       // larger clusters are dropped (0: no limit), as PCL

  template <class V>
  void visit(V& v) {
    v("tolerance", tolerance, "Euclidean clustering distance [m]");
    v("min_points", min_points, "clusters with fewer points are dropped");
    v("max_points", max_points, "clusters with more points are dropped (0: no limit)");
  }
};

/// Clusters of `points[indices]` (all points when indices is empty), each a list of indices into
/// `points` in ascending order; clusters ordered by size, largest first (ties: smallest index).
[[nodiscard]] std::vector<std::vector<std::uint32_t>> euclidean_clusters(
    std::span<const Vec3f> points, std::span<const std::uint32_t> indices, const ClusterConfig& config);

}  // namespace cairn
