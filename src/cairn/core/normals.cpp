#include "cairn/core/normals.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <limits>

namespace cairn {

PcaFrame pca(std::span<const Vec3f> points, std::span<const std::uint32_t> indices) {
  // Covariance accumulated in double around the first point for numerical stability.
  const Eigen::Vector3d ref = points[indices[0]].cast<double>();
  // The six distinct second moments only (the matrix is symmetric): the same products and sums
  // per entry as the full outer product (bit-identical unless the compiler contracts to FMA).
  double sx = 0, sy = 0, sz = 0, xx = 0, xy = 0, xz = 0, yy = 0, yz = 0, zz = 0;
  for (auto i : indices) {
    const double x = double(points[i].x()) - ref.x(), y = double(points[i].y()) - ref.y(),
                 z = double(points[i].z()) - ref.z();
    sx += x;
    sy += y;
    sz += z;
    xx += x * x;
    xy += x * y;
    xz += x * z;
    yy += y * y;
    yz += y * z;
    zz += z * z;
  }
  const double n = double(indices.size());
  const Eigen::Vector3d mean(sx / n, sy / n, sz / n);
  Eigen::Matrix3d cov;
  cov << xx / n, xy / n, xz / n, xy / n, yy / n, yz / n, xz / n, yz / n, zz / n;
  cov -= mean * mean.transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
  return {(ref + mean).cast<float>(), es.eigenvectors().cast<float>(),
          es.eigenvalues().cwiseMax(0.0).cast<float>()};
}

NormalResult estimate_normals(std::span<const Vec3f> points, const KdTree& tree,
                              const NormalConfig& config) {
  constexpr std::size_t kMinNeighbors = 3;
  NormalResult out;
  out.normals.assign(points.size(), Vec3f::Zero());
  out.curvature.assign(points.size(), std::numeric_limits<float>::quiet_NaN());
  const Vec3f viewpoint(float(config.viewpoint_x), float(config.viewpoint_y), float(config.viewpoint_z));
  std::atomic<std::size_t> invalid{0};
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, points.size(), 512), [&](const auto& r) {
    Neighbors nb;
    for (auto i = r.begin(); i != r.end(); ++i) {
      if (config.k > 0)
        tree.knn(points[i], std::size_t(config.k), nb);
      else
        tree.radius(points[i], float(config.radius), nb);
      if (nb.size() < kMinNeighbors) {
        ++invalid;
        continue;
      }
      const PcaFrame f = pca(tree.points(), nb.indices);
      Vec3f n = f.eigenvectors.col(0);
      if (n.dot(viewpoint - points[i]) < 0.0f) n = -n;
      out.normals[i] = n;
      const float total = f.eigenvalues.sum();
      out.curvature[i] = total > 0.0f ? f.eigenvalues[0] / total : 0.0f;
    }
  });
  out.num_invalid = invalid;
  return out;
}

}  // namespace cairn
