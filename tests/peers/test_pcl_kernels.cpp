// Cross-checks of cairn's kernels against PCL on identical inputs (PCL is linked by tests only).
#include <gtest/gtest.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/features/normal_3d_omp.h>
#include <pcl/point_types.h>
#include <pcl/sample_consensus/method_types.h>
#include <pcl/sample_consensus/model_types.h>
#include <pcl/search/kdtree.h>
#include <pcl/segmentation/extract_clusters.h>
#include <pcl/segmentation/sac_segmentation.h>

#include <algorithm>
#include <map>
#include <random>
#include <set>

#include "cairn/core/io/io.hpp"
#include "cairn/core/normals.hpp"
#include "cairn/core/plane.hpp"
#include "cairn/core/voxel_grid.hpp"
#include "cairn/segmentation/clustering.hpp"
#include "support/pcl_convert.hpp"
#include "support/test_data.hpp"

using namespace cairn;

namespace {

using test::to_pcl;

/// Real LiDAR scan (KITTI, 64 beams) cropped to a 40 m box around the sensor.
std::vector<Vec3f> kitti_crop() {
  const PointCloud c = io::load_cloud(test::real_data("patchworkpp-kitti-scans/000000.bin"));
  std::vector<Vec3f> out;
  for (const auto& p : c.points)
    if (std::abs(p.x()) < 20 && std::abs(p.y()) < 20) out.push_back(p);
  return out;
}

}  // namespace

TEST(PeerPcl, VoxelGridCountsAndCentroidsOnRealScan) {
  CAIRN_REQUIRE_REAL_DATA("patchworkpp-kitti-scans/000000.bin");
  PointCloud ours;
  ours.points = kitti_crop();
  for (const double leaf : {0.03, 0.1, 0.5}) {
    for (const int n_min : {1, 3}) {
      const PointCloud out = voxel_downsample(ours, {.res_voxel = leaf, .n_min = n_min});
      pcl::VoxelGrid<pcl::PointXYZ> vg;
      vg.setInputCloud(to_pcl(ours.points));
      vg.setLeafSize(float(leaf), float(leaf), float(leaf));
      vg.setMinimumPointsNumberPerVoxel(unsigned(n_min));
      pcl::PointCloud<pcl::PointXYZ> ref;
      vg.filter(ref);
      ASSERT_EQ(out.size(), ref.size()) << "leaf " << leaf << " n_min " << n_min;
      // Both are ordered by voxel index: compare point by point.
      double worst = 0;
      for (std::size_t i = 0; i < out.size(); ++i)
        worst = std::max(worst, double((out.points[i] - ref[i].getVector3fMap()).norm()));
      EXPECT_LT(worst, 1e-4) << "leaf " << leaf;
    }
  }
}

TEST(PeerPcl, NormalsAgreeInAngleOnRealScan) {
  CAIRN_REQUIRE_REAL_DATA("gicp-outdoor-lidar-pair/source.ply");
  const PointCloud c = io::load_cloud(test::real_data("gicp-outdoor-lidar-pair/source.ply"));
  const float radius = 0.5f;
  const KdTree tree(c.points);
  const NormalResult ours = estimate_normals(c.points, tree, {.radius = radius});
  auto cloud = to_pcl(c.points);
  pcl::NormalEstimationOMP<pcl::PointXYZ, pcl::Normal> ne(2);
  ne.setInputCloud(cloud);
  ne.setSearchMethod(pcl::make_shared<pcl::search::KdTree<pcl::PointXYZ>>());
  ne.setRadiusSearch(radius);
  ne.setViewPoint(0, 0, 0);
  pcl::PointCloud<pcl::Normal> ref;
  ne.compute(ref);
  std::size_t compared = 0, within = 0;
  double worst_curv = 0;
  for (std::size_t i = 0; i < c.size(); ++i) {
    const Vec3f r = ref[i].getNormalVector3fMap();
    if (!r.allFinite() || ours.normals[i].isZero()) continue;
    ++compared;
    const double angle = std::acos(std::clamp(double(ours.normals[i].dot(r)), -1.0, 1.0)) * 180.0 / M_PI;
    within += angle < 1.0;
    worst_curv = std::max(worst_curv, double(std::abs(ours.curvature[i] - ref[i].curvature)));
  }
  ASSERT_GT(compared, c.size() * 9 / 10);
  // Same neighbourhoods, same PCA: all but near-isotropic neighbourhoods agree within 1°.
  EXPECT_GT(double(within) / double(compared), 0.999);
  EXPECT_LT(worst_curv, 1e-3);
}

TEST(PeerPcl, RansacPlaneSameInliersNoiseFree) {
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<float> u(-5.0f, 5.0f);
  std::vector<Vec3f> pts;
  std::vector<std::uint32_t> plane_idx;
  for (int i = 0; i < 20000; ++i) {
    const float x = u(rng), y = u(rng);
    plane_idx.push_back(std::uint32_t(pts.size()));
    pts.emplace_back(x, y, 0.05f * x - 0.02f * y + 1.0f);
    if (i % 2 == 0) pts.emplace_back(u(rng), u(rng), 3.0f + std::abs(u(rng)));  // clutter, well above
  }
  std::mt19937_64 gen(42);
  const PlaneFit ours = fit_plane_ransac(pts, {}, {.distance = 0.02}, gen);
  pcl::SACSegmentation<pcl::PointXYZ> seg;
  seg.setModelType(pcl::SACMODEL_PLANE);
  seg.setMethodType(pcl::SAC_RANSAC);
  seg.setDistanceThreshold(0.02);
  seg.setOptimizeCoefficients(true);
  seg.setInputCloud(to_pcl(pts));
  pcl::PointIndices inl;
  pcl::ModelCoefficients coef;
  seg.segment(inl, coef);
  ASSERT_TRUE(ours.found);
  std::vector<std::uint32_t> ref(inl.indices.begin(), inl.indices.end());
  std::sort(ref.begin(), ref.end());
  EXPECT_EQ(ours.inliers, ref);
  EXPECT_EQ(ours.inliers, plane_idx);
  const Vec3f n(coef.values[0], coef.values[1], coef.values[2]);
  EXPECT_GT(std::abs(n.dot(ours.plane.normal)), 0.99999f);
}

TEST(PeerPcl, EuclideanClustersIdenticalPartitionOnRealScan) {
  CAIRN_REQUIRE_REAL_DATA("patchworkpp-kitti-scans/000000.bin");
  // Non-ground part of a real 64-beam scan (points above the road, z > -1.4 m at 1.73 m height).
  std::vector<Vec3f> pts;
  for (const auto& p : kitti_crop())
    if (p.z() > -1.4f) pts.push_back(p);
  ASSERT_GT(pts.size(), 10000u);
  for (const double tol : {0.3, 0.5}) {
    const ClusterConfig cfg{.tolerance = tol, .min_points = 20, .max_points = 0};
    const auto ours = euclidean_clusters(pts, {}, cfg);
    auto cloud = to_pcl(pts);
    auto tree = pcl::make_shared<pcl::search::KdTree<pcl::PointXYZ>>();
    pcl::EuclideanClusterExtraction<pcl::PointXYZ> ec;
    ec.setClusterTolerance(tol);
    ec.setMinClusterSize(20);
    ec.setMaxClusterSize(std::numeric_limits<int>::max());
    ec.setSearchMethod(tree);
    ec.setInputCloud(cloud);
    std::vector<pcl::PointIndices> ref;
    ec.extract(ref);
    std::set<std::vector<std::uint32_t>> a(ours.begin(), ours.end()), b;
    for (const auto& r : ref) {
      std::vector<std::uint32_t> v(r.indices.begin(), r.indices.end());
      std::sort(v.begin(), v.end());
      b.insert(v);
    }
    EXPECT_GT(a.size(), 5u);
    EXPECT_EQ(a, b) << "tolerance " << tol << ": " << a.size() << " vs " << b.size() << " clusters";
  }
}
