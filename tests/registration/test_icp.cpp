// ICP against known transforms on synthetic sites (independently sampled source and target).
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <random>

#include "cairn/core/error.hpp"
#include "cairn/registration/icp.hpp"
#include "support/registration_scenes.hpp"
#include "support/sanitizers.hpp"
#include "cairn/core/units.hpp"

using namespace cairn;
using test::make_pose;
using test::pose_error;

namespace {

using cairn::kDeg;

/// Target: dense map of the site; source: an independent LiDAR-like sample seen from the origin,
/// expressed in the source frame (T_target_source = T_gt).
struct Pair {
  std::vector<Vec3f> source;
  std::vector<Vec3f> target;
  Eigen::Isometry3d T_gt;
};

const Pair& site_pair() {
  static const Pair p = [] {
    Pair q;
    q.T_gt = make_pose(2 * kDeg, -1.5 * kDeg, 12 * kDeg, {0.8, -0.5, 0.1});
    q.target = test::sample_site(100000, 1, 0.005f);
    q.source = test::transformed(test::sample_site(15000, 2, 0.005f, true), q.T_gt.inverse());
    return q;
  }();
  return p;
}

const IcpTarget& site_target() {
  static const IcpTarget t(site_pair().target, NormalConfig{.k = 10});
  return t;
}

/// Perturbations of the ground truth: up to 0.3 m and 5 degrees.
std::vector<Eigen::Isometry3d> perturbed_starts(const Eigen::Isometry3d& T_gt, int n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Eigen::Isometry3d> out;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d axis = Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized();
    Eigen::Isometry3d d = Eigen::Isometry3d::Identity();
    d.linear() = Eigen::AngleAxisd(5 * kDeg * std::abs(u(rng)), axis).toRotationMatrix();
    d.translation() = 0.3 * Eigen::Vector3d(u(rng), u(rng), u(rng)) / std::sqrt(3.0);
    out.push_back(d * T_gt);
  }
  return out;
}

}  // namespace

TEST(Icp, RecoversKnownTransformFromPerturbedStarts) {
  const Pair& p = site_pair();
  for (const char* objective : {"point_to_plane", "point_to_point"}) {
    const IcpConfig cfg{.objective = objective, .max_correspondence_distance = 1.0, .max_iterations = 100};
    // Point-to-point converges slowly (and is biased by the sampling) on independent samples.
    const bool p2l = std::string(objective) == "point_to_plane";
    // Under the sanitizers one start runs the path; the five starts are a figure (Release).
    for (const auto& T0 : perturbed_starts(p.T_gt, test::kSanitized ? 1 : 5, 11)) {
      const IcpResult r = register_icp(p.source, site_target(), T0, cfg);
      const auto e = pose_error(r.T_target_source, p.T_gt);
      if (p2l) {
        EXPECT_TRUE(r.converged) << to_string(r.status);
      }
      EXPECT_LT(e.translation, p2l ? 0.01 : 0.02) << objective;
      EXPECT_LT(e.rotation, (p2l ? 0.1 : 0.2) * kDeg) << objective;
      EXPECT_GT(r.fitness, 0.95) << objective;
      EXPECT_LT(r.rmse, 0.08) << objective;  // nearest-neighbour distance between independent samples
    }
  }
}

TEST(Icp, RecoversInverseTransform) {
  // Roles swapped: the dense map is registered to the scan; the answer is T_gt⁻¹.
  const Pair& p = site_pair();
  const IcpTarget scan(p.source, NormalConfig{.k = 10});
  const std::vector<Vec3f> map_sample(p.target.begin(), p.target.begin() + 30000);
  const Eigen::Isometry3d T_inv = p.T_gt.inverse();
  // The map extends beyond the scan: only map points near the scan pair up (fitness < 1).
  const IcpConfig cfg{.max_correspondence_distance = 0.5, .max_iterations = 100};
  for (const auto& T0 : perturbed_starts(T_inv, 4, 12)) {
    const IcpResult r = register_icp(map_sample, scan, T0, cfg);
    const auto e = pose_error(r.T_target_source, T_inv);
    EXPECT_TRUE(r.converged) << to_string(r.status);
    EXPECT_LT(e.translation, 0.01);
    EXPECT_LT(e.rotation, 0.1 * kDeg);
  }
}

TEST(Icp, PointToPlaneNeedsFewerIterationsOnPlanes) {
  const auto target_pts = test::sample_planes(40000, 3);
  const Eigen::Isometry3d T_gt = make_pose(1 * kDeg, 2 * kDeg, -4 * kDeg, {0.15, 0.1, -0.05});
  const auto source = test::transformed(test::sample_planes(8000, 4), T_gt.inverse());
  const IcpTarget target(target_pts, NormalConfig{.k = 10});
  const IcpConfig base{.max_correspondence_distance = 0.5, .max_iterations = 200, .translation_tolerance = 1e-5,
                       .rotation_tolerance = 1e-5};
  IcpConfig p2p = base, p2l = base;
  p2p.objective = "point_to_point";
  const IcpResult a = register_icp(source, target, Eigen::Isometry3d::Identity(), p2l);
  const IcpResult b = register_icp(source, target, Eigen::Isometry3d::Identity(), p2p);
  EXPECT_TRUE(a.converged);
  EXPECT_LT(pose_error(a.T_target_source, T_gt).translation, 0.005);
  EXPECT_LT(a.iterations * 2, b.iterations) << "point-to-plane " << a.iterations << ", point-to-point "
                                            << b.iterations;
}

TEST(Icp, RobustKernelsSurviveThirtyPercentOutliers) {
  const Pair& p = site_pair();
  // 30 % of the source replaced by outliers within the correspondence distance, all biased
  // upwards (dust, vegetation, a moving arm): they pull a plain least-squares fit off.
  std::vector<Vec3f> src = p.source;
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  const Eigen::Vector3f up = (p.T_gt.inverse().linear() * Eigen::Vector3d::UnitZ()).cast<float>();
  for (std::size_t i = 0; i < src.size(); ++i)
    if (u(rng) < 0.3f) src[i] += up * (0.1f + 0.3f * u(rng)) + 0.1f * Vec3f(u(rng), u(rng), u(rng));
  const Eigen::Isometry3d T0 = perturbed_starts(p.T_gt, 1, 21)[0];
  IcpConfig cfg{.kernel_scale = 0.03, .max_correspondence_distance = 0.5, .max_iterations = 100};
  const IcpResult plain = register_icp(src, site_target(), T0, cfg);
  const double plain_err = pose_error(plain.T_target_source, p.T_gt).translation;
  for (const char* kernel : {"huber", "cauchy", "tukey", "geman_mcclure"}) {
    cfg.kernel = kernel;
    const IcpResult r = register_icp(src, site_target(), T0, cfg);
    const auto e = pose_error(r.T_target_source, p.T_gt);
    EXPECT_LT(e.translation, 0.015) << kernel;
    EXPECT_LT(e.rotation, 0.15 * kDeg) << kernel;
    EXPECT_LT(e.translation, plain_err) << kernel;
  }
  EXPECT_GT(plain_err, 0.02) << "the outliers should bias the unweighted fit";
}

TEST(Icp, FourDofKeepsRollAndPitch) {
  const Pair& p = site_pair();
  // Initial guess with the right roll/pitch: 4-DoF recovers yaw + translation.
  Eigen::Isometry3d T0 = p.T_gt;
  T0.prerotate(Eigen::AngleAxisd(4 * kDeg, Eigen::Vector3d::UnitZ()));
  T0.pretranslate(Eigen::Vector3d(0.2, -0.15, 0.05));
  const IcpConfig cfg{.max_correspondence_distance = 1.0, .max_iterations = 100, .four_dof = true};
  const IcpResult r = register_icp(p.source, site_target(), T0, cfg);
  EXPECT_TRUE(r.converged);
  EXPECT_LT(pose_error(r.T_target_source, p.T_gt).translation, 0.01);
  EXPECT_LT(pose_error(r.T_target_source, p.T_gt).rotation, 0.1 * kDeg);
  // Wrong roll/pitch in the guess: they are kept (third row of R unchanged by a yaw about z).
  Eigen::Isometry3d T1 = T0;
  T1.prerotate(Eigen::AngleAxisd(1.5 * kDeg, Eigen::Vector3d::UnitX()));
  const IcpResult r1 = register_icp(p.source, site_target(), T1, cfg);
  EXPECT_LT((r1.T_target_source.linear().row(2) - T1.linear().row(2)).norm(), 1e-12);
  EXPECT_EQ(r.hessian.rows(), 6);
}

TEST(Icp, DeterministicAndSerialEqualsParallel) {
  const Pair& p = site_pair();
  const Eigen::Isometry3d T0 = perturbed_starts(p.T_gt, 1, 31)[0];
  IcpConfig cfg{.kernel = "cauchy", .max_correspondence_distance = 1.0};
  const IcpResult a = register_icp(p.source, site_target(), T0, cfg);
  const IcpResult b = register_icp(p.source, site_target(), T0, cfg);
  cfg.parallel = false;
  const IcpResult c = register_icp(p.source, site_target(), T0, cfg);
  for (const IcpResult* x : {&b, &c}) {
    EXPECT_EQ(x->T_target_source.matrix(), a.T_target_source.matrix());  // bit-identical
    EXPECT_EQ(x->iterations, a.iterations);
    EXPECT_EQ(x->num_inliers, a.num_inliers);
    EXPECT_EQ(x->rmse, a.rmse);
    EXPECT_EQ(x->hessian, a.hessian);
  }
}

TEST(Icp, HessianIsSymmetricAndSeesPlaneDegeneracy) {
  // A single plane constrains z, roll and pitch only: three near-zero Hessian eigenvalues.
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<float> u(-5.0f, 5.0f);
  std::vector<Vec3f> plane;
  for (int i = 0; i < 20000; ++i) plane.emplace_back(u(rng), u(rng), 0.0f);
  const IcpTarget target(plane, std::vector<Vec3f>(plane.size(), Vec3f::UnitZ()));
  std::vector<Vec3f> src(plane.begin(), plane.begin() + 2000);
  for (auto& q : src) q.z() += 0.05f;
  const IcpResult r = register_icp(src, target, Eigen::Isometry3d::Identity(), {});
  EXPECT_TRUE(r.converged);
  EXPECT_NEAR(r.T_target_source.translation().z(), -0.05, 1e-6);
  EXPECT_NEAR(r.T_target_source.translation().head<2>().norm(), 0.0, 1e-9);  // no drift along the plane
  EXPECT_LT((r.hessian - r.hessian.transpose()).norm(), 1e-9 * r.hessian.norm());
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>> es(r.hessian);
  EXPECT_LT(es.eigenvalues()(2), 1e-9 * es.eigenvalues()(5));
  EXPECT_GT(es.eigenvalues()(3), 1e-3 * es.eigenvalues()(5));
}

TEST(Icp, ManySourcesAgainstOnePreparedTarget) {
  // The mapping use case: one submap, several scans (registered concurrently is safe: const).
  const Pair& p = site_pair();
  for (std::uint64_t seed = 40; seed < 43; ++seed) {
    const auto src = test::transformed(test::sample_site(5000, seed, 0.005f, true), p.T_gt.inverse());
    const IcpResult r = register_icp(src, site_target(), perturbed_starts(p.T_gt, 1, seed)[0],
                                     {.max_correspondence_distance = 1.0});
    EXPECT_LT(pose_error(r.T_target_source, p.T_gt).translation, 0.015) << seed;
  }
}

TEST(Icp, CloudInterfaceKeepsGeoreferencedPrecision) {
  const Pair& p = site_pair();
  const Vec3d o_t(2.6e6, 1.2e6, 400.0), o_s(2.6e6 + 3.0, 1.2e6 - 2.0, 401.0);
  PointCloud tgt, src;
  tgt.points = p.target;
  tgt.origin = o_t;
  src.points = p.source;
  src.origin = o_s;
  // World-frame ground truth: x_t,world = o_t + T_gt (x_s,world − o_s).
  const Eigen::Isometry3d T_world = Eigen::Translation3d(o_t) * p.T_gt * Eigen::Translation3d(-o_s);
  const IcpTarget target = IcpTarget::from_cloud(tgt);
  EXPECT_EQ(target.origin(), o_t);
  const Eigen::Isometry3d T0 = T_world * Eigen::Translation3d(0.1, 0.1, 0.0);
  const IcpResult r = register_icp(src, target, T0, {.max_correspondence_distance = 1.0});
  EXPECT_TRUE(r.converged);
  // Compare where the cloud lands (the world translation itself is dominated by R·o_s).
  const Eigen::Isometry3d T_local = Eigen::Translation3d(-o_t) * r.T_target_source * Eigen::Translation3d(o_s);
  EXPECT_LT(pose_error(T_local, p.T_gt).translation, 0.01);
  EXPECT_LT(pose_error(T_local, p.T_gt).rotation, 0.1 * kDeg);
  // Same answer as the span interface on the local coordinates.
  const IcpResult r_local = register_icp(p.source, target, Eigen::Translation3d(-o_t) * T0 * Eigen::Translation3d(o_s),
                                         {.max_correspondence_distance = 1.0});
  EXPECT_LT((r_local.T_target_source.matrix() - T_local.matrix()).norm(), 1e-6);
}

TEST(Icp, ReportsFailureAndRejectsBadInput) {
  const Pair& p = site_pair();
  // Source 100 m away: nothing within the correspondence distance.
  const IcpResult far = register_icp(p.source, site_target(), make_pose(0, 0, 0, {100, 0, 0}), {});
  EXPECT_FALSE(far.converged);
  EXPECT_EQ(far.status, IcpStatus::too_few_correspondences);
  EXPECT_EQ(far.num_inliers, 0u);

  const Eigen::Isometry3d I = Eigen::Isometry3d::Identity();
  EXPECT_THROW((void)register_icp(std::vector<Vec3f>{}, site_target(), I, {}), InputError);
  std::vector<Vec3f> bad = {{0, 0, 0}, {1, NAN, 0}};
  EXPECT_THROW((void)register_icp(bad, site_target(), I, {}), InputError);
  EXPECT_THROW((void)IcpTarget(std::vector<Vec3f>{}), InputError);
  EXPECT_THROW((void)IcpTarget(bad), InputError);
  EXPECT_THROW((void)IcpTarget({{0, 0, 0}}, std::vector<Vec3f>{}), InputError);
  const IcpTarget no_normals(p.target);
  EXPECT_THROW((void)register_icp(p.source, no_normals, I, {}), ConfigError);
  EXPECT_NO_THROW((void)register_icp(p.source, no_normals, p.T_gt, {.objective = "point_to_point"}));
  EXPECT_THROW((void)register_icp(p.source, site_target(), I, {.kernel = "welsch"}), ConfigError);
  EXPECT_THROW((void)register_icp(p.source, site_target(), I, {.objective = "plane"}), ConfigError);
  EXPECT_THROW((void)register_icp(p.source, site_target(), I, {.kernel_scale = 0}), ConfigError);
  EXPECT_THROW((void)register_icp(p.source, site_target(), I, {.max_correspondence_distance = -1}), ConfigError);
  EXPECT_THROW((void)register_icp(p.source, site_target(), I, {.max_iterations = 0}), ConfigError);
  Eigen::Isometry3d nan_T = I;
  nan_T.translation().x() = NAN;
  EXPECT_THROW((void)register_icp(p.source, site_target(), nan_T, {}), InputError);
}

TEST(Icp, EvaluateAlignmentAtGroundTruth) {
  const Pair& p = site_pair();
  const IcpResult at_gt = evaluate_alignment(p.source, site_target(), p.T_gt, 0.2);
  const IcpResult off = evaluate_alignment(p.source, site_target(), make_pose(0, 0, 0, {0.3, 0, 0}) * p.T_gt, 0.2);
  EXPECT_GT(at_gt.fitness, 0.98);
  EXPECT_LT(at_gt.rmse, off.rmse);
  EXPECT_EQ(at_gt.iterations, 0);
}
