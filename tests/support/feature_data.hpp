#pragma once
// Inputs shared by the feature tests (tests/features, tests/peers) and bench/bench_features:
// real clouds of the shared data folder and PCL's UniformSampling keypoint selection.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <span>
#include <unordered_map>
#include <vector>

#include "cairn/core/io/io.hpp"
#include "cairn/core/kdtree.hpp"
#include "cairn/core/point_cloud.hpp"
#include "support/test_data.hpp"

namespace cairn::test {

/// Positions of a cloud from the shared real data (non-finite points dropped).
inline std::vector<Vec3f> load_real_points(const std::filesystem::path& relative) {
  return io::load_cloud(real_data(relative), {.drop_non_finite = true}).points;
}

/// Indices of the points PCL's UniformSampling keeps: per voxel of edge `leaf` (index
/// floor(p / leaf)), the point closest to the voxel centre; ascending voxel key order.
inline std::vector<std::uint32_t> uniform_sampling(std::span<const Vec3f> points, float leaf) {
  struct Best {
    std::uint32_t index;
    float d2;
  };
  std::unordered_map<std::uint64_t, Best> best;
  const float inv = 1.0f / leaf;
  for (std::uint32_t i = 0; i < points.size(); ++i) {
    const Eigen::Array3f f = (points[i].array() * inv).floor();
    const Eigen::Array3i ijk = f.cast<int>();
    const std::uint64_t key = (std::uint64_t(std::uint32_t(ijk[0] + (1 << 20))) << 42) |
                              (std::uint64_t(std::uint32_t(ijk[1] + (1 << 20))) << 21) |
                              std::uint64_t(std::uint32_t(ijk[2] + (1 << 20)));
    const Vec3f center = ((f + 0.5f) * leaf).matrix();
    const float d2 = (points[i] - center).squaredNorm();
    auto [it, fresh] = best.try_emplace(key, Best{i, d2});
    if (!fresh && d2 < it->second.d2) it->second = {i, d2};
  }
  std::vector<std::pair<std::uint64_t, std::uint32_t>> sorted;
  for (const auto& [k, b] : best) sorted.emplace_back(k, b.index);
  std::sort(sorted.begin(), sorted.end());
  std::vector<std::uint32_t> out;
  for (const auto& [k, i] : sorted) out.push_back(i);
  return out;
}

inline std::vector<Vec3f> gather(std::span<const Vec3f> points, std::span<const std::uint32_t> indices) {
  std::vector<Vec3f> out;
  out.reserve(indices.size());
  for (auto i : indices) out.push_back(points[i]);
  return out;
}

/// Share of `model` points that `T` places within `distance` of a `scene` point.
inline double overlap(std::span<const Vec3f> model, std::span<const Vec3f> scene, const Eigen::Isometry3d& T,
                      double distance) {
  const KdTree tree(scene);
  std::size_t close = 0;
  for (const auto& p : model) {
    float d2 = 0.0f;
    (void)tree.nearest((T * p.cast<double>()).cast<float>(), &d2);
    close += double(d2) < distance * distance;
  }
  return model.empty() ? 0.0 : double(close) / double(model.size());
}

/// RMS distance from the `model` points placed by `T` to their nearest `scene` points.
inline double rms_to_nearest(std::span<const Vec3f> model, std::span<const Vec3f> scene, const Eigen::Isometry3d& T) {
  const KdTree tree(scene);
  double sum = 0.0;
  for (const auto& p : model) {
    float d2 = 0.0f;
    (void)tree.nearest((T * p.cast<double>()).cast<float>(), &d2);
    sum += double(d2);
  }
  return model.empty() ? 0.0 : std::sqrt(sum / double(model.size()));
}

}  // namespace cairn::test
