#pragma once
// Hand-made scenes for the object database tests: ground grids and round stones with known poses.
#include <cmath>
#include <numbers>

#include "cairn/core/point_cloud.hpp"

namespace cairn::test {

/// Points on the upper part (z > z_min) of a sphere: a round stone resting on the ground.
inline PointCloud stone(const Vec3d& center, double radius, int n = 1500, double z_min = 0.02) {
  PointCloud c;
  c.origin = center.array().floor().matrix();
  const double golden = std::numbers::pi * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < n; ++i) {  // Fibonacci sphere: deterministic, uniform
    const double z = 1.0 - 2.0 * (i + 0.5) / n, r = std::sqrt(1.0 - z * z), a = golden * i;
    const Vec3d p = center + radius * Vec3d(r * std::cos(a), r * std::sin(a), z);
    if (p.z() > z_min) c.points.push_back((p - c.origin).cast<float>());
  }
  return c;
}

/// An elongated stone (an ellipsoid with semi-axes a, b, c): orientation observable.
inline PointCloud ellipsoid(const Vec3d& center, const Vec3d& axes, int n = 2500) {
  PointCloud c = stone(Vec3d::Zero(), 1.0, n, -2.0);
  c.origin = center.array().floor().matrix();
  for (Vec3f& p : c.points) p = (p.cast<double>().cwiseProduct(axes) + center - c.origin).cast<float>();
  return c;
}

/// A square grid of ground points at z = 0 (half-size h, spacing s) around (cx, cy).
inline PointCloud ground(double cx, double cy, double h, double s = 0.03) {
  PointCloud c;
  c.origin = Vec3d(std::floor(cx), std::floor(cy), 0.0);
  for (double x = -h; x <= h; x += s)
    for (double y = -h; y <= h; y += s) c.points.push_back((Vec3d(cx + x, cy + y, 0.0) - c.origin).cast<float>());
  return c;
}

}  // namespace cairn::test
