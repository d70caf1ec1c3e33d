#pragma once
// Synthetic scenes for grasp planning tests: sampled boxes, spheres, cylinders and a ground plane.
#include <cmath>
#include <functional>
#include <numbers>

#include "cairn/core/point_cloud.hpp"

namespace cairn::test {

/// Points on the surface of an axis-aligned box (centre c, half extents h) at spacing s, with
/// outward normals; the face z = c.z - h.z is left out when `with_bottom` is false.
inline PointCloud box_surface(const Vec3d& c, const Vec3d& h, double s, bool with_bottom = true) {
  PointCloud out;
  for (int axis = 0; axis < 3; ++axis) {
    for (const double side : {-1.0, 1.0}) {
      if (axis == 2 && side < 0 && !with_bottom) continue;
      const int u = (axis + 1) % 3, v = (axis + 2) % 3;
      for (double a = -h[u]; a <= h[u] + 1e-9; a += s) {
        for (double b = -h[v]; b <= h[v] + 1e-9; b += s) {
          Vec3d p = c;
          p[axis] += side * h[axis];
          p[u] += a;
          p[v] += b;
          Vec3f n = Vec3f::Zero();
          n[axis] = float(side);
          out.points.push_back(p.cast<float>());
          out.normals.push_back(n);
        }
      }
    }
  }
  return out;
}

/// A horizontal ground square (z = height) of half-size `half` around (0, 0), spacing s, with a
/// hole of radius `hole` around (0, 0) (unobserved ground: occluded by the object).
inline PointCloud ground_square(double half, double height, double s, double hole = 0.0) {
  PointCloud out;
  for (double x = -half; x <= half + 1e-9; x += s)
    for (double y = -half; y <= half + 1e-9; y += s) {
      if (std::hypot(x, y) < hole) continue;
      out.points.emplace_back(float(x), float(y), float(height));
      out.normals.emplace_back(0.0f, 0.0f, 1.0f);
    }
  return out;
}

/// Points on a sphere (Fibonacci lattice) with outward normals.
inline PointCloud sphere_surface(const Vec3d& c, double r, int n) {
  PointCloud out;
  const double golden = std::numbers::pi * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < n; ++i) {
    const double z = 1.0 - 2.0 * (i + 0.5) / n, rho = std::sqrt(1.0 - z * z), phi = golden * i;
    const Vec3d d(rho * std::cos(phi), rho * std::sin(phi), z);
    out.points.push_back((c + r * d).cast<float>());
    out.normals.push_back(d.cast<float>());
  }
  return out;
}

/// Points on a cylinder's side along `axis` (unit) through c, radius r, half length l.
inline PointCloud cylinder_surface(const Vec3d& c, const Vec3d& axis, double r, double l, double s) {
  PointCloud out;
  const Vec3d u = axis.unitOrthogonal(), v = axis.cross(u);
  const int around = int(std::ceil(2.0 * std::numbers::pi * r / s));
  for (double t = -l; t <= l + 1e-9; t += s)
    for (int k = 0; k < around; ++k) {
      const double a = 2.0 * std::numbers::pi * k / around;
      const Vec3d d = std::cos(a) * u + std::sin(a) * v;
      out.points.push_back((c + t * axis + r * d).cast<float>());
      out.normals.push_back(d.cast<float>());
    }
  return out;
}

}  // namespace cairn::test
