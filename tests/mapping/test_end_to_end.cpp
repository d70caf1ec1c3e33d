// End to end against simulator ground truth: exp1 and exp2, 20 s of cabin swinging each (no drone,
// no map snapshot); exp1 seed 1 simulated once per ctest run (support/shared_runs.hpp), the others
// once per test process into a temporary directory.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <map>

#include "cairn/core/error.hpp"
#include "cairn/core/io/io.hpp"
#include "cairn/core/io/run_dir.hpp"
#include "cairn/core/kdtree.hpp"
#include "cairn/eval/map_scoring.hpp"
#include "cairn/mapping/mapper.hpp"
#include "cairn/mapping/self_filter.hpp"
#include "cairn/sim/simulation.hpp"
#include "support/shared_runs.hpp"
#include "support/test_data.hpp"

namespace cairn {
namespace {

namespace fs = std::filesystem;
using eval::trajectory_error;
using eval::TrajectoryError;
constexpr double kDuration = 20.0;

const fs::path& simulated_run(const std::string& scenario, std::uint64_t seed, double duration = kDuration) {
  static std::map<std::string, fs::path> runs;
  const std::string name = scenario + "_s" + std::to_string(seed) + "_" + std::to_string(int(duration)) + "s";
  auto it = runs.find(name);
  if (it != runs.end()) return it->second;
  if (scenario == test::kExp1Scans20s.scenario && seed == test::kExp1Scans20s.seed &&
      duration == test::kExp1Scans20s.duration)  // shared by this file's tests (one simulation per ctest run)
    return runs.emplace(name, test::shared_run(test::kExp1Scans20s) / "run").first->second;
  const fs::path dir = test::temp_dir("mapping_" + name) / "run";
  sim::SimulationConfig cfg = sim::scenario_config(scenario, sim::default_real_mesh_dir());
  cfg.with_drone = false;
  cfg.with_snapshot = false;
  cfg.with_scan_truth = true;
  (void)sim::simulate_run(scenario, cfg, seed, duration, dir, true);
  return runs.emplace(name, dir).first->second;
}

// Exact point-to-triangle distances to the true surfaces (terrain + stone meshes).
class TrueSurface {
 public:
  explicit TrueSurface(const fs::path& truth) {
    add(io::read_ply_mesh(truth / "terrain.ply"));
    for (const auto& e : fs::directory_iterator(truth / "stones"))
      if (e.path().extension() == ".ply") add(io::read_ply_mesh(e.path()));
    tree_ = std::make_unique<KdTree>(centroids_);
  }
  [[nodiscard]] double distance(const Vec3d& p) const {
    Neighbors nb;
    tree_->knn(p.cast<float>(), 12, nb);
    double best = 1e9;
    for (std::uint32_t i : nb.indices) best = std::min(best, point_triangle(p, tri_[i]));
    return best;
  }

 private:
  void add(const io::Mesh& m) {
    for (const auto& t : m.triangles) {
      const std::array<Vec3d, 3> v{m.vertices.world(t[0]), m.vertices.world(t[1]), m.vertices.world(t[2])};
      tri_.push_back(v);
      centroids_.push_back(((v[0] + v[1] + v[2]) / 3.0).cast<float>());
    }
  }
  static double point_triangle(const Vec3d& p, const std::array<Vec3d, 3>& t) {  // Ericson, RTCD 5.1.5
    const Vec3d &a = t[0], &b = t[1], &c = t[2];
    const Vec3d ab = b - a, ac = c - a, ap = p - a;
    const double d1 = ab.dot(ap), d2 = ac.dot(ap);
    if (d1 <= 0 && d2 <= 0) return ap.norm();
    const Vec3d bp = p - b;
    const double d3 = ab.dot(bp), d4 = ac.dot(bp);
    if (d3 >= 0 && d4 <= d3) return bp.norm();
    const double vc = d1 * d4 - d3 * d2;
    if (vc <= 0 && d1 >= 0 && d3 <= 0) return (p - (a + d1 / (d1 - d3) * ab)).norm();
    const Vec3d cp = p - c;
    const double d5 = ab.dot(cp), d6 = ac.dot(cp);
    if (d6 >= 0 && d5 <= d6) return cp.norm();
    const double vb = d5 * d2 - d1 * d6;
    if (vb <= 0 && d2 >= 0 && d6 <= 0) return (p - (a + d2 / (d2 - d6) * ac)).norm();
    const double va = d3 * d6 - d5 * d4;
    if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0)
      return (p - (b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b))).norm();
    const double denom = 1.0 / (va + vb + vc);
    return (p - (a + ab * (vb * denom) + ac * (vc * denom))).norm();
  }
  std::vector<std::array<Vec3d, 3>> tri_;
  std::vector<Vec3f> centroids_;
  std::unique_ptr<KdTree> tree_;
};

struct MapAccuracy {
  double within_2cm = 0.0, within_3cm = 0.0, median = 0.0, p95 = 0.0;
};

MapAccuracy map_accuracy(const PointCloud& map, const TrueSurface& surface) {
  std::vector<double> d(map.size());
  for (std::size_t i = 0; i < map.size(); ++i) d[i] = surface.distance(map.world(i));
  std::sort(d.begin(), d.end());
  MapAccuracy a;
  if (d.empty()) return a;
  a.within_2cm = double(std::upper_bound(d.begin(), d.end(), 0.02) - d.begin()) / d.size();
  a.within_3cm = double(std::upper_bound(d.begin(), d.end(), 0.03) - d.begin()) / d.size();
  a.median = d[d.size() / 2];
  a.p95 = d[std::min(d.size() - 1, std::size_t(0.95 * d.size()))];
  return a;
}

class MappingEndToEnd : public ::testing::TestWithParam<std::pair<std::string, std::uint64_t>> {};

TEST_P(MappingEndToEnd, TrajectoryMapSelfFilterAndDeskewAgainstTruth) {
  const auto& [scenario, seed] = GetParam();
  // The sanitizers run the path once (exp1, without the smoothing and de-skew ablations); the
  // figures of both scenarios and the ablations are asserted in Release.
  using test::kSanitized;
  if (kSanitized && scenario != "exp1") GTEST_SKIP() << "exp1 covers this path under the sanitizers";
  const fs::path& dir = simulated_run(scenario, seed);
  io::RunDirectory run = io::open_run_directory(dir);
  test::shorten_under_sanitizers(run, 8.0);  // the figures below hold on the whole 20 s run
  const std::vector<StampedPose> truth = io::read_stamped_poses(run.truth_dir() / "cabin_poses.tum");

  MappingConfig tuned;
  const MapRunResult r = map_run(run, tuned);
  ASSERT_GT(r.stats.nodes, kSanitized ? 40u : 100u);
  ASSERT_GT(r.map.size(), 10000u);
  const TrajectoryError raw = trajectory_error(r.raw_trajectory, truth);
  const TrajectoryError mapped = trajectory_error(r.trajectory, truth);
  std::printf("[ %s ] pairs %zu nodes %zu scan edges %zu loop edges %zu rejected %zu map points %zu (%.1f pairs/s)\n",
              scenario.c_str(), r.stats.pairs, r.stats.nodes, r.stats.scan_edges, r.stats.loop_edges,
              r.stats.icp_rejected, r.map.size(), r.stats.pairs / r.seconds);
  std::printf("[ %s ] ATE RMSE raw %.4f m (without mean %.4f) | mapped %.4f m (without mean %.4f); "
              "rotation raw %.3f deg | mapped %.3f deg\n",
              scenario.c_str(), raw.ate_rmse, raw.ate_rmse_without_mean, mapped.ate_rmse,
              mapped.ate_rmse_without_mean, raw.rotation_rmse_deg, mapped.rotation_rmse_deg);
  EXPECT_LT(mapped.ate_rmse, raw.ate_rmse);
  EXPECT_LT(mapped.ate_rmse_without_mean, raw.ate_rmse_without_mean);
  // 20 s runs: the mean GNSS bias over the run (1.6 cm on exp1, seed 1) is unobservable; see
  // docs/mapping.md. Measured: exp1 2.11 cm (raw 3.03), exp2 1.65 cm (raw 2.75).
  if (!kSanitized) {
    EXPECT_LT(mapped.ate_rmse, 0.022);
    EXPECT_LT(mapped.ate_rmse_without_mean, 0.015);  // measured 1.33 / 1.25 cm
  }

  const TrueSurface surface(run.truth_dir());
  const MapAccuracy acc = map_accuracy(r.map, surface);
  std::printf("[ %s ] map: %.1f %% of points within 2 cm of the true surface, %.1f %% within 3 cm, median %.4f m, "
              "p95 %.4f m\n",
              scenario.c_str(), 100 * acc.within_2cm, 100 * acc.within_3cm, acc.median, acc.p95);
  // The same map with the constant part of the pose error (the run's mean GNSS bias, which no
  // relative constraint can observe) removed: the map's shape accuracy.
  PointCloud shifted = r.map;
  shifted.origin -= mapped.mean_error;
  const MapAccuracy acc_shape = map_accuracy(shifted, surface);
  MappingConfig plain;
  plain.local_map.smoothing_radius = 0.0;  // the paper's plain voxel grid
  const MapRunResult r_plain = kSanitized ? r : map_run(run, plain);
  PointCloud plain_shifted = r_plain.map;
  plain_shifted.origin -= mapped.mean_error;
  const MapAccuracy acc_plain = map_accuracy(r_plain.map, surface);
  const MapAccuracy acc_plain_shape = map_accuracy(plain_shifted, surface);
  std::printf("[ %s ] map without the mean pose bias (%.4f %.4f %.4f m): %.1f %% within 2 cm, %.1f %% within 3 cm, "
              "median %.4f m\n",
              scenario.c_str(), mapped.mean_error.x(), mapped.mean_error.y(), mapped.mean_error.z(),
              100 * acc_shape.within_2cm, 100 * acc_shape.within_3cm, acc_shape.median);
  std::printf("[ %s ] plain voxel grid (no smoothing): %.1f %% within 2 cm (%.1f %% without the mean bias), "
              "median %.4f m\n",
              scenario.c_str(), 100 * acc_plain.within_2cm, 100 * acc_plain_shape.within_2cm, acc_plain.median);
  // Measured (quadratic MLS smoothing): exp1 74.4 % absolute (its mean GNSS bias is -1.6 cm in
  // z), 96.8 % without it; exp2 95.2 % / 95.4 %.
  if (!kSanitized) {
    EXPECT_GT(acc.within_2cm, 0.7);         // absolute: includes the run's mean GNSS bias
    EXPECT_GT(acc_shape.within_2cm, 0.94);  // shape
    EXPECT_GT(acc.within_2cm, acc_plain.within_2cm);
  }

  // Self-filter: share of kept sweep points that truly hit the robot (label -3).
  std::size_t kept_total = 0, kept_robot = 0, robot_total = 0;
  for (const io::ScanInfo& s : run.scans) {
    const PointCloud cloud = run.read_scan(s);
    const std::vector<std::int32_t> labels = run.read_scan_truth(s);
    for (std::int32_t l : labels) robot_total += l == -3;
    const auto kept = self_filter(cloud, run.robot, run.joint_states, run.T_cabin_sensor.at(s.sensor), {});
    kept_total += kept.size();
    for (std::uint32_t i : kept) kept_robot += labels[i] == -3;
  }
  const double robot_share = double(kept_robot) / std::max<std::size_t>(1, kept_total);
  std::printf("[ %s ] self-filter: %zu robot returns, %zu left after filtering = %.4f %% of kept points\n",
              scenario.c_str(), robot_total, kept_robot, 100 * robot_share);
  EXPECT_LT(robot_share, 0.001);

  // De-skew ablation: one pose per sweep instead of one per point (a figure: Release only, its
  // one config branch is a pose lookup).
  if (kSanitized) return;
  MappingConfig no_deskew;
  no_deskew.deskew.enabled = false;
  const MapRunResult off = map_run(run, no_deskew);
  const MapAccuracy acc_off = map_accuracy(off.map, surface);
  const TrajectoryError mapped_off = trajectory_error(off.trajectory, truth);
  std::printf("[ %s ] de-skew off: map %.1f %% within 2 cm (on: %.1f %%), median %.4f m (on: %.4f m), "
              "ATE %.4f m (on: %.4f m)\n",
              scenario.c_str(), 100 * acc_off.within_2cm, 100 * acc.within_2cm, acc_off.median, acc.median,
              mapped_off.ate_rmse, mapped.ate_rmse);
  EXPECT_GT(acc.within_2cm, acc_off.within_2cm);
}

INSTANTIATE_TEST_SUITE_P(Scenarios, MappingEndToEnd,
                         ::testing::Values(std::make_pair(std::string("exp1"), std::uint64_t{1}),
                                           std::make_pair(std::string("exp2"), std::uint64_t{2})),
                         [](const auto& p) { return p.param.first; });

// 60 s of swinging (the long end of the 20-60 s): the run's mean GNSS/INS error, which
// no relative constraint observes, averages down with the length of the run (docs/mapping.md),
// and the absolute targets come within reach. Release only (a minute of simulated sweeps).
class MappingLongRun : public ::testing::TestWithParam<std::pair<std::string, std::uint64_t>> {};

TEST_P(MappingLongRun, SixtySecondsMeetTheAbsoluteTargets) {
#if defined(__SANITIZE_ADDRESS__) || !defined(NDEBUG)
  GTEST_SKIP() << "60 s mapping run: optimised builds only (the 20 s runs cover the mapper under the sanitizers)";
#endif
  const auto& [scenario, seed] = GetParam();
  const fs::path dir = test::temp_dir("mapping_long_" + scenario) / "run";
  sim::SimulationConfig cfg = sim::scenario_config(scenario, sim::default_real_mesh_dir());
  cfg.with_drone = false;
  cfg.with_snapshot = false;
  cfg.with_scan_truth = false;
  (void)sim::simulate_run(scenario, cfg, seed, 60.0, dir, true);
  const io::RunDirectory run = io::open_run_directory(dir);
  const std::vector<StampedPose> truth = io::read_stamped_poses(run.truth_dir() / "cabin_poses.tum");
  const MapRunResult r = map_run(run, {});
  const TrajectoryError raw = trajectory_error(r.raw_trajectory, truth);
  const TrajectoryError mapped = trajectory_error(r.trajectory, truth);
  const MapAccuracy acc = map_accuracy(r.map, TrueSurface(run.truth_dir()));
  std::printf("[ %s 60 s seed %llu ] ATE raw %.4f m -> mapped %.4f m (mean error %.4f %.4f %.4f m); map %.1f %% "
              "within 2 cm, %.1f %% within 3 cm, median %.4f m; %.1f pairs/s\n",
              scenario.c_str(), static_cast<unsigned long long>(seed), raw.ate_rmse, mapped.ate_rmse,
              mapped.mean_error.x(), mapped.mean_error.y(), mapped.mean_error.z(), 100 * acc.within_2cm,
              100 * acc.within_3cm, acc.median, double(r.stats.pairs) / r.seconds);
  // Measured: exp1 3.29 -> 1.34 cm, exp2 3.84 -> 1.83 cm: the 2 cm is met at 60 s (20 s
  // exp1 seed 1: 2.11 cm). Map within 2 cm of the true surface: 95.9 % / 95.8 % (median 7 mm),
  // the 95 % (with the plane smoothing before the quadratic one: 91.6 % / 91.4 %).
  EXPECT_LT(mapped.ate_rmse, 0.02);  // the target; exp2 measures 1.83 cm (little margin)
  EXPECT_LT(mapped.ate_rmse, 0.6 * raw.ate_rmse);
  EXPECT_GT(acc.within_2cm, 0.95);  // the target; deterministic run, 0.9 points of margin
  PointCloud shifted = r.map;
  shifted.origin -= mapped.mean_error;
  const MapAccuracy shape = map_accuracy(shifted, TrueSurface(run.truth_dir()));
  std::printf("[ %s 60 s seed %llu ] map without the run's mean position error: %.1f %% within 2 cm\n",
              scenario.c_str(), static_cast<unsigned long long>(seed), 100 * shape.within_2cm);
  EXPECT_GT(shape.within_2cm, 0.96);  // exp1 97.6 %, exp2 97.2 %
}

INSTANTIATE_TEST_SUITE_P(Scenarios, MappingLongRun,
                         ::testing::Values(std::make_pair(std::string("exp1"), std::uint64_t{1}),
                                           std::make_pair(std::string("exp2"), std::uint64_t{2})),
                         [](const auto& p) { return p.param.first; });

// Short runs (8 s, three seeds): mapping must never make the trajectory worse than the state
// estimate it starts from, although few loop closures exist yet (first after 4 s).
TEST(MappingShortRun, MappedNeverWorseThanRaw) {
  if (test::kSanitized) GTEST_SKIP() << "a figure over seeds; MappingEndToEnd/exp1 runs map_run and trajectory_error "
                                        "on an 8 s exp1 run under the sanitizers";
  const std::vector<std::uint64_t> seeds{1, 2, 3};
  for (const std::uint64_t seed : seeds) {
    const io::RunDirectory run = io::open_run_directory(simulated_run("exp1", seed, 8.0));
    const std::vector<StampedPose> truth = io::read_stamped_poses(run.truth_dir() / "cabin_poses.tum");
    MappingConfig cfg;
    cfg.local_map.smoothing_radius = 0.0;  // the trajectory does not depend on the snapshot
    const MapRunResult r = map_run(run, cfg);
    const TrajectoryError raw = trajectory_error(r.raw_trajectory, truth);
    const TrajectoryError mapped = trajectory_error(r.trajectory, truth);
    std::printf("[ exp1 8 s seed %llu ] ATE raw %.4f m -> mapped %.4f m (without mean %.4f -> %.4f m)\n",
                static_cast<unsigned long long>(seed), raw.ate_rmse, mapped.ate_rmse, raw.ate_rmse_without_mean,
                mapped.ate_rmse_without_mean);
    EXPECT_LE(mapped.ate_rmse, raw.ate_rmse) << "seed " << seed;
    // Measured: 2.84 -> 1.98, 3.04 -> 2.69, 2.42 -> 1.86 cm; the part without the run's mean
    // (unobservable) GNSS bias drops by a third or more.
    EXPECT_LT(mapped.ate_rmse_without_mean, 0.7 * raw.ate_rmse_without_mean) << "seed " << seed;
    fs::remove_all(run.root);
  }
}

TEST(MappingRunDirectory, MissingFilesAreInputErrors) {
  const fs::path dir = test::temp_dir("mapping_broken");
  fs::remove_all(dir);
  EXPECT_THROW((void)io::open_run_directory(dir), InputError);
  const fs::path& good = simulated_run("exp1", 1, 2.0);  // a short run has every file kind
  fs::copy(good, dir, fs::copy_options::recursive);
  fs::remove(dir / "scans" / "H" / "000003.ply");
  const io::RunDirectory run = io::open_run_directory(dir);
  EXPECT_THROW((void)map_run(run), InputError);
  fs::remove(dir / "state" / "cabin_poses.tum");
  EXPECT_THROW((void)io::open_run_directory(dir), InputError);
  fs::remove_all(dir);
}

// The windowed updates keep old nodes fixed, so mid-stream the map's absolute frame stays where
// the first window's GNSS/INS priors put it; reoptimize() lets every prior so far pull the whole
// trajectory (and the rebuilt map) to their mean, and mapping goes on from there.
TEST(MappingStreaming, ReoptimizeMidStreamFollowsTheMeanOfThePriors) {
  io::RunDirectory run = io::open_run_directory(simulated_run("exp1", 1));
  test::shorten_under_sanitizers(run, 4.0);  // the path on 4 s; the figures on 20 s in Release
  const std::vector<StampedPose> truth = io::read_stamped_poses(run.truth_dir() / "cabin_poses.tum");
  MappingConfig cfg;
  cfg.local_map.smoothing_radius = 0.0;  // the poses do not depend on the snapshot
  Mapper mapper({.robot = run.robot, .T_cabin_sensor = run.T_cabin_sensor}, cfg);
  mapper.add_state_estimates(run.state_estimate);
  mapper.add_joint_states(run.joint_states);
  const std::size_t half = run.scans.size() / 2;
  for (std::size_t k = 0; k < half; ++k) {
    const io::ScanInfo& s = run.scans[k];
    mapper.add_sweep(s.sensor, run.read_scan(s), s.t_start, s.t_end);
  }
  // The gap between the mapped trajectory's mean error and the priors' mean error.
  const auto gap = [&] {
    const TrajectoryError raw = trajectory_error(mapper.raw_trajectory(), truth);
    const TrajectoryError mapped = trajectory_error(mapper.trajectory(), truth);
    return (mapped.mean_error - raw.mean_error).norm();
  };
  const auto shape = [&](const PointCloud& map) {  // accuracy with the trajectory's mean error removed
    PointCloud shifted = map;
    shifted.origin -= trajectory_error(mapper.trajectory(), truth).mean_error;
    return map_accuracy(shifted, TrueSurface(run.truth_dir()));
  };
  const PointCloud map_before = mapper.map();
  const MapAccuracy shape_before = shape(map_before);
  const double gap_windowed = gap();
  mapper.reoptimize();
  const double gap_full = gap();
  const PointCloud map_after = mapper.map();
  const MapAccuracy shape_after = shape(map_after);
  std::printf("[ exp1 10 s ] mapped minus prior mean error: windowed %.2f mm, reoptimised %.2f mm; map %zu -> %zu "
              "points, shape within 2 cm %.1f -> %.1f %%, median %.1f -> %.1f mm\n",
              1e3 * gap_windowed, 1e3 * gap_full, map_before.size(), map_after.size(), 100 * shape_before.within_2cm,
              100 * shape_after.within_2cm, 1e3 * shape_before.median, 1e3 * shape_after.median);
  if (!test::kSanitized) {
    EXPECT_LT(gap_full, 0.5 * gap_windowed);
    EXPECT_LT(gap_full, 0.005);
  }
  // The rebuilt map holds the same scans with the same crops (every crop_every nodes, none at
  // the end: a stone at the edge of R_map keeps its far side, as when streaming), each at its new
  // pose where the windowed map kept the pose it had when inserted: as many voxels, and a shape
  // at least as accurate.
  EXPECT_NEAR(double(map_after.size()), double(map_before.size()), 0.01 * double(map_before.size()));
  if (!test::kSanitized) {
    EXPECT_GE(shape_after.within_2cm, shape_before.within_2cm);
  }
  // Mapping goes on from the moved trajectory (the submaps built before are still matched) and
  // ends as accurate as a run that never reoptimised.
  for (std::size_t k = half; k < run.scans.size(); ++k) {
    const io::ScanInfo& s = run.scans[k];
    mapper.add_sweep(s.sensor, run.read_scan(s), s.t_start, s.t_end);
  }
  mapper.finish();
  if (test::kSanitized) return;  // the comparison with a plain run is a figure; its path is the same
  const MapRunResult plain = map_run(run, cfg);
  const TrajectoryError with = trajectory_error(mapper.trajectory(), truth);
  const TrajectoryError without = trajectory_error(plain.trajectory, truth);
  std::printf("[ exp1 20 s ] ATE with a mid-stream reoptimisation %.4f m, without %.4f m; icp rejected %zu / %zu\n",
              with.ate_rmse, without.ate_rmse, mapper.stats().icp_rejected, plain.stats.icp_rejected);
  EXPECT_LT(with.ate_rmse, without.ate_rmse + 0.002);
  EXPECT_LE(mapper.stats().icp_rejected, plain.stats.icp_rejected + 2);
}

// An edit made early moves with the node that was newest then when a later reoptimisation moves
// the trajectory (an inserted cloud stays on the surfaces it was placed against).
TEST(MappingStreaming, EditsMoveWithTheirNodeInARebuild) {
  io::RunDirectory run = io::open_run_directory(simulated_run("exp1", 1));
  test::shorten_under_sanitizers(run, 6.0);  // the edit and the rebuild on 6 s; 20 s in Release
  MappingConfig cfg;
  cfg.local_map.smoothing_radius = 0.0;
  Mapper mapper({.robot = run.robot, .T_cabin_sensor = run.T_cabin_sensor}, cfg);
  mapper.add_state_estimates(run.state_estimate);
  mapper.add_joint_states(run.joint_states);
  const std::size_t early = 40;  // 2 s of scanning: the first window's priors alone
  for (std::size_t k = 0; k < early; ++k) {
    const io::ScanInfo& s = run.scans[k];
    mapper.add_sweep(s.sensor, run.read_scan(s), s.t_start, s.t_end);
  }
  PointCloud marker;
  marker.points = {Vec3f(0.0f, 0.0f, 0.0f)};
  marker.origin = (mapper.current_pose().translation() + Vec3d(3, 0, 5)).eval();  // above the site
  mapper.insert(marker);
  const std::size_t anchor = mapper.trajectory().size() - 1;
  const Eigen::Isometry3d T_anchor_before = mapper.trajectory()[anchor].pose;
  for (std::size_t k = early; k < run.scans.size(); ++k) {
    const io::ScanInfo& s = run.scans[k];
    mapper.add_sweep(s.sensor, run.read_scan(s), s.t_start, s.t_end);
  }
  mapper.reoptimize();
  const Eigen::Isometry3d motion = mapper.trajectory()[anchor].pose * T_anchor_before.inverse();
  const Vec3d expected = motion * marker.origin;
  const PointCloud map = mapper.map();
  double nearest = 1e9;
  for (std::size_t i = 0; i < map.size(); ++i) nearest = std::min(nearest, (map.world(i) - expected).norm());
  std::printf("edit's node moved %.1f mm; the marker is %.3f mm from where it moved to\n",
              1e3 * (expected - marker.origin).norm(), 1e3 * nearest);
  EXPECT_GT((expected - marker.origin).norm(), 0.002);  // the reoptimisation did move it
  EXPECT_LT(nearest, 1e-3);
}

TEST(MappingStreaming, RemoveAndInsertSurviveTheFinalRebuild) {
  const io::RunDirectory run = io::open_run_directory(simulated_run("exp1", 1));
  MappingConfig cfg;
  Mapper mapper({.robot = run.robot, .T_cabin_sensor = run.T_cabin_sensor}, cfg);
  mapper.add_state_estimates(run.state_estimate);
  mapper.add_joint_states(run.joint_states);
  const Vec3d hole(0.0, 0.0, 0.0);
  for (std::size_t k = 0; k < 60 && k < run.scans.size(); ++k) {
    const io::ScanInfo& s = run.scans[k];
    mapper.add_sweep(s.sensor, run.read_scan(s), s.t_start, s.t_end);
  }
  const PointCloud before = mapper.map();  // a snapshot while mapping runs
  ASSERT_GT(before.size(), 1000u);
  const Vec3d centre = before.world(before.size() / 2);
  const std::size_t removed = mapper.remove_sphere(centre, 1.0);
  EXPECT_GT(removed, 0u);
  PointCloud marker;
  marker.points = {Vec3f(0.0f, 0.0f, 30.0f)};  // far above everything
  marker.origin = (mapper.current_pose().translation() - Vec3d(0, 0, 25)).eval();
  mapper.insert(marker);
  const std::size_t anchor = mapper.trajectory().size() - 1;  // the newest node when editing
  const Eigen::Isometry3d T_anchor_before = mapper.trajectory()[anchor].pose;
  mapper.finish();
  // The final optimisation moves the scans; an edit moves with the node that was newest when it
  // was made (here by millimetres to centimetres).
  const Eigen::Isometry3d motion = mapper.trajectory()[anchor].pose * T_anchor_before.inverse();
  const Vec3d marker_now = motion * (marker.origin + Vec3d(0, 0, 30));
  const PointCloud after = mapper.map();
  std::size_t near_centre = 0, markers = 0;
  for (std::size_t i = 0; i < after.size(); ++i) {
    if ((after.world(i) - motion * centre).norm() < 0.9) ++near_centre;
    if ((after.world(i) - marker_now).norm() < 1e-3) ++markers;
  }
  // Only sweeps after the removal may refill the hole (2.5 s of the 3 s here): some points, not all.
  EXPECT_LT(near_centre, removed);
  EXPECT_EQ(markers, 1u);
  (void)hole;
}

}  // namespace
}  // namespace cairn
