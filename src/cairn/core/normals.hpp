#pragma once
// PCA surface normals: eigenvector of the smallest eigenvalue of the neighbourhood covariance,
// oriented towards a viewpoint (as PCL's NormalEstimation + flipNormalTowardsViewpoint).
#include <span>
#include <vector>

#include "cairn/core/kdtree.hpp"

namespace cairn {

struct NormalConfig {
  double radius = 0.1;  // neighbourhood radius [m]; used when k == 0
  int k = 0;            // k nearest neighbours instead of a radius when > 0
  double viewpoint_x = 0.0, viewpoint_y = 0.0, viewpoint_z = 0.0;  // normals point towards it

  template <class V>
  void visit(V& v) {
    v("radius", radius, "neighbourhood radius for PCA normals [m] (used when k = 0)");
    v("k", k, "number of nearest neighbours for PCA normals (0: use radius)");
    v("viewpoint_x", viewpoint_x, "viewpoint the normals are oriented towards, x [m]");
    v("viewpoint_y", viewpoint_y, "viewpoint, y [m]");
    v("viewpoint_z", viewpoint_z, "viewpoint, z [m]");
  }
};

struct NormalResult {
  std::vector<Vec3f> normals;    // zero vector where fewer than 3 neighbours were found
  std::vector<float> curvature;  // λ0 / (λ0 + λ1 + λ2), NaN where invalid
  std::size_t num_invalid = 0;
};

/// Normals of `points` using `tree` (built over the same or another point set) for neighbours.
[[nodiscard]] NormalResult estimate_normals(std::span<const Vec3f> points, const KdTree& tree,
                                            const NormalConfig& config);

/// Smallest-eigenvalue eigenvector and eigenvalues (ascending) of the covariance of `neighbors`.
struct PcaFrame {
  Vec3f mean;
  Eigen::Matrix3f eigenvectors;  // columns, ascending eigenvalues
  Eigen::Vector3f eigenvalues;
};
[[nodiscard]] PcaFrame pca(std::span<const Vec3f> points, std::span<const std::uint32_t> indices);

}  // namespace cairn
