// ICP: cairn vs PCL (IterativeClosestPoint, IterativeClosestPointWithNormals) vs Open3D
// (RegistrationICP + TransformationEstimationPointToPlane), same pairs, same initial guess,
// same correspondence distance, same target normals, same iteration cap, same run.
//
// Pairs:
//  - Scan2Submap: a LiDAR-like scan (30k points, density ∝ 1/range²) against a 300k-point submap of
//    the synthetic stone site (Sec. 4.2 scan-to-submap; independent samples, 5 mm noise),
//    initial error 0.2 m / 3°.
//  - Outdoor: the real outdoor LiDAR pair (gicp-outdoor-lidar-pair), voxelised at 10 cm, from
//    identity (0.5 m away from the reference).
// Timed: registration only. Target preparation (kd-tree; normals, which all three receive from
// cairn) is timed separately as *_PrepareTarget: a mapping submap is prepared once per many scans.
#include <benchmark/benchmark.h>
#include <pcl/point_types.h>
#include <pcl/registration/icp.h>

#ifdef CAIRN_BENCH_OPEN3D
#include <open3d/geometry/PointCloud.h>
#include <open3d/pipelines/registration/Registration.h>
#include <open3d/pipelines/registration/TransformationEstimation.h>
#endif

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "cairn/core/io/io.hpp"
#include "cairn/core/voxel_grid.hpp"
#include "cairn/registration/icp.hpp"
#include "support/registration_scenes.hpp"

using namespace cairn;

namespace {

constexpr double kDeg = M_PI / 180.0;
constexpr int kMaxIterations = 50;
// Comparable stopping rules: cairn stops at an increment below 1e-4 m and 1e-4 rad (its defaults);
// PCL at a squared translation increment below 1e-8 m² and a rotation increment that rounds to
// identity in float; Open3D at a relative fitness and RMSE change below 1e-6. Each benchmark
// reports its iterations and its error against the reference (err_mm, err_mdeg).
constexpr double kTolerance = 1e-4;

struct Pair {
  std::string name;
  std::vector<Vec3f> source, target, target_normals;
  Eigen::Isometry3d T_init = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_ref = Eigen::Isometry3d::Identity();  // ground truth / published reference
  double max_corr = 1.0;
};

std::filesystem::path shared_dir() {
  if (const char* env = std::getenv("CAIRN_SHARED_DIR")) return env;
  return CAIRN_SHARED_DIR;
}

const Pair& pair(int which) {
  static const Pair scan2submap = [] {
    Pair p;
    p.name = "scan2submap";
    const Eigen::Isometry3d T_gt = test::make_pose(2 * kDeg, -1.5 * kDeg, 12 * kDeg, {0.8, -0.5, 0.1});
    p.target = test::sample_site(300000, 1, 0.005f);
    p.source = test::transformed(test::sample_site(30000, 2, 0.005f, true), T_gt.inverse());
    p.T_init = test::make_pose(0.5 * kDeg, 0.5 * kDeg, 3 * kDeg, {0.2, -0.1, 0.05}) * T_gt;
    p.max_corr = 1.0;
    const IcpTarget t(p.target, NormalConfig{.k = 20});
    p.target.assign(t.points().begin(), t.points().end());  // the same (Morton) order for every peer
    p.target_normals.assign(t.normals().begin(), t.normals().end());
    p.T_ref = T_gt;
    return p;
  }();
  static const Pair outdoor = [] {
    Pair p;
    p.name = "outdoor";
    const auto dir = shared_dir() / "data/real/gicp-outdoor-lidar-pair";
    if (!std::filesystem::exists(dir / "source.ply")) return p;
    p.source = voxel_downsample(io::load_cloud(dir / "source.ply"), {.res_voxel = 0.1}).points;
    p.target = voxel_downsample(io::load_cloud(dir / "target.ply"), {.res_voxel = 0.1}).points;
    p.max_corr = 1.0;
    std::ifstream in(dir / "T_target_source.txt");
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) in >> p.T_ref.matrix()(r, c);
    const IcpTarget t(p.target, NormalConfig{.k = 20});
    p.target.assign(t.points().begin(), t.points().end());  // the same (Morton) order for every peer
    p.target_normals.assign(t.normals().begin(), t.normals().end());
    return p;
  }();
  return which == 0 ? scan2submap : outdoor;
}

const IcpTarget& cairn_target(int which) {
  static const IcpTarget a(pair(0).target, pair(0).target_normals);
  static const IcpTarget b = pair(1).target.empty() ? IcpTarget(std::vector<Vec3f>{Vec3f::Zero()})
                                                    : IcpTarget(pair(1).target, pair(1).target_normals);
  return which == 0 ? a : b;
}

bool skip_if_missing(benchmark::State& state, int which) {
  if (!pair(which).source.empty()) return false;
  state.SkipWithError("real data not found (gicp-outdoor-lidar-pair)");
  return true;
}

void set_counters(benchmark::State& state, const Pair& p, int iterations, const Eigen::Isometry3d& T) {
  state.counters["source_pts"] = double(p.source.size());
  state.counters["target_pts"] = double(p.target.size());
  if (iterations >= 0) state.counters["icp_iters"] = iterations;  // Open3D 0.16 does not report it
  const auto e = test::pose_error(T, p.T_ref);
  state.counters["err_mm"] = e.translation * 1e3;
  state.counters["err_mdeg"] = e.rotation / kDeg * 1e3;
  state.SetLabel(p.name);
}

IcpConfig cairn_config(const Pair& p, const char* objective, bool parallel) {
  return {.objective = objective, .max_correspondence_distance = p.max_corr, .max_iterations = kMaxIterations,
          .translation_tolerance = kTolerance, .rotation_tolerance = kTolerance, .parallel = parallel};
}

void BM_Cairn_PointToPlane(benchmark::State& state) {
  const int w = int(state.range(0));
  if (skip_if_missing(state, w)) return;
  IcpResult r;
  for (auto _ : state) r = register_icp(pair(w).source, cairn_target(w), pair(w).T_init, cairn_config(pair(w), "point_to_plane", true));
  set_counters(state, pair(w), r.iterations, r.T_target_source);
}

void BM_Cairn_PointToPlaneSerial(benchmark::State& state) {
  const int w = int(state.range(0));
  if (skip_if_missing(state, w)) return;
  IcpResult r;
  for (auto _ : state) r = register_icp(pair(w).source, cairn_target(w), pair(w).T_init, cairn_config(pair(w), "point_to_plane", false));
  set_counters(state, pair(w), r.iterations, r.T_target_source);
}

void BM_Cairn_PointToPoint(benchmark::State& state) {
  const int w = int(state.range(0));
  if (skip_if_missing(state, w)) return;
  IcpResult r;
  for (auto _ : state) r = register_icp(pair(w).source, cairn_target(w), pair(w).T_init, cairn_config(pair(w), "point_to_point", true));
  set_counters(state, pair(w), r.iterations, r.T_target_source);
}

/// Including the kd-tree build over the submap (normals given), as Open3D's RegistrationICP does.
void BM_Cairn_PointToPlaneWithTree(benchmark::State& state) {
  const int w = int(state.range(0));
  if (skip_if_missing(state, w)) return;
  IcpResult r;
  for (auto _ : state) {
    const IcpTarget target(pair(w).target, pair(w).target_normals);
    r = register_icp(pair(w).source, target, pair(w).T_init, cairn_config(pair(w), "point_to_plane", true));
  }
  set_counters(state, pair(w), r.iterations, r.T_target_source);
}

void BM_Cairn_PrepareTarget(benchmark::State& state) {
  const int w = int(state.range(0));
  if (skip_if_missing(state, w)) return;
  for (auto _ : state) benchmark::DoNotOptimize(IcpTarget(pair(w).target, NormalConfig{.k = 20}));
  state.counters["target_pts"] = double(pair(w).target.size());
  state.SetLabel(pair(w).name);
}

template <class PointT>
typename pcl::PointCloud<PointT>::Ptr to_pcl(std::span<const Vec3f> pts, std::span<const Vec3f> normals = {}) {
  auto c = pcl::make_shared<pcl::PointCloud<PointT>>();
  c->reserve(pts.size());
  for (std::size_t i = 0; i < pts.size(); ++i) {
    PointT q;
    q.getVector3fMap() = pts[i];
    if constexpr (std::is_same_v<PointT, pcl::PointNormal>)
      q.getNormalVector3fMap() = normals.empty() ? Vec3f::Zero() : normals[i];
    c->push_back(q);
  }
  return c;
}

/// The PCL objects own their kd-tree: setInputTarget once outside the loop, so the timed part is
/// the registration only (PCL rebuilds the target tree only when the target changes).
template <class Icp>
void run_pcl(benchmark::State& state, Icp& icp, int w) {
  const Pair& p = pair(w);
  icp.setMaxCorrespondenceDistance(p.max_corr);
  icp.setMaximumIterations(kMaxIterations);
  icp.setTransformationEpsilon(kTolerance * kTolerance);
  icp.setTransformationRotationEpsilon(std::cos(kTolerance));
  typename Icp::PointCloudSource out;
  icp.align(out, p.T_init.matrix().cast<float>());  // warm-up: builds the target tree
  for (auto _ : state) {
    icp.align(out, p.T_init.matrix().cast<float>());
    benchmark::DoNotOptimize(out.size());
  }
  Eigen::Isometry3d T;
  T.matrix() = icp.getFinalTransformation().template cast<double>();
  set_counters(state, p, icp.nr_iterations_, T);
}

template <class T>
struct PclIcpAccess : T {  // nr_iterations_ is protected; expose it for the counter
  using T::nr_iterations_;
};

void BM_Pcl_PointToPoint(benchmark::State& state) {
  const int w = int(state.range(0));
  if (skip_if_missing(state, w)) return;
  PclIcpAccess<pcl::IterativeClosestPoint<pcl::PointXYZ, pcl::PointXYZ>> icp;
  icp.setInputSource(to_pcl<pcl::PointXYZ>(pair(w).source));
  icp.setInputTarget(to_pcl<pcl::PointXYZ>(pair(w).target));
  run_pcl(state, icp, w);
}

void BM_Pcl_PointToPlane(benchmark::State& state) {
  const int w = int(state.range(0));
  if (skip_if_missing(state, w)) return;
  PclIcpAccess<pcl::IterativeClosestPointWithNormals<pcl::PointNormal, pcl::PointNormal>> icp;
  icp.setInputSource(to_pcl<pcl::PointNormal>(pair(w).source));
  icp.setInputTarget(to_pcl<pcl::PointNormal>(pair(w).target, pair(w).target_normals));
  run_pcl(state, icp, w);
}

#ifdef CAIRN_BENCH_OPEN3D
namespace o3r = open3d::pipelines::registration;

void BM_Open3d_PointToPlane(benchmark::State& state) {
  const int w = int(state.range(0));
  if (skip_if_missing(state, w)) return;
  const Pair& p = pair(w);
  open3d::geometry::PointCloud src, tgt;
  for (const auto& q : p.source) src.points_.push_back(q.cast<double>());
  for (const auto& q : p.target) tgt.points_.push_back(q.cast<double>());
  for (const auto& n : p.target_normals) tgt.normals_.push_back(n.cast<double>());
  o3r::RegistrationResult r;
  // Open3D builds its target kd-tree inside RegistrationICP (no reusable target): included.
  for (auto _ : state)
    r = o3r::RegistrationICP(src, tgt, p.max_corr, p.T_init.matrix(), o3r::TransformationEstimationPointToPlane(),
                             o3r::ICPConvergenceCriteria(kTolerance, kTolerance, kMaxIterations));
  Eigen::Isometry3d T;
  T.matrix() = r.transformation_;
  set_counters(state, p, -1, T);
}
#endif

}  // namespace

#define CAIRN_ICP_BENCH(fn) BENCHMARK(fn)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime()
CAIRN_ICP_BENCH(BM_Cairn_PointToPlane);
CAIRN_ICP_BENCH(BM_Cairn_PointToPlaneSerial);
CAIRN_ICP_BENCH(BM_Cairn_PointToPlaneWithTree);
CAIRN_ICP_BENCH(BM_Cairn_PointToPoint);
CAIRN_ICP_BENCH(BM_Cairn_PrepareTarget);
CAIRN_ICP_BENCH(BM_Pcl_PointToPoint);
CAIRN_ICP_BENCH(BM_Pcl_PointToPlane);
#ifdef CAIRN_BENCH_OPEN3D
CAIRN_ICP_BENCH(BM_Open3d_PointToPlane);
#endif
BENCHMARK_MAIN();
