#pragma once
// Synthetic registration problems shared by tests/registration, the peer cross-checks and
// bench/bench_icp: a stone site (undulating ground, ellipsoid boulders, two walls) sampled
// independently for source and target, so no point has an exact counterpart (as with real scans).
#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "cairn/core/point_cloud.hpp"

namespace cairn::test {

struct Boulder {
  Vec3f center;
  Vec3f radii;
  Eigen::Matrix3f rotation;
};

inline float ground_height(float x, float y) { return 0.15f * std::sin(0.4f * x) * std::cos(0.3f * y); }

/// A fixed 30 m × 30 m site (independent of any seed): 14 boulders of 0.4–1.4 m and two walls.
inline std::vector<Boulder> site_boulders() {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<float> pos(-12.0f, 12.0f), rad(0.4f, 1.4f), ang(-3.14159f, 3.14159f);
  std::vector<Boulder> b;
  for (int i = 0; i < 14; ++i) {
    const float x = pos(rng), y = pos(rng);
    const Vec3f r(rad(rng), rad(rng), 0.6f * rad(rng));
    const Eigen::Matrix3f R =
        (Eigen::AngleAxisf(ang(rng), Vec3f::UnitZ()) * Eigen::AngleAxisf(0.3f * ang(rng) / 3.14159f, Vec3f::UnitX()))
            .toRotationMatrix();
    b.push_back({Vec3f(x, y, ground_height(x, y) + 0.5f * r.z()), r, R});
  }
  return b;
}

/// Samples a point on the site: ground (area 900 m²), boulders, walls at x = 14 and y = -14.
/// lidar_like: density ∝ 1/range² around `sensor`, up to `max_range` (a scan, not a map).
inline std::vector<Vec3f> sample_site(std::size_t n, std::uint64_t seed, float noise_sigma = 0.0f,
                                      bool lidar_like = false, const Vec3f& sensor = Vec3f(0, 0, 2),
                                      float max_range = 18.0f) {
  static const std::vector<Boulder> boulders = site_boulders();
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  std::normal_distribution<float> g(0.0f, 1.0f);
  std::vector<Vec3f> out;
  out.reserve(n);
  while (out.size() < n) {
    Vec3f p;
    const float kind = u(rng);
    if (kind < 0.70f) {  // ground
      const float x = -15.0f + 30.0f * u(rng), y = -15.0f + 30.0f * u(rng);
      p = {x, y, ground_height(x, y)};
    } else if (kind < 0.90f) {  // boulder surface
      const Boulder& b = boulders[std::size_t(u(rng) * float(boulders.size())) % boulders.size()];
      const Vec3f d = Vec3f(g(rng), g(rng), g(rng)).normalized();
      p = b.center + b.rotation * b.radii.cwiseProduct(d);
      if (p.z() < ground_height(p.x(), p.y())) continue;  // buried part
    } else if (kind < 0.95f) {  // wall x = 14 (3 m high)
      p = {14.0f, -15.0f + 30.0f * u(rng), 3.0f * u(rng)};
    } else {  // wall y = -14, 2 m high
      p = {-15.0f + 30.0f * u(rng), -14.0f, 2.0f * u(rng)};
    }
    if (lidar_like) {
      const float r = (p - sensor).norm();
      if (r > max_range) continue;
      if (u(rng) > std::min(1.0f, 9.0f / (r * r))) continue;  // density ∝ 1/r² beyond 3 m
    }
    if (noise_sigma > 0.0f) p += noise_sigma * Vec3f(g(rng), g(rng), g(rng));
    out.push_back(p);
  }
  return out;
}

/// Planes only (floor, two walls, a 30° ramp): for objective comparisons.
inline std::vector<Vec3f> sample_planes(std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  std::vector<Vec3f> out;
  out.reserve(n);
  const float c = std::cos(0.5236f), s = std::sin(0.5236f);
  for (std::size_t i = 0; i < n; ++i) {
    const float a = 10.0f * u(rng), b = 3.0f * u(rng);
    switch (i % 4) {
      case 0: out.emplace_back(10.0f * u(rng), 10.0f * u(rng), 0.0f); break;
      case 1: out.emplace_back(0.0f, a, b); break;
      case 2: out.emplace_back(a, 10.0f, b); break;
      default: out.emplace_back(3.0f + 3.0f * u(rng) * c, 2.0f + 5.0f * u(rng), 3.0f * u(rng) * s); break;
    }
  }
  return out;
}

inline std::vector<Vec3f> transformed(const std::vector<Vec3f>& pts, const Eigen::Isometry3d& T) {
  std::vector<Vec3f> out;
  out.reserve(pts.size());
  for (const auto& p : pts) out.push_back((T * p.cast<double>()).cast<float>());
  return out;
}

inline Eigen::Isometry3d make_pose(double roll, double pitch, double yaw, const Eigen::Vector3d& t) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  T.translation() = t;
  return T;
}

/// Rotation error [rad] and translation error [m] of `T` against `T_ref`.
struct PoseError {
  double rotation = 0.0, translation = 0.0;
};
inline PoseError pose_error(const Eigen::Isometry3d& T, const Eigen::Isometry3d& T_ref) {
  const Eigen::Isometry3d d = T_ref.inverse() * T;
  return {Eigen::AngleAxisd(d.linear()).angle(), (T.translation() - T_ref.translation()).norm()};
}

}  // namespace cairn::test
