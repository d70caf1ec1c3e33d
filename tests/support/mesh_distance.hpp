#pragma once
// Exact point-to-mesh distances for tests (brute force over triangles with bounding spheres).
#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <limits>
#include <vector>

#include "cairn/core/io/io.hpp"

namespace cairn::test {

using Eigen::Vector3d;

/// Closest point on triangle abc to p (Ericson, Real-Time Collision Detection, 5.1.5).
inline Vector3d closest_on_triangle(const Vector3d& p, const Vector3d& a, const Vector3d& b,
                             const Vector3d& c) {
  const Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + d1 / (d1 - d3) * ab;
  const Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + d2 / (d2 - d6) * ac;
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0)
    return b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b);
  const double denom = 1.0 / (va + vb + vc);
  return a + ab * (vb * denom) + ac * (vc * denom);
}

/// Point-to-surface distances: triangles with bounding spheres to skip far ones.
class TriangleSoup {
 public:
  explicit TriangleSoup(const io::Mesh& mesh) {
    for (const auto& [i, j, k] : mesh.triangles) {
      const std::array<Vector3d, 3> t{mesh.vertices.world(i), mesh.vertices.world(j), mesh.vertices.world(k)};
      const Vector3d centre = (t[0] + t[1] + t[2]) / 3.0;
      double radius = 0.0;
      for (const auto& v : t) radius = std::max(radius, (v - centre).norm());
      triangles_.push_back(t);
      centres_.push_back(centre);
      radii_.push_back(radius);
    }
  }

  [[nodiscard]] double distance(const Vector3d& p) const {
    double best = std::numeric_limits<double>::max();
    for (std::size_t t = 0; t < triangles_.size(); ++t) {
      if ((p - centres_[t]).norm() - radii_[t] >= best) continue;
      const auto& [a, b, c] = triangles_[t];
      best = std::min(best, (p - closest_on_triangle(p, a, b, c)).norm());
    }
    return best;
  }

 private:
  std::vector<std::array<Vector3d, 3>> triangles_;
  std::vector<Vector3d> centres_;
  std::vector<double> radii_;
};

}  // namespace cairn::test
