// Cross-check of cairn's point-to-plane ICP against Open3D's RegistrationICP with
// TransformationEstimationPointToPlane on identical inputs (same pairs, initial guess,
// correspondence distance and target normals). Also compares inlier RMSE and fitness, which both
// libraries define the same way (nearest-neighbour distance over pairs within the distance).
#include <gtest/gtest.h>
#include <open3d/geometry/PointCloud.h>
#include <open3d/pipelines/registration/Registration.h>
#include <open3d/pipelines/registration/TransformationEstimation.h>

#include <fstream>

#include "cairn/core/io/io.hpp"
#include "cairn/core/voxel_grid.hpp"
#include "cairn/registration/icp.hpp"
#include "support/registration_scenes.hpp"
#include "support/test_data.hpp"
#include "cairn/core/units.hpp"

using namespace cairn;
namespace o3r = open3d::pipelines::registration;

namespace {

using cairn::kDeg;

open3d::geometry::PointCloud to_o3d(std::span<const Vec3f> pts, std::span<const Vec3f> normals = {}) {
  open3d::geometry::PointCloud c;
  for (const auto& p : pts) c.points_.push_back(p.cast<double>());
  for (const auto& n : normals) c.normals_.push_back(n.cast<double>());
  return c;
}

Eigen::Isometry3d read_matrix(const std::filesystem::path& path) {
  std::ifstream in(path);
  Eigen::Isometry3d T;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) in >> T.matrix()(r, c);
  return T;
}

void compare(std::span<const Vec3f> source, std::span<const Vec3f> target_pts, const Eigen::Isometry3d& T_init,
             const Eigen::Isometry3d& T_gt, double max_corr, double tol_t, double tol_r_deg, const char* what) {
  const IcpTarget target(std::vector<Vec3f>(target_pts.begin(), target_pts.end()), NormalConfig{.k = 20});
  const IcpResult ours = register_icp(source, target, T_init,
                                      {.max_correspondence_distance = max_corr, .max_iterations = 100,
                                       .translation_tolerance = 1e-6, .rotation_tolerance = 1e-6});
  const auto src = to_o3d(source), tgt = to_o3d(target.points(), target.normals());
  const o3r::RegistrationResult theirs =
      o3r::RegistrationICP(src, tgt, max_corr, T_init.matrix(), o3r::TransformationEstimationPointToPlane(),
                           o3r::ICPConvergenceCriteria(1e-10, 1e-10, 100));
  Eigen::Isometry3d T_o3d;
  T_o3d.matrix() = theirs.transformation_;
  const auto d = test::pose_error(ours.T_target_source, T_o3d);
  std::printf("%s: cairn vs Open3D %.2f mm %.4f deg (GT: cairn %.2f mm, Open3D %.2f mm); rmse %.5f / %.5f, "
              "fitness %.4f / %.4f\n",
              what, d.translation * 1e3, d.rotation / kDeg, test::pose_error(ours.T_target_source, T_gt).translation * 1e3,
              test::pose_error(T_o3d, T_gt).translation * 1e3, ours.rmse, theirs.inlier_rmse_, ours.fitness,
              theirs.fitness_);
  EXPECT_LT(d.translation, tol_t) << what;
  EXPECT_LT(d.rotation, tol_r_deg * kDeg) << what;
  EXPECT_NEAR(ours.fitness, theirs.fitness_, 0.01) << what;
  EXPECT_NEAR(ours.rmse, theirs.inlier_rmse_, 0.05 * theirs.inlier_rmse_ + 1e-6) << what;
}

}  // namespace

TEST(PeerOpen3dIcp, SyntheticSiteSameAnswer) {
  const Eigen::Isometry3d T_gt = test::make_pose(2 * kDeg, -1.5 * kDeg, 12 * kDeg, {0.8, -0.5, 0.1});
  const auto target = test::sample_site(100000, 1, 0.005f);
  const auto source = test::transformed(test::sample_site(15000, 2, 0.005f, true), T_gt.inverse());
  const Eigen::Isometry3d T_init = test::make_pose(0.5 * kDeg, 0.5 * kDeg, 3 * kDeg, {0.2, -0.1, 0.05}) * T_gt;
  compare(source, target, T_init, T_gt, 1.0, 0.0005, 0.005, "site");
}

TEST(PeerOpen3dIcp, OutdoorLidarPairSameAnswer) {
  CAIRN_REQUIRE_REAL_DATA("gicp-outdoor-lidar-pair/source.ply");
  const PointCloud s = io::load_cloud(test::real_data("gicp-outdoor-lidar-pair/source.ply"));
  const PointCloud t = io::load_cloud(test::real_data("gicp-outdoor-lidar-pair/target.ply"));
  const Eigen::Isometry3d T_gt = read_matrix(test::real_data("gicp-outdoor-lidar-pair/T_target_source.txt"));
  compare(voxel_downsample(s, {.res_voxel = 0.1}).points, voxel_downsample(t, {.res_voxel = 0.1}).points,
          Eigen::Isometry3d::Identity(), T_gt, 1.0, 0.0005, 0.005, "outdoor");
}

TEST(PeerOpen3dIcp, BunnySameAnswer) {
  CAIRN_REQUIRE_REAL_DATA("pcl-bunny/bun_zipper_res3.ply");
  const auto bunny = io::load_cloud(test::real_data("pcl-bunny/bun_zipper_res3.ply")).points;
  const Eigen::Isometry3d T_gt = test::make_pose(3 * kDeg, -4 * kDeg, 8 * kDeg, {0.01, -0.005, 0.008});
  compare(test::transformed(bunny, T_gt.inverse()), bunny, Eigen::Isometry3d::Identity(), T_gt, 0.05, 0.00005, 0.005,
          "bunny");
}
