#include <gtest/gtest.h>

#include <map>
#include <random>

#include "cairn/core/error.hpp"
#include "cairn/core/voxel_grid.hpp"

using namespace cairn;

TEST(VoxelGrid, CentroidsAndCountsMatchDirectComputation) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<float> u(-2.0f, 2.0f);
  PointCloud c;
  for (int i = 0; i < 20000; ++i) c.points.emplace_back(u(rng), u(rng), 0.3f * u(rng));
  const float leaf = 0.1f;
  std::map<std::tuple<int, int, int>, std::pair<Eigen::Vector3d, int>> expect;
  for (const auto& p : c.points) {
    auto [it, fresh] = expect.try_emplace(
        {int(std::floor(p.x() / leaf)), int(std::floor(p.y() / leaf)), int(std::floor(p.z() / leaf))},
        Eigen::Vector3d::Zero(), 0);
    auto& e = it->second;
    e.first += p.cast<double>();
    ++e.second;
  }
  for (int n_min : {1, 3}) {
    const PointCloud out = voxel_downsample(c, {.res_voxel = leaf, .n_min = n_min});
    std::size_t count = 0;
    for (const auto& [k, v] : expect) count += v.second >= n_min;
    ASSERT_EQ(out.size(), count);
    for (const auto& p : out.points) {
      const auto& e = expect.at({int(std::floor(p.x() / leaf)), int(std::floor(p.y() / leaf)), int(std::floor(p.z() / leaf))});
      EXPECT_LT((p.cast<double>() - e.first / e.second).norm(), 1e-5);
    }
  }
}

TEST(VoxelGrid, AttributesAveraged) {
  PointCloud c;
  c.points = {{0.01f, 0.01f, 0.01f}, {0.02f, 0.02f, 0.02f}, {0.5f, 0.5f, 0.5f}};
  c.normals = {{0, 0, 1}, {0, 1, 0}, {1, 0, 0}};
  c.colors = {{0, 0, 0}, {100, 200, 50}, {1, 2, 3}};
  c.labels = {4, 4, 9};
  c.fields.push_back({"intensity", {1.0f, 3.0f, 5.0f}});
  const PointCloud out = voxel_downsample(c, {.res_voxel = 0.1, .n_min = 1});
  ASSERT_EQ(out.size(), 2u);
  EXPECT_NEAR(out.points[0].x(), 0.015f, 1e-6f);
  EXPECT_NEAR(out.normals[0].norm(), 1.0f, 1e-6f);
  EXPECT_EQ(out.colors[0], (Rgb{50, 100, 25}));
  EXPECT_EQ(out.labels[0], 4);
  EXPECT_FLOAT_EQ(out.fields[0].values[0], 2.0f);
  EXPECT_FLOAT_EQ(out.fields[0].values[1], 5.0f);
}

TEST(VoxelGrid, RejectsBadLeafAndHugeExtents) {
  PointCloud c;
  c.points = {{0, 0, 0}, {1e5f, 0, 0}};
  EXPECT_THROW((void)voxel_downsample(c, {.res_voxel = 0.0}), ConfigError);
  EXPECT_THROW((void)voxel_downsample(c, {.res_voxel = 0.01}), ConfigError);
  EXPECT_TRUE(voxel_downsample(PointCloud{}, {}).empty());
}
