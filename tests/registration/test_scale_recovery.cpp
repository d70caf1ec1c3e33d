// Scale recovery of the drone SfM model from camera positions (Sec. 4.1).
#include <gtest/gtest.h>

#include <random>

#include "cairn/core/error.hpp"
#include "cairn/registration/scale_recovery.hpp"

namespace cairn {
namespace {

// A lawnmower flight: 3 lines of 15 cameras, 12 m up, in the metric frame.
std::vector<Vec3d> flight() {
  std::vector<Vec3d> c;
  for (int line = 0; line < 3; ++line)
    for (int i = 0; i < 15; ++i) c.emplace_back(-7.0 + i, -4.0 + 4.0 * line, 12.0 + 0.1 * (i % 3));
  return c;
}

Similarity some_similarity() {
  Similarity S;
  S.scale = 0.3217;
  S.rotation = Eigen::AngleAxisd(2.1, Vec3d(0.3, -0.5, 0.8).normalized()).toRotationMatrix();
  S.translation = Vec3d(4.0, -17.0, 33.0);
  return S;
}

TEST(ScaleRecovery, RecoversAKnownSimilarityUnderNoiseAndOutliers) {
  const std::vector<Vec3d> metric = flight();
  const Similarity T_sfm_metric = some_similarity();
  std::mt19937_64 rng(3);
  std::normal_distribution<double> noise(0.0, 0.03);  // [m] VINS noise
  std::vector<Vec3d> sfm, noisy_metric = metric;
  for (auto& p : noisy_metric) p += Vec3d(noise(rng), noise(rng), noise(rng));
  for (const auto& p : metric) sfm.push_back(T_sfm_metric * p);
  noisy_metric[5] += Vec3d(3.0, 0.0, 0.0);  // two bad VINS positions
  noisy_metric[30] += Vec3d(0.0, -2.0, 1.0);
  const ScaleRecoveryResult r = recover_scale(sfm, noisy_metric);
  const Similarity truth = T_sfm_metric.inverse();
  EXPECT_NEAR(r.T_metric_sfm.scale / truth.scale, 1.0, 2e-3);
  EXPECT_LT(rotation_angle(r.T_metric_sfm.rotation.transpose() * truth.rotation), 0.2 * 3.14159 / 180.0);
  EXPECT_LT((r.T_metric_sfm * sfm[20] - metric[20]).norm(), 0.03);
  EXPECT_EQ(r.cameras, 45u);
  EXPECT_EQ(r.inliers.size(), 43u);  // the two bad ones are out
  EXPECT_GT(r.residuals[5], 2.5);
  EXPECT_LT(r.rms, 0.06);
}

TEST(ScaleRecovery, RefusesTooFewDegenerateOrMismatchedCameras) {
  const std::vector<Vec3d> metric = flight();
  const Similarity S = some_similarity();
  std::vector<Vec3d> sfm;
  for (const auto& p : metric) sfm.push_back(S * p);
  // Too few.
  EXPECT_THROW((void)recover_scale(std::span(sfm).first(4), std::span(metric).first(4)), InputError);
  // Different counts.
  EXPECT_THROW((void)recover_scale(std::span(sfm).first(10), std::span(metric).first(11)), InputError);
  // One straight flight line: the rotation about it is undetermined.
  std::vector<Vec3d> line_m, line_s;
  for (int i = 0; i < 12; ++i) {
    line_m.emplace_back(i, 0.0, 12.0);
    line_s.push_back(S * line_m.back());
  }
  try {
    (void)recover_scale(line_s, line_m);
    FAIL() << "a straight flight line was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("line"), std::string::npos) << e.what();
  }
  // Non-finite.
  sfm[3].x() = std::nan("");
  EXPECT_THROW((void)recover_scale(sfm, metric), InputError);
  // Mostly garbage: too few inliers.
  std::vector<Vec3d> garbage = metric;
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> u(-20.0, 20.0);
  for (std::size_t i = 0; i < garbage.size(); i += 1)
    if (i % 3 != 0) garbage[i] = Vec3d(u(rng), u(rng), u(rng));
  std::vector<Vec3d> good;
  for (const auto& p : metric) good.push_back(S * p);
  EXPECT_THROW((void)recover_scale(good, garbage), InputError);
  // Bad config.
  EXPECT_THROW((void)recover_scale(good, metric, {.min_cameras = 2}), ConfigError);
}

TEST(ScaleRecovery, ColmapModelImagesAreAssociatedByNameWithTheTrajectoryByTime) {
  const std::vector<Vec3d> metric = flight();
  const Similarity S = some_similarity();
  io::ColmapModel model;
  std::vector<io::TrajectoryPose> traj;
  for (std::size_t i = 0; i < metric.size(); ++i) {
    io::ColmapImage im;
    im.id = std::uint32_t(100 - i);  // ids in reverse: the association must not use them
    char name[32];
    std::snprintf(name, sizeof name, "frame_%04zu.png", i);
    im.name = name;
    // World (SfM) to camera: identity rotation, t = -C.
    im.t_cam_world = -(S * metric[i]);
    model.images.push_back(im);
    traj.push_back({.timestamp = 0.5 * double(i), .position = metric[i]});
  }
  std::reverse(model.images.begin(), model.images.end());
  std::reverse(traj.begin(), traj.end());  // read order does not matter either
  const ScaleRecoveryResult r = recover_scale(model, traj);
  EXPECT_NEAR(r.T_metric_sfm.scale * S.scale, 1.0, 1e-9);
  EXPECT_LT(r.rms, 1e-9);
  traj.pop_back();
  EXPECT_THROW((void)recover_scale(model, traj), InputError);
}

}  // namespace
}  // namespace cairn
