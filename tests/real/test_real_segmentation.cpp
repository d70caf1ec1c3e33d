// Segmentation stages on real data nobody here made (../shared/data/real).
#include <gtest/gtest.h>

#include <cstdio>

#include "cairn/core/io/io.hpp"
#include "cairn/segmentation/segmenter.hpp"
#include "support/test_data.hpp"

using namespace cairn;

// Real airborne terrain (ISPRS): tests/peers/test_pcl_ground.cpp, beside PCL's filter.

// Real stereo capture of a layer of stones on a flat work surface (camera above, z towards it).
// The stones of the layer touch each other along their seams, so — as the paper notes of
// Euclidean clustering — they come out as one object; what must hold: the table is the ground,
// the stone layer is one non-planar object of the right size, nothing else is an object.
TEST(RealData, StoneLayerOnFlatSurface) {
  CAIRN_REQUIRE_REAL_DATA("epfl-stacking-zed-scans/tempcloud.ply");
  const PointCloud c = io::load_cloud(test::real_data("epfl-stacking-zed-scans/tempcloud.ply"));
  SegmentationConfig cfg;
  cfg.ground.method = "plane";  // a flat table: the paper's method applies directly
  cfg.ground.d_plane = 0.02;    // objects here are 10–20 cm: margins scaled to them
  cfg.clustering.tolerance = 0.01;
  cfg.clustering.min_points = 200;
  // The terrain check looks for steep sides, which a single top-down depth image never holds
  // (one point per pixel ray): it is meant for side views (LiDAR, LiDAR + drone), so off here.
  cfg.verticality.enabled = false;
  const SegmentationResult r = segment(c, cfg);
  EXPECT_GT(double(r.num_ground) / double(c.size()), 0.7);
  EXPECT_GT(std::abs(r.ground_plane.normal.z()), 0.95f);
  ASSERT_EQ(r.num_objects(), 1u);
  const Segment& s = r.segments[0];
  const Vec3f extent = s.box.max - s.box.min;
  std::printf("stone layer: %zu points, extent %.2f x %.2f x %.2f m\n", s.indices.size(), extent.x(), extent.y(),
              extent.z());
  EXPECT_GT(extent.x(), 0.2f);
  EXPECT_LT(extent.x(), 0.6f);
  EXPECT_GT(extent.y(), 0.4f);
  EXPECT_LT(extent.y(), 0.9f);
  EXPECT_GT(extent.z(), 0.08f);  // stands above the table
  EXPECT_LT(extent.z(), 0.3f);
}

// Real 64-beam LiDAR scans (KITTI): ground near the car is the road at sensor height -1.73 m.
TEST(RealData, KittiScanGroundAndClusters) {
  CAIRN_REQUIRE_REAL_DATA("patchworkpp-kitti-scans/000000.bin");
  for (const char* f : {"000000.bin", "000003.bin"}) {
    const PointCloud c = io::load_cloud(test::real_data(std::string("patchworkpp-kitti-scans/") + f));
    SegmentationConfig cfg;
    cfg.ground.cell_size = 1.0;
    cfg.ground.max_window = 8.0;  // cars and walls, not stones
    cfg.ground.d_plane = 0.2;
    cfg.clustering.tolerance = 0.5;
    cfg.clustering.min_points = 30;
    cfg.split.enabled = false;  // cars and walls, not piles of stones: clusters stay whole
    const SegmentationResult r = segment(c, cfg);
    std::size_t near = 0, near_ground = 0;
    for (std::size_t i = 0; i < c.size(); ++i) {
      const Vec3f& p = c.points[i];
      if (p.head<2>().norm() > 4 && p.head<2>().norm() < 10 && std::abs(p.z() + 1.73f) < 0.15f) {
        ++near;
        near_ground += r.labels[i] == kLabelGround;
      }
    }
    EXPECT_GT(double(near_ground) / double(near), 0.95) << f;  // road around the car is ground
    EXPECT_GT(r.num_objects(), 10u) << f;                      // cars, poles, walls...
    std::printf("KITTI %s: %zu points, %zu ground, %zu objects\n", f, c.size(), r.num_ground, r.num_objects());
  }
}
