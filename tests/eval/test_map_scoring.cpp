// The mapper scored against the truth (cairn/eval/map_scoring.hpp): the trajectory error on a
// known answer. The map's offset at the objects is exercised by the registration protocol's
// tests (Cli.ProtocolRegistersWhileMapping, GlobalRegistration end to end).
#include <gtest/gtest.h>

#include <cmath>

#include "cairn/core/units.hpp"
#include "cairn/eval/map_scoring.hpp"

namespace cairn::eval {
namespace {

// trajectory_error, which the mapping acceptance tests count with, on a known answer: a truth
// driving along x while turning about z, an estimate between its poses (interpolated truth)
// offset by a constant (0.1, -0.2, 0.05) m plus +-3 cm in z alternating, and turned 1 deg
// further about z: ATE from the offsets, the mean the constant, the RMSE without it the 3 cm.
TEST(TrajectoryError, KnownOffsetAndRotation) {
  std::vector<StampedPose> truth, estimate;
  const auto pose_at = [](double t, double extra_yaw, const Vec3d& offset) {
    StampedPose p{.time = t, .pose = Eigen::Isometry3d::Identity()};
    p.pose.linear() = Eigen::AngleAxisd(0.1 * t + extra_yaw, Vec3d::UnitZ()).toRotationMatrix();
    p.pose.translation() = Vec3d(t, 0.5 * t, 0.0) + offset;
    return p;
  };
  for (int k = 0; k <= 10; ++k) truth.push_back(pose_at(double(k), 0.0, Vec3d::Zero()));
  const Vec3d constant(0.1, -0.2, 0.05);
  for (int k = 0; k < 10; ++k)
    estimate.push_back(pose_at(k + 0.5, 1.0 * kDeg, constant + Vec3d(0, 0, k % 2 ? -0.03 : 0.03)));
  const TrajectoryError e = trajectory_error(estimate, truth);
  EXPECT_EQ(e.num, 10u);
  const double high = (constant + Vec3d(0, 0, 0.03)).norm(), low = (constant - Vec3d(0, 0, 0.03)).norm();
  EXPECT_NEAR(e.ate_rmse, std::sqrt(0.5 * (high * high + low * low)), 1e-9);
  EXPECT_NEAR(e.ate_max, high, 1e-9);
  EXPECT_NEAR((e.mean_error - constant).norm(), 0.0, 1e-9);
  EXPECT_NEAR(e.ate_rmse_without_mean, 0.03, 1e-9);
  EXPECT_NEAR(e.rotation_rmse_deg, 1.0, 1e-6);
  const std::vector<PoseError> each = pose_errors(estimate, truth);
  ASSERT_EQ(each.size(), 10u);
  EXPECT_NEAR(each[1].position_error_m, low, 1e-9);
  EXPECT_NEAR(each[1].rotation_error_deg, 1.0, 1e-6);
  EXPECT_EQ(trajectory_error({}, truth).num, 0u);
  EXPECT_TRUE(pose_errors(estimate, {}).empty());
}

}  // namespace
}  // namespace cairn::eval
