// Segment-based global registration (Sec. 4.4) end to end on the simulator: the exp1 site is
// simulated once per ctest run (8 s of cabin swinging + the drone survey; support/shared_runs.hpp),
// mapped by the mapping stage, and the
// drone cloud registered into that map under different source frames. Ground truth: the
// simulator's T_map_drone.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>

#include "cairn/core/error.hpp"
#include "cairn/core/io/io.hpp"
#include "cairn/core/io/run_dir.hpp"
#include "cairn/eval/map_scoring.hpp"
#include "cairn/mapping/mapper.hpp"
#include "cairn/registration/drone_registration.hpp"
#include "cairn/registration/global_registration.hpp"
#include "cairn/registration/scale_recovery.hpp"
#include "cairn/segmentation/evaluation.hpp"
#include "cairn/sim/simulation.hpp"
#include "support/shared_runs.hpp"
#include "support/test_data.hpp"

namespace cairn {
namespace {

namespace fs = std::filesystem;
constexpr double kPi = 3.14159265358979323846;

// Success must be right: figures measured on this fixture (seed 1: 0.47°, 3.4 cm against the
// truth, which includes the map's own georeferencing error of ~2 cm) plus a margin.
constexpr double kMaxRotationErrorDeg = 1.0;
constexpr double kMaxTranslationError = 0.06;  // [m]

struct Fixture {
  fs::path run_dir;
  PointCloud map;
  PointCloud drone_sfm;      // as the drone delivers it (SfM frame, arbitrary scale)
  Similarity T_map_sfm;      // truth
  io::ColmapModel sfm_model;
  std::vector<io::TrajectoryPose> vins;
};

const Fixture& fixture() {
  static const Fixture f = [] {
    Fixture x;
    const fs::path shared = test::shared_run(test::kExp1Drone8s);
    x.run_dir = shared / "run";
    x.map = io::load_cloud(shared / "map.ply");
    x.drone_sfm = io::load_cloud(x.run_dir / "drone" / "cloud.ply");
    std::ifstream in(x.run_dir / "truth" / "drone.json");
    x.T_map_sfm = Similarity::from_matrix(matrix_from_json(nlohmann::json::parse(in)["T_map_drone"]));
    x.sfm_model = io::read_colmap_text(x.run_dir / "drone" / "sparse");
    x.vins = io::read_tum_trajectory(x.run_dir / "drone" / "vins_trajectory.tum");
    return x;
  }();
  return f;
}

std::string describe(const GlobalRegistrationResult& r) {
  std::string s = r.reason + " | segments " + std::to_string(r.source_segments) + " / " +
                  std::to_string(r.target_segments) + " | candidates " + std::to_string(r.candidates) + " + " +
                  std::to_string(r.centroid_candidates) + " from centroids; refined:";
  for (const CandidateReport& c : r.reports)
    if (c.refined)
      s += " [" + c.origin + " inliers " + std::to_string(c.centroid_inliers) + " rmse " + std::to_string(c.rmse) +
           " overlap " + std::to_string(c.overlap) + "]";
  return s;
}

/// Error of an estimated T_map_source against the truth at the site centre (the stones' area).
RegistrationError errors(const Eigen::Isometry3d& est, const Similarity& truth_map_source, const Vec3d& site_point_map) {
  return registration_error(Similarity::from_isometry(est), truth_map_source, site_point_map);
}

const Vec3d kSiteCentre(0.0, 0.0, 0.0);  // exp1 stones lie around the origin, in front of the machine

PointCloud metric_drone(const Fixture& f, const Similarity& T_source_map) {
  PointCloud c = f.drone_sfm;
  transform_cloud(c, T_source_map * f.T_map_sfm);
  return c;
}

TEST(GlobalRegistration, DroneCloudAfterScaleRecoveryLandsOnTheLidarMap) {
  const Fixture& f = fixture();
  const ScaleRecoveryResult s = recover_scale(f.sfm_model, f.vins);
  const Similarity T_map_vins_true = f.T_map_sfm * s.T_metric_sfm.inverse();
  EXPECT_NEAR(T_map_vins_true.scale, 1.0, 2e-3);  // scale recovered to 0.2 %
  PointCloud source = f.drone_sfm;
  transform_cloud(source, s.T_metric_sfm);
  const GlobalRegistrationResult r = register_global(source, f.map, {}, {});
  ASSERT_TRUE(r.success) << describe(r);
  const RegistrationError e = errors(r.T_target_source, T_map_vins_true, kSiteCentre);
  EXPECT_LT(e.rotation_deg, kMaxRotationErrorDeg);
  EXPECT_LT(e.translation_m, kMaxTranslationError);
  EXPECT_LT(r.rmse, 0.03);
  EXPECT_GE(r.matched_segments.size(), 5u);
  EXPECT_EQ(r.merged_segments.size(), r.matched_segments.size());
  EXPECT_GT(r.merged_map.size(), f.map.size());
  // The registered scene's objects (merged pairs + segments only one cloud holds): every stone is
  // exactly one object holding >= 95 % of its points (the paper's protocol criterion).
  PointCloud objects;
  std::vector<std::int32_t> object_of;
  objects.origin = f.map.origin;
  for (std::size_t k = 0; k < r.objects.size(); ++k)
    for (std::size_t i = 0; i < r.objects[k].cloud.size(); ++i) {
      objects.points.push_back((r.objects[k].cloud.world(i) - objects.origin).cast<float>());
      object_of.push_back(std::int32_t(k));
    }
  const PointCloud snapshot = io::load_cloud(f.run_dir / "truth" / "map_snapshot.ply");
  const SegmentationScore score = score_segmentation(object_of, transfer_labels(snapshot, objects, 0.06), 7);
  EXPECT_EQ(score.found(0.95), 7u) << score.to_json().dump();
  EXPECT_EQ(score.terrain_segments, 0u);
  for (const char* stage : {"segmentation_source", "segmentation_target", "keypoints", "descriptors", "matching",
                            "verification", "refinement"})
    EXPECT_GT(r.timings.get(stage), 0.0) << stage;
  std::printf("[registration] scale recovery: scale error %.4f %%; registration: %.3f deg, %.1f mm, rmse %.1f mm, "
              "%zu matched segments, %.0f ms\n",
              100 * (T_map_vins_true.scale - 1.0), e.rotation_deg, 1000 * e.translation_m, 1000 * r.rmse,
              r.matched_segments.size(), r.timings.total());
}

TEST(GlobalRegistration, ArbitraryRotationsAnd180DegreeYawAreRecovered) {
  const Fixture& f = fixture();
  std::mt19937_64 rng(11);
  std::normal_distribution<double> n(0.0, 1.0);
  std::vector<Similarity> frames;
  Similarity yaw180;
  yaw180.rotation = Eigen::AngleAxisd(kPi, Vec3d::UnitZ()).toRotationMatrix();
  yaw180.translation = Vec3d(30.0, -12.0, 4.0);
  frames.push_back(yaw180);
  for (int k = 0; k < 3; ++k) {  // arbitrary 3-D rotations (the drone cloud upside down, on its side, ...)
    Similarity S;
    S.rotation = Eigen::Quaterniond(n(rng), n(rng), n(rng), n(rng)).normalized().toRotationMatrix();
    S.translation = Vec3d(20 * n(rng), 20 * n(rng), 20 * n(rng));
    frames.push_back(S);
  }
  int k = 0;
  for (const Similarity& T_source_map : frames) {
    const GlobalRegistrationResult r = register_global(metric_drone(f, T_source_map), f.map, {}, {});
    ASSERT_TRUE(r.success) << "frame " << k << ": " << describe(r);
    const RegistrationError e = errors(r.T_target_source, T_source_map.inverse(), kSiteCentre);
    EXPECT_LT(e.rotation_deg, kMaxRotationErrorDeg) << "frame " << k;
    EXPECT_LT(e.translation_m, kMaxTranslationError) << "frame " << k;
    ++k;
  }
}

TEST(GlobalRegistration, GravityAlignedModeEstimatesYawAndTranslation) {
  const Fixture& f = fixture();
  Similarity T_source_map;
  T_source_map.rotation = Eigen::AngleAxisd(2.3, Vec3d::UnitZ()).toRotationMatrix();
  T_source_map.translation = Vec3d(-5.0, 8.0, 1.0);
  GlobalRegistrationConfig cfg;
  cfg.gravity_aligned = true;
  const GlobalRegistrationResult r = register_global(metric_drone(f, T_source_map), f.map, {}, cfg);
  ASSERT_TRUE(r.success) << describe(r);
  const RegistrationError e = errors(r.T_target_source, T_source_map.inverse(), kSiteCentre);
  EXPECT_LT(e.rotation_deg, kMaxRotationErrorDeg);
  EXPECT_LT(e.translation_m, kMaxTranslationError);
}

// Partial overlap: the drone surveyed only part of the site, or the LiDAR has mapped only part
// of it. The site is cut between two stones (true centroids sorted along x) so that each side
// keeps four of the seven (the 8 s map holds six of them); each cut cloud registers against the
// other, whole one.
TEST(GlobalRegistration, PartialOverlapEitherWayRegisters) {
  const Fixture& f = fixture();
  const PointCloud snapshot = io::load_cloud(f.run_dir / "truth" / "map_snapshot.ply");
  const std::vector<std::int32_t>& stone_of = snapshot.labels;  // the simulator's object index per point
  ASSERT_EQ(stone_of.size(), snapshot.size());
  std::vector<Vec3d> sum(7, Vec3d::Zero());
  std::vector<int> count(7, 0);
  for (std::size_t i = 0; i < snapshot.size(); ++i)
    if (stone_of[i] >= 0 && stone_of[i] < 7) {
      sum[std::size_t(stone_of[i])] += snapshot.world(i);
      ++count[std::size_t(stone_of[i])];
    }
  std::vector<double> xs;
  for (std::size_t k = 0; k < 7; ++k)
    if (count[k] > 0) xs.push_back(sum[k].x() / count[k]);
  ASSERT_EQ(xs.size(), 7u);
  std::sort(xs.begin(), xs.end());
  const auto keep_x = [](const PointCloud& c, double lo, double hi) {
    PointCloud out;
    out.origin = c.origin;
    for (std::size_t i = 0; i < c.size(); ++i)
      if (c.world(i).x() >= lo && c.world(i).x() < hi) out.points.push_back(c.points[i]);
    return out;
  };
  const double inf = std::numeric_limits<double>::infinity();
  const PointCloud drone = metric_drone(f, {});  // in the map frame: the truth is the identity
  struct Case {
    const char* what;
    PointCloud source, target;
  };
  const Case cases[] = {
      {"drone cloud of the four stones with the smallest x", keep_x(drone, -inf, 0.5 * (xs[3] + xs[4])), f.map},
      {"map of the four stones with the largest x", drone, keep_x(f.map, 0.5 * (xs[2] + xs[3]), inf)},
  };
  for (const Case& c : cases) {
    const GlobalRegistrationResult r = register_global(c.source, c.target, {}, {});
    ASSERT_TRUE(r.success) << c.what << ": " << describe(r);
    const RegistrationError e = errors(r.T_target_source, Similarity{}, kSiteCentre);
    EXPECT_LT(e.rotation_deg, kMaxRotationErrorDeg) << c.what;
    EXPECT_LT(e.translation_m, kMaxTranslationError) << c.what;
    EXPECT_GE(r.matched_segments.size(), 3u) << c.what;
    EXPECT_LE(r.matched_segments.size(), 5u) << c.what;  // four stones (a fifth may be a cut piece)
    std::printf("[registration, partial] %s: %zu matched, %.3f deg, %.1f mm\n", c.what, r.matched_segments.size(),
                e.rotation_deg, 1000 * e.translation_m);
  }
}

TEST(GlobalRegistration, WrongScaleWrongSiteAndNoOverlapFailCleanly) {
  const Fixture& f = fixture();
  // 1. The SfM cloud without scale recovery (scale ~0.3 of metric): must not succeed.
  const GlobalRegistrationResult unscaled = register_global(f.drone_sfm, f.map, {}, {});
  EXPECT_FALSE(unscaled.success);
  // 2. A drone cloud of another site (seed 5) against this map.
  const fs::path other = test::temp_dir("registration_other") / "run";
  sim::SimulationConfig cfg = sim::scenario_config("exp1", sim::default_real_mesh_dir());
  cfg.with_scan_truth = false;
  cfg.with_snapshot = false;
  (void)sim::simulate_run("exp1", cfg, 5, 0.3, other, true);
  PointCloud wrong = io::load_cloud(other / "drone" / "cloud.ply");
  std::ifstream in(other / "truth" / "drone.json");
  transform_cloud(wrong, Similarity::from_matrix(matrix_from_json(nlohmann::json::parse(in)["T_map_drone"])));
  const GlobalRegistrationResult wrong_site = register_global(wrong, f.map, {}, {});
  EXPECT_FALSE(wrong_site.success) << "rmse " << wrong_site.rmse;
  EXPECT_FALSE(wrong_site.reason.empty());
  // 3. Only terrain on one side (the stones cropped away): no object segments, a reason.
  PointCloud flat;
  for (std::size_t i = 0; i < f.map.size(); ++i)
    if (f.map.world(i).x() < -9.0) flat.points.push_back(f.map.points[i]);  // behind the machine
  flat.origin = f.map.origin;
  ASSERT_GT(flat.size(), 1000u);
  const GlobalRegistrationResult none = register_global(metric_drone(f, {}), flat, {}, {});
  EXPECT_FALSE(none.success);
  // 4. Bad input: empty and non-finite clouds are InputErrors, bad config a ConfigError.
  EXPECT_THROW((void)register_global(PointCloud{}, f.map, {}, {}), InputError);
  PointCloud nan_cloud = metric_drone(f, {});
  nan_cloud.points[10].x() = std::nanf("");
  EXPECT_THROW((void)register_global(nan_cloud, f.map, {}, {}), InputError);
  GlobalRegistrationConfig bad;
  bad.d_match = -1.0;
  EXPECT_THROW((void)register_global(metric_drone(f, {}), f.map, {}, bad), ConfigError);
}

// Issue #20: a drone cloud whose scale is off (scale recovery skipped or wrong) is never registered
// "successfully" and wrong: it is refused for its scale (or right everywhere on the site); with
// scale_check.estimate (`--estimate-scale`, 7-DoF) it is registered and its scale estimated.
class GlobalRegistrationScale : public ::testing::TestWithParam<double> {};

TEST_P(GlobalRegistrationScale, AWrongScaleIsRefusedOrRightAndEstimatedWhenAsked) {
  const Fixture& f = fixture();
  const double k = GetParam();
  Similarity S;  // the metric drone cloud scaled by k about a point off the site's centre
  const Vec3d about(3.0, 2.0, 0.0);
  S.scale = k;
  S.translation = about - k * about;
  const PointCloud source = metric_drone(f, S);
  const Similarity truth = S.inverse();  // T_map_source
  // Right means right where the stones are: at the site's centre and 3 m out diagonally (exp1's
  // stones lie within ~4 m of the centre).
  const std::vector<Vec3d> checks = {kSiteCentre, {3, 3, 0}, {3, -3, 0}, {-3, 3, 0}, {-3, -3, 0}};
  const auto worst = [&](const Similarity& estimate) {
    RegistrationError w;
    for (const Vec3d& at : checks) {
      const RegistrationError e = registration_error(estimate, truth, at);
      w.rotation_deg = std::max(w.rotation_deg, e.rotation_deg);
      w.translation_m = std::max(w.translation_m, e.translation_m);
    }
    return w;
  };
  const GlobalRegistrationResult rigid = register_global(source, f.map, {}, {});
  const RegistrationError e = worst(Similarity::from_isometry(rigid.T_target_source));
  std::printf("[registration, scale %.2f] rigid: %s (fitted scale %.4f), worst %.2f deg, %.1f cm\n", k,
              rigid.success ? "accepted" : rigid.reason.c_str(), rigid.scale_fit.scale, e.rotation_deg,
              100 * e.translation_m);
  if (rigid.success) {  // never a wrong success
    EXPECT_LT(e.rotation_deg, kMaxRotationErrorDeg) << "scale " << k;
    EXPECT_LT(e.translation_m, kMaxTranslationError) << "scale " << k;
  } else if (std::abs(k - 1.0) >= 0.02) {
    EXPECT_EQ(rigid.reason.rfind("scale", 0), 0u) << rigid.reason;  // refused for what it is
  }
  GlobalRegistrationConfig seven_dof;
  seven_dof.scale_check.estimate = true;
  const DroneRegistration d = register_drone(source, f.map, "", "", {}, seven_dof, {});
  ASSERT_TRUE(d.result.success) << "scale " << k << ": " << describe(d.result);
  const RegistrationError e7 = worst(d.T_target_source);
  std::printf("[registration, scale %.2f] 7-DoF: scale %.4f (truth %.4f) in %d passes, worst %.2f deg, %.1f cm\n", k,
              d.T_target_source.scale, 1.0 / k, d.passes, e7.rotation_deg, 100 * e7.translation_m);
  EXPECT_NEAR(d.T_target_source.scale * k, 1.0, 0.005) << "scale " << k;
  EXPECT_LT(e7.rotation_deg, kMaxRotationErrorDeg) << "scale " << k;
  EXPECT_LT(e7.translation_m, kMaxTranslationError) << "scale " << k;
}

#if defined(__SANITIZE_ADDRESS__)
// One scale error under the sanitizers (the path is the same for all); the sweep in Release.
INSTANTIATE_TEST_SUITE_P(ScaleErrors, GlobalRegistrationScale, ::testing::Values(1.05));
#else
INSTANTIATE_TEST_SUITE_P(ScaleErrors, GlobalRegistrationScale,
                         ::testing::Values(0.90, 0.95, 0.98, 0.99, 1.01, 1.02, 1.05, 1.10));
#endif

TEST(GlobalRegistration, LevellingTurnsTheGroundOntoTheMapsGround) {
  const Fixture& f = fixture();
  // The site's ground slopes: the reference is the ground normal of the map (gravity frame).
  const std::optional<Vec3d> up_map = ground_normal(f.map.points);
  ASSERT_TRUE(up_map.has_value());
  EXPECT_GT(up_map->z(), 0.9);  // the map's own ground faces up
  std::mt19937_64 rng(11);
  std::normal_distribution<double> n(0.0, 1.0);
  for (int k = 0; k < 8; ++k) {
    Similarity S;  // arbitrary 3-D rotations, the first one the identity
    if (k > 0) S.rotation = Eigen::Quaterniond(n(rng), n(rng), n(rng), n(rng)).normalized().toRotationMatrix();
    const PointCloud tilted = metric_drone(f, S);
    const Eigen::Matrix3d R = levelling_rotation(voxel_downsample(tilted, {}).points, *up_map);
    // R undoes the tilt: the map's ground normal, seen through S then R, is itself again (yaw is free).
    const Vec3d up = R * S.rotation * *up_map;
    const double err = std::acos(std::clamp(up.dot(*up_map), -1.0, 1.0)) * 180.0 / kPi;
    std::printf("[levelling] rotation %d: ground normal error %.2f deg\n", k, err);
    EXPECT_LT(err, 1.5) << "rotation " << k;  // was 3° off (or 180°) with the plain RANSAC plane
  }
}

// The whole chain on more sites (seed 1 above): each seed is its own simulated exp1 layout (stones, terrain,
// drone survey), 8 s of scanning, scale recovery, and a drone cloud in an arbitrary 3-D frame.
// Success must be right against the truth, and against the map as built (the map's own offset at
// the stones removed, eval/map_offset_at_objects) within the 0.3 deg / 2 cm.
class GlobalRegistrationSeeds : public ::testing::TestWithParam<std::uint64_t> {};

TEST_P(GlobalRegistrationSeeds, ArbitraryFrameRegistersWithEveryStoneOneObject) {
#if defined(__SANITIZE_ADDRESS__) || !defined(NDEBUG)
  GTEST_SKIP() << "seed sweep: optimised builds only (seed 1 covers this chain under the sanitizers)";
#endif
  const std::uint64_t seed = GetParam();
  const fs::path run = test::temp_dir("registration_seed" + std::to_string(seed)) / "run";
  sim::SimulationConfig cfg = sim::scenario_config("exp1", sim::default_real_mesh_dir());
  cfg.with_scan_truth = false;
  (void)sim::simulate_run("exp1", cfg, seed, 8.0, run, true);
  const io::RunDirectory rd = io::open_run_directory(run);
  const PointCloud map = map_run(rd, {}).map;
  std::ifstream in(run / "truth" / "drone.json");
  const Similarity T_map_sfm = Similarity::from_matrix(matrix_from_json(nlohmann::json::parse(in)["T_map_drone"]));
  const ScaleRecoveryResult s = recover_scale(io::read_colmap_text(run / "drone" / "sparse"),
                                              io::read_tum_trajectory(run / "drone" / "vins_trajectory.tum"));
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n(0.0, 1.0);
  Similarity T_source_metric;  // an arbitrary frame on top of the metric (gravity-aligned) one
  T_source_metric.rotation = Eigen::Quaterniond(n(rng), n(rng), n(rng), n(rng)).normalized().toRotationMatrix();
  T_source_metric.translation = Vec3d(20 * n(rng), 20 * n(rng), 20 * n(rng));
  PointCloud source = io::load_cloud(run / "drone" / "cloud.ply");
  transform_cloud(source, T_source_metric * s.T_metric_sfm);
  const Similarity truth = T_map_sfm * (T_source_metric * s.T_metric_sfm).inverse();

  // The paper's candidates alone (consistency groups of ISS + SHOT matches, no centroid pairs),
  // measured for comparison, not asserted: they register 5 of seeds 1-8, seed 5 at 1.5 deg
  // (docs/registration.md). A seed-1 test asserting they register failed as soon as the arm's
  // geometry changed the map (issue #15's angular gripper): it had been a single-seed result.
  GlobalRegistrationConfig groups_only;
  groups_only.centroid_hypotheses = false;
  const GlobalRegistrationResult g = register_global(source, map, {}, groups_only);
  const RegistrationError eg = errors(g.T_target_source, truth, kSiteCentre);
  std::printf("[registration seed %llu, groups only] %s %.3f deg %.1f mm\n", static_cast<unsigned long long>(seed),
              g.success ? "registered" : "failed", eg.rotation_deg, 1000 * eg.translation_m);

  const GlobalRegistrationResult r = register_global(source, map, {}, {});
  ASSERT_TRUE(r.success) << "seed " << seed << ": " << describe(r);
  const RegistrationError e = errors(r.T_target_source, truth, kSiteCentre);
  EXPECT_LT(e.rotation_deg, kMaxRotationErrorDeg);
  EXPECT_LT(e.translation_m, kMaxTranslationError);
  const PointCloud snapshot = io::load_cloud(run / "truth" / "map_snapshot.ply");
  const Similarity T_map_true = Similarity::from_isometry(eval::map_offset_at_objects(map, snapshot).inverse());
  const Vec3d centre_in_map = T_map_true * kSiteCentre;
  const RegistrationError e_map = errors(r.T_target_source, T_map_true * truth, centre_in_map);
  EXPECT_LT(e_map.rotation_deg, 0.3);
  EXPECT_LT(e_map.translation_m, 0.02);

  PointCloud objects;
  std::vector<std::int32_t> object_of;
  objects.origin = map.origin;
  for (std::size_t k = 0; k < r.objects.size(); ++k)
    for (std::size_t i = 0; i < r.objects[k].cloud.size(); ++i) {
      objects.points.push_back((r.objects[k].cloud.world(i) - objects.origin).cast<float>());
      object_of.push_back(std::int32_t(k));
    }
  const SegmentationScore score = score_segmentation(object_of, transfer_labels(snapshot, objects, 0.06), 7);
  EXPECT_EQ(score.found(0.95), 7u) << score.to_json().dump();
  std::printf("[registration seed %llu] vs truth %.3f deg %.1f mm; vs the map %.3f deg %.1f mm (map offset at the "
              "stones %.1f mm); %zu matched, %zu/7 stones single, %.0f ms\n",
              static_cast<unsigned long long>(seed), e.rotation_deg, 1000 * e.translation_m, e_map.rotation_deg,
              1000 * e_map.translation_m, 1000 * (centre_in_map - kSiteCentre).norm(), r.matched_segments.size(),
              score.found(0.95), r.timings.total());
}

INSTANTIATE_TEST_SUITE_P(Exp1, GlobalRegistrationSeeds, ::testing::Values(2, 3, 4, 5, 6, 7, 8),
                         [](const auto& param_info) { return "seed" + std::to_string(param_info.param); });

}  // namespace
}  // namespace cairn
