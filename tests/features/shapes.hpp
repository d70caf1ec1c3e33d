#pragma once
// Synthetic shapes for the feature tests: fixed seeds, known geometry.
#include <Eigen/Geometry>
#include <array>
#include <cmath>
#include <random>
#include <vector>

#include "cairn/core/point_cloud.hpp"
#include "support/registration_scenes.hpp"  // transformed(), make_pose()

namespace cairn::test {

/// Uniform random points on the surface of an axis-aligned cube of edge `edge` centred at 0.
inline std::vector<Vec3f> cube_surface(float edge, std::size_t n, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-0.5f * edge, 0.5f * edge);
  std::uniform_int_distribution<int> face(0, 5);
  std::vector<Vec3f> out(n);
  for (auto& p : out) {
    const int f = face(rng);
    p = {u(rng), u(rng), u(rng)};
    p[f / 2] = (f % 2 ? 0.5f : -0.5f) * edge;
  }
  return out;
}

inline std::array<Vec3f, 8> cube_corners(float edge) {
  std::array<Vec3f, 8> c;
  for (int i = 0; i < 8; ++i)
    c[std::size_t(i)] = 0.5f * edge * Vec3f(i & 1 ? 1.f : -1.f, i & 2 ? 1.f : -1.f, i & 4 ? 1.f : -1.f);
  return c;
}

/// An irregular stone-like surface: a 0.5 m sphere with random low-frequency bumps (no
/// symmetry), uniformly sampled, optional Gaussian noise.
inline std::vector<Vec3f> bumpy_surface(std::size_t n, std::uint32_t seed, float noise = 0.0f) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> g(0.0f, 1.0f);
  std::vector<Vec3f> bumps(12);
  for (auto& b : bumps) b = Vec3f(g(rng), g(rng), g(rng)).normalized();
  std::vector<Vec3f> out(n);
  for (auto& p : out) {
    const Vec3f d = Vec3f(g(rng), g(rng), g(rng)).normalized();
    float r = 0.5f;
    for (std::size_t k = 0; k < bumps.size(); ++k)
      r += 0.06f * float(k % 3 + 1) / 3.0f * std::exp(-8.0f * (d - bumps[k]).squaredNorm());
    p = r * d + noise * Vec3f(g(rng), g(rng), g(rng));
  }
  return out;
}

inline std::vector<Vec3f> rotated(const std::vector<Vec3f>& v, const Eigen::Matrix3d& R) {
  std::vector<Vec3f> out;
  out.reserve(v.size());
  for (const auto& n : v) out.push_back((R * n.cast<double>()).cast<float>());
  return out;
}

}  // namespace cairn::test
