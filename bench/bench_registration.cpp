// Segment-based global registration (Sec. 4.4) end to end: cairn::register_global vs the same
// pipeline written with PCL 1.13 (and Open3D's FPFH + RANSAC when found), on the same input in the
// same run.
//
// Input (built once, as tests/registration_e2e/test_global_registration.cpp): the exp1 site,
// seed 1, simulated for 8 s with the drone; the LiDAR map from the mapping stage is the target,
// the drone's photogrammetry cloud after scale recovery (metric, arbitrary frame) the source.
// Truth: the simulator's T_map_drone composed with the inverse of the recovered scale. Errors
// (registration_error) are measured at the site centre = the mean of the target's object-segment
// points.
//
// - BM_Cairn_RegisterGlobal: register_global(source, target, {}, {}) with its own stage timings
//   (segmentation_source includes the source voxel grid and the levelling).
// - BM_Cairn_GroupsOnly: the same with registration.centroid_hypotheses = false: candidates from
//   the consistency groups only, as in the PCL pipeline (cairn still keeps b = 30, refines up to
//   5 candidates and judges them by its overlap test).
// - BM_Pcl_Pipeline (the paper's Sec. 4.4 pipeline written with PCL): cairn's segmentations are
//   shared (from one register_global run outside the timed region; PCL segmentation numbers:
//   bench_segmentation). On the object-segment points of the voxelised source and of the target:
//     keypoints   pcl::ISSKeypoint3D (cairn's IssConfig: 6 / 4 cm, gamma 0.975, 5 neighbours, 2 threads)
//     normals     pcl::NormalEstimationOMP (r = 0.1, 2 threads), oriented away from the segment's
//                 centroid as cairn does (SHOT's histogram depends on the normal's sign)
//     descriptors pcl::SHOTEstimationOMP (r = 0.1, 2 threads)
//     matching    pcl::KdTreeFLANN<pcl::SHOT352> over the target descriptors, nearest neighbour of
//                 each source descriptor, kept when the squared distance < 0.25 (cairn's MatchConfig)
//     grouping    pcl::GeometricConsistencyGrouping (consensus 0.1, threshold 3); the b = 30
//                 groups with the most correspondences (cairn's GroupingConfig::max_candidates)
//     verification cairn::match_centroids (PCL has no such step): most centroid inliers within
//                 d_match = 1 m wins, ties to the smaller largest distance; at least 3 (cairn's
//                 min_matched_segments) or no result
//     icp         pcl::IterativeClosestPoint on the matched segments' points from the
//                 best-verified group's transform, two passes as cairn (correspondence distance
//                 0.4, then 0.15; 40 iterations each)
//   Success: the final transform within 2° and 10 cm of the truth (no acceptance test of its own).
// - BM_Open3d_FpfhRansac (when Open3D is found): on the same object-segment points: voxel grid
//   0.05 per segment, normals (r = 0.1, max 30 nn, oriented as above), FPFH (r = 0.25, max 100 nn),
//   RegistrationRANSACBasedOnFeatureMatching (mutual filter, 0.075 m, edge-length 0.9 + distance
//   checkers, 100000 iterations / 0.999), then point-to-plane ICP on the full-resolution object
//   points (0.4 then 0.15 m, 40 iterations each). Success as for PCL.
// Every benchmark reports: ms_<stage>, ms_total (without segmentation), success, correct (within
// 2° / 10 cm of the truth), rotation_deg, translation_m, points (source + target object points; for
// cairn the input clouds). Diagnostics: cairn's accepted_from_centroids (1: the accepted alignment
// came from the centroid-pair hypotheses, not from a consistency group), PCL's
// clusters_near_truth (groups within 10° / 1 m of the truth), clusters_near_truth_in_b (those among
// the b verified), near_truth_centroid_inliers (the most centroid inliers one of those got),
// failed_refits (clusters whose RANSAC refit failed: identity transform, left out) and
// icp_from_truth_ms (the same ICP started at the truth, on the segments matched there; not part
// of ms_total).
// Scripts: scripts/bench_registration.sh prints the comparison table.
#include <benchmark/benchmark.h>
#include <pcl/console/print.h>
#include <pcl/correspondence.h>
#include <pcl/features/normal_3d_omp.h>
#include <pcl/features/shot_omp.h>
#include <pcl/kdtree/kdtree_flann.h>
#include <pcl/point_types.h>
#include <pcl/recognition/cg/geometric_consistency.h>
#include <pcl/registration/icp.h>
#include <pcl/search/kdtree.h>

#ifdef CAIRN_BENCH_OPEN3D
#include <open3d/geometry/KDTreeSearchParam.h>
#include <open3d/geometry/PointCloud.h>
#include <open3d/pipelines/registration/CorrespondenceChecker.h>
#include <open3d/pipelines/registration/Feature.h>
#include <open3d/pipelines/registration/Registration.h>
#include <open3d/pipelines/registration/TransformationEstimation.h>
#include <open3d/utility/Random.h>
#endif

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <numeric>
#include <string>
#include <vector>

#include "cairn/core/io/io.hpp"
#include "cairn/core/io/run_dir.hpp"
#include "cairn/core/log.hpp"
#include "cairn/mapping/mapper.hpp"
#include "cairn/registration/global_registration.hpp"
#include "cairn/registration/scale_recovery.hpp"
#include "cairn/sim/simulation.hpp"
#include "support/pcl_convert.hpp"
#include "support/pcl_iss.hpp"

using namespace cairn;

namespace {

using test::to_pcl;

namespace fs = std::filesystem;

constexpr double kMaxRotationDeg = 2.0;     // "correct": within this of the truth ...
constexpr double kMaxTranslationM = 0.10;   // ... and this at the site centre
constexpr double kCoarseCorrespondence = 0.4;  // cairn's coarse_correspondence_distance
constexpr double kFineCorrespondence = 0.15;   // cairn's icp.max_correspondence_distance
constexpr int kIcpIterations = 40;             // cairn's icp.max_iterations

/// Object-segment points of one cloud (local coordinates of the cloud), with the segment of each.
struct Objects {
  std::vector<Vec3f> points;
  std::vector<std::int32_t> segment_of;  // index into centroids
  std::vector<Vec3f> centroids;
  Vec3d origin = Vec3d::Zero();
};

Objects object_points(const PointCloud& cloud, const SegmentationResult& seg) {
  Objects o;
  o.origin = cloud.origin;
  for (const Segment& g : seg.segments) {
    if (g.planar) continue;  // as register_global: planar segments are not objects
    const auto k = std::int32_t(o.centroids.size());
    Vec3d c = Vec3d::Zero();
    for (std::uint32_t i : g.indices) {
      o.points.push_back(cloud.points[i]);
      o.segment_of.push_back(k);
      c += cloud.points[i].cast<double>();
    }
    o.centroids.push_back((c / double(std::max<std::size_t>(1, g.indices.size()))).cast<float>());
  }
  return o;
}

struct Fixture {
  fs::path dir;
  PointCloud source, target;
  Similarity truth;  // T_target_source (world frames)
  GlobalRegistrationResult reference;  // one register_global run: the shared segmentations
  Objects source_objects, target_objects;  // from reference's segmentations
  Vec3d site_centre = Vec3d::Zero();     // world
};

const Fixture& fixture() {
  static const Fixture f = [] {
    Fixture x;
    x.dir = fs::temp_directory_path() / ("cairn_bench_registration_" + std::to_string(::getpid()));
    std::error_code ec;
    fs::remove_all(x.dir, ec);
    fs::create_directories(x.dir);
    std::atexit([] {
      std::error_code ignored;
      fs::remove_all(fs::temp_directory_path() / ("cairn_bench_registration_" + std::to_string(::getpid())), ignored);
    });
    const fs::path run = x.dir / "run";
    sim::SimulationConfig cfg = sim::scenario_config("exp1", sim::default_real_mesh_dir());
    cfg.with_scan_truth = false;
    (void)sim::simulate_run("exp1", cfg, 1, 8.0, run, true);
    const io::RunDirectory rd = io::open_run_directory(run);
    x.target = map_run(rd, {}).map;
    const PointCloud drone_sfm = io::load_cloud(run / "drone" / "cloud.ply");
    std::ifstream in(run / "truth" / "drone.json");
    const Similarity T_map_sfm =
        Similarity::from_matrix(matrix_from_json(nlohmann::json::parse(in)["T_map_drone"]));
    const ScaleRecoveryResult s = recover_scale(io::read_colmap_text(run / "drone" / "sparse"),
                                                io::read_tum_trajectory(run / "drone" / "vins_trajectory.tum"));
    x.source = drone_sfm;
    transform_cloud(x.source, s.T_metric_sfm);
    x.truth = T_map_sfm * s.T_metric_sfm.inverse();
    x.reference = register_global(x.source, x.target, {}, {});
    x.source_objects = object_points(x.reference.source_voxelised, x.reference.source_segmentation);
    x.target_objects = object_points(x.target, x.reference.target_segmentation);
    Vec3d c = Vec3d::Zero();
    for (const Vec3f& p : x.target_objects.points) c += p.cast<double>();
    x.site_centre = x.target.origin + c / double(std::max<std::size_t>(1, x.target_objects.points.size()));
    return x;
  }();
  return f;
}

/// A transform between the two clouds' local coordinates → between their world frames.
Eigen::Isometry3d local_to_world(const Eigen::Isometry3d& T_local, const Fixture& f) {
  return Eigen::Translation3d(f.target_objects.origin) * T_local *
         Eigen::Translation3d(-f.source_objects.origin);
}

void report_errors(benchmark::State& state, const Fixture& f, const Eigen::Isometry3d& T_world, bool success) {
  const RegistrationError e = registration_error(Similarity::from_isometry(T_world), f.truth, f.site_centre);
  state.counters["success"] = success ? 1.0 : 0.0;
  state.counters["correct"] = (e.rotation_deg < kMaxRotationDeg && e.translation_m < kMaxTranslationM) ? 1.0 : 0.0;
  state.counters["rotation_deg"] = e.rotation_deg;
  state.counters["translation_m"] = e.translation_m;
}

/// Mean per iteration of named stage times, into ms_<stage> counters (and ms_total over `total_of`).
struct StageClock {
  std::map<std::string, double> sum;
  std::vector<std::string> order;
  int iterations = 0;
  void add(const std::string& stage, double ms) {
    if (!sum.count(stage)) order.push_back(stage);
    sum[stage] += ms;
  }
  void report(benchmark::State& state, const std::vector<std::string>& excluded_from_total) const {
    double total = 0.0;
    for (const std::string& s : order) {
      const double ms = sum.at(s) / std::max(1, iterations);
      state.counters["ms_" + s] = ms;
      if (std::find(excluded_from_total.begin(), excluded_from_total.end(), s) == excluded_from_total.end()) total += ms;
    }
    state.counters["ms_total"] = total;
  }
};

// --- cairn -----------------------------------------------------------------------------------------

void run_cairn(benchmark::State& state, const GlobalRegistrationConfig& cfg) {
  const Fixture& f = fixture();
  StageClock clock;
  GlobalRegistrationResult r;
  for (auto _ : state) {
    r = register_global(f.source, f.target, {}, cfg);
    for (const auto& [stage, ms] : r.timings.stages) clock.add(stage, ms);
    ++clock.iterations;
  }
  clock.report(state, {"segmentation_source", "segmentation_target"});
  report_errors(state, f, r.T_target_source, r.success);
  state.counters["points"] = double(f.source.size() + f.target.size());
  state.counters["object_points"] = double(f.source_objects.points.size() + f.target_objects.points.size());
  state.counters["keypoints"] = double(r.source_keypoints + r.target_keypoints);
  state.counters["correspondences"] = double(r.correspondences);
  state.counters["matched_segments"] = double(r.matched_segments.size());
  state.counters["candidates"] = double(r.candidates);
  for (const CandidateReport& c : r.reports)  // where the accepted alignment came from
    if (c.accepted) state.counters["accepted_from_centroids"] = c.origin == "centroids" ? 1.0 : 0.0;
}

void BM_Cairn_RegisterGlobal(benchmark::State& state) { run_cairn(state, {}); }

/// Candidates from the consistency groups only, as in the PCL pipeline: no centroid-pair hypotheses.
void BM_Cairn_GroupsOnly(benchmark::State& state) {
  GlobalRegistrationConfig cfg;
  cfg.centroid_hypotheses = false;
  run_cairn(state, cfg);
}

/// The n points of `cloud` nearest (in x, y) to the world point `centre`: a smaller site around
/// the same stones.
PointCloud crop_nearest(const PointCloud& cloud, const Vec3d& centre, std::size_t n) {
  const Eigen::Vector2f c = (centre - cloud.origin).head<2>().cast<float>();
  std::vector<std::pair<float, std::uint32_t>> d;
  d.reserve(cloud.size());
  for (std::uint32_t i = 0; i < cloud.size(); ++i) d.emplace_back((cloud.points[i].head<2>() - c).squaredNorm(), i);
  n = std::min(n, d.size());
  std::nth_element(d.begin(), d.begin() + std::ptrdiff_t(n), d.end());
  std::vector<std::uint32_t> keep;
  for (std::size_t k = 0; k < n; ++k) keep.push_back(d[k].second);
  std::sort(keep.begin(), keep.end());  // input order
  PointCloud out;
  out.origin = cloud.origin;
  for (std::uint32_t i : keep) out.points.push_back(cloud.points[i]);
  return out;
}

/// The size: ~100k source + ~100k target points as the pipeline sees them (the source
/// after its voxel grid, the map as it is), both cropped to the points nearest the site centre;
/// every stage timed including both segmentations (ms_all).
void BM_Cairn_RegisterGlobal_100k(benchmark::State& state) {
  const Fixture& f = fixture();
  const std::size_t n = std::size_t(state.range(0));
  const Vec3d centre_source = f.truth.inverse() * f.site_centre;  // the same place in the drone's frame
  const GlobalRegistrationConfig defaults;
  const PointCloud source = crop_nearest(voxel_downsample(f.source, defaults.source_voxel), centre_source, n);
  const PointCloud target = crop_nearest(f.target, f.site_centre, n);
  StageClock clock;
  GlobalRegistrationResult r;
  for (auto _ : state) {
    r = register_global(source, target, {}, {});
    for (const auto& [stage, ms] : r.timings.stages) clock.add(stage, ms);
    ++clock.iterations;
  }
  clock.report(state, {"segmentation_source", "segmentation_target"});
  state.counters["ms_all"] = r.timings.total();  // last iteration, segmentations included
  report_errors(state, f, r.T_target_source, r.success);
  state.counters["points"] = double(source.size() + target.size());
  state.counters["source_points_after_voxel_grid"] = double(r.source_points);
  state.counters["target_points"] = double(r.target_points);
  state.counters["matched_segments"] = double(r.matched_segments.size());
}
BENCHMARK(BM_Cairn_RegisterGlobal_100k)->Arg(100000)->Iterations(5)->Unit(benchmark::kMillisecond)->UseRealTime();

// --- PCL -------------------------------------------------------------------------------------------

using CloudXYZ = pcl::PointCloud<pcl::PointXYZ>;
using Normals = pcl::PointCloud<pcl::Normal>;
using Descriptors = pcl::PointCloud<pcl::SHOT352>;

CloudXYZ::Ptr pcl_iss(const CloudXYZ::Ptr& cloud, const IssConfig& iss) {
  test::PclIss est;
  test::configure_pcl_iss(est, iss);
  est.setInputCloud(cloud);
  auto out = pcl::make_shared<CloudXYZ>();
  est.compute(*out);
  return out;
}

Normals::Ptr pcl_normals(const CloudXYZ::Ptr& cloud, const Objects& o, double radius) {
  pcl::NormalEstimationOMP<pcl::PointXYZ, pcl::Normal> est;
  est.setNumberOfThreads(2);
  est.setSearchMethod(pcl::make_shared<pcl::search::KdTree<pcl::PointXYZ>>());
  est.setRadiusSearch(radius);
  est.setInputCloud(cloud);
  auto out = pcl::make_shared<Normals>();
  est.compute(*out);
  for (std::size_t i = 0; i < out->size(); ++i) {  // outward, as register_global
    pcl::Normal& n = (*out)[i];
    const Vec3f away = o.points[i] - o.centroids[std::size_t(o.segment_of[i])];
    if (std::isfinite(n.normal_x) && n.getNormalVector3fMap().dot(away) < 0.0f)
      n.getNormalVector3fMap() = -n.getNormalVector3fMap();
  }
  return out;
}

Descriptors::Ptr pcl_shot(const CloudXYZ::Ptr& keypoints, const CloudXYZ::Ptr& surface, const Normals::Ptr& normals,
                          double radius) {
  pcl::SHOTEstimationOMP<pcl::PointXYZ, pcl::Normal, pcl::SHOT352> est;
  est.setNumberOfThreads(2);
  est.setRadiusSearch(radius);
  est.setInputCloud(keypoints);
  est.setInputNormals(normals);
  est.setSearchSurface(surface);
  auto out = pcl::make_shared<Descriptors>();
  est.compute(*out);
  return out;
}

pcl::CorrespondencesPtr pcl_match(const Descriptors::Ptr& source, const Descriptors::Ptr& target,
                                  double max_squared_distance) {
  pcl::KdTreeFLANN<pcl::SHOT352> search;
  search.setInputCloud(target);
  auto out = pcl::make_shared<pcl::Correspondences>();
  pcl::Indices idx(1);
  std::vector<float> d2(1);
  for (std::size_t i = 0; i < source->size(); ++i) {
    if (!std::isfinite(source->at(i).descriptor[0])) continue;
    if (search.nearestKSearch(source->at(i), 1, idx, d2) == 1 && d2[0] < float(max_squared_distance))
      out->push_back(pcl::Correspondence(int(i), idx[0], d2[0]));
  }
  return out;
}

/// The points of the segments matched by `m` (its source side or target side).
CloudXYZ::Ptr matched_points(const Objects& o, const CentroidMatch& m, bool source_side) {
  std::vector<char> in(o.centroids.size(), 0);
  for (const auto& [a, b] : m.pairs) in[std::size_t(source_side ? a : b)] = 1;
  std::vector<Vec3f> out;
  for (std::size_t i = 0; i < o.points.size(); ++i)
    if (in[std::size_t(o.segment_of[i])]) out.push_back(o.points[i]);
  return to_pcl(out);
}

template <class T>
struct PclIcpAccess : T {  // nr_iterations_ is protected; expose it for the counter
  using T::nr_iterations_;
};

Eigen::Matrix4f pcl_icp(const CloudXYZ::Ptr& source, const CloudXYZ::Ptr& target, const Eigen::Matrix4f& guess,
                        int& iterations) {
  PclIcpAccess<pcl::IterativeClosestPoint<pcl::PointXYZ, pcl::PointXYZ>> icp;
  icp.setInputSource(source);
  icp.setInputTarget(target);
  icp.setMaximumIterations(kIcpIterations);
  icp.setTransformationEpsilon(1e-8);  // cairn: increments below 1e-4 m / 1e-4 rad
  icp.setTransformationRotationEpsilon(std::cos(1e-4));
  CloudXYZ out;
  Eigen::Matrix4f T = guess;
  iterations = 0;
  for (const double d : {kCoarseCorrespondence, kFineCorrespondence}) {
    icp.setMaxCorrespondenceDistance(d);
    icp.align(out, T);
    T = icp.getFinalTransformation();
    iterations += icp.nr_iterations_;
  }
  return T;
}

void BM_Pcl_Pipeline(benchmark::State& state) {
  const Fixture& f = fixture();
  const GlobalRegistrationConfig gcfg;
  const CloudXYZ::Ptr src = to_pcl(f.source_objects.points), tgt = to_pcl(f.target_objects.points);
  StageClock clock;
  Eigen::Matrix4f T = Eigen::Matrix4f::Identity();
  bool found = false;
  std::size_t keypoints = 0, correspondences = 0, best_votes = 0, clusters = 0, failed_refits = 0;
  int icp_iterations = 0, matched_segments = 0;
  std::vector<std::size_t> top_b;  // the b most-voted groups (indices into transforms)
  std::vector<Eigen::Matrix4f, Eigen::aligned_allocator<Eigen::Matrix4f>> transforms;
  // GeometricConsistencyGrouping's RANSAC refit prints an error for every cluster it cannot refit.
  const pcl::console::VERBOSITY_LEVEL verbosity = pcl::console::getVerbosityLevel();
  pcl::console::setVerbosityLevel(pcl::console::L_ALWAYS);
  for (auto _ : state) {
    Stopwatch sw;
    const CloudXYZ::Ptr kp_s = pcl_iss(src, gcfg.iss), kp_t = pcl_iss(tgt, gcfg.iss);
    clock.add("keypoints", sw.lap_ms());
    const Normals::Ptr n_s = pcl_normals(src, f.source_objects, gcfg.normals.radius);
    const Normals::Ptr n_t = pcl_normals(tgt, f.target_objects, gcfg.normals.radius);
    clock.add("normals", sw.lap_ms());
    const Descriptors::Ptr d_s = pcl_shot(kp_s, src, n_s, gcfg.shot.radius);
    const Descriptors::Ptr d_t = pcl_shot(kp_t, tgt, n_t, gcfg.shot.radius);
    clock.add("descriptors", sw.lap_ms());
    const pcl::CorrespondencesPtr corrs = pcl_match(d_s, d_t, gcfg.matching.max_squared_distance);
    clock.add("matching", sw.lap_ms());
    pcl::GeometricConsistencyGrouping<pcl::PointXYZ, pcl::PointXYZ> gc;
    gc.setGCSize(gcfg.grouping.consensus_size);
    gc.setGCThreshold(gcfg.grouping.min_votes);
    gc.setInputCloud(kp_s);  // model = source: transforms are T_target_source
    gc.setSceneCloud(kp_t);
    gc.setModelSceneCorrespondences(corrs);
    transforms.clear();
    std::vector<pcl::Correspondences> grouped;
    gc.recognize(transforms, grouped);
    // A cluster whose RANSAC refit fails comes back from PCL with an identity transform and all
    // its correspondences (CorrespondenceRejectorSampleConsensus); cairn's grouping drops a
    // cluster it cannot fit, so these are left out here too. Of the rest, the b most-voted
    // (stable: PCL's order among equal votes), each verified by the segment centroids; most
    // inliers wins, ties to the smaller largest distance (Sec. 4.4).
    std::vector<std::size_t>& order = top_b;
    order.clear();
    failed_refits = 0;
    for (std::size_t k = 0; k < grouped.size(); ++k) {
      if (transforms[k].isIdentity(0.0f))
        ++failed_refits;
      else
        order.push_back(k);
    }
    std::stable_sort(order.begin(), order.end(),
                     [&](std::size_t a, std::size_t b) { return grouped[a].size() > grouped[b].size(); });
    order.resize(std::min(order.size(), std::size_t(gcfg.grouping.max_candidates)));
    clock.add("grouping", sw.lap_ms());
    constexpr std::size_t kNone = std::numeric_limits<std::size_t>::max();
    std::size_t best = kNone;
    CentroidMatch best_match;
    for (std::size_t k : order) {
      Eigen::Isometry3d Tk;
      Tk.matrix() = transforms[k].cast<double>();
      const CentroidMatch m =
          match_centroids(f.source_objects.centroids, f.target_objects.centroids, Tk, gcfg.d_match);
      if (best == kNone || m.inliers > best_match.inliers ||
          (m.inliers == best_match.inliers && m.max_distance < best_match.max_distance)) {
        best = k;
        best_match = m;
      }
    }
    found = best != kNone && best_match.inliers >= gcfg.acceptance.min_matched_segments;
    clock.add("verification", sw.lap_ms());
    icp_iterations = 0;
    matched_segments = 0;
    T = Eigen::Matrix4f::Identity();
    if (found) {  // ICP on the matched segments only
      T = pcl_icp(matched_points(f.source_objects, best_match, true),
                  matched_points(f.target_objects, best_match, false), transforms[best], icp_iterations);
      matched_segments = best_match.inliers;
    }
    clock.add("icp", sw.lap_ms());
    ++clock.iterations;
    keypoints = kp_s->size() + kp_t->size();
    correspondences = corrs->size();
    best_votes = found ? grouped[best].size() : 0;
    clusters = grouped.size();
  }
  pcl::console::setVerbosityLevel(verbosity);
  clock.report(state, {});
  // Diagnostic (untimed): clusters whose transform is near the truth (within 10 deg / 1 m), i.e.
  // whether the right alignment was among the candidates the most-voted rule chose from.
  // Also how many of them were among the b verified, and the best centroid inliers they got.
  std::size_t near_truth = 0, near_truth_in_b = 0;
  int near_truth_inliers = 0;
  for (std::size_t k = 0; k < transforms.size(); ++k) {
    Eigen::Isometry3d Tl;
    Tl.matrix() = transforms[k].cast<double>();
    Tl.linear() = Eigen::Quaterniond(Tl.linear()).normalized().toRotationMatrix();
    const RegistrationError ec =
        registration_error(Similarity::from_isometry(local_to_world(Tl, f)), f.truth, f.site_centre);
    if (ec.rotation_deg >= 10.0 || ec.translation_m >= 1.0) continue;
    ++near_truth;
    if (std::find(top_b.begin(), top_b.end(), k) == top_b.end()) continue;
    ++near_truth_in_b;
    near_truth_inliers = std::max(
        near_truth_inliers,
        match_centroids(f.source_objects.centroids, f.target_objects.centroids, Tl, gcfg.d_match).inliers);
  }
  state.counters["clusters_near_truth"] = double(near_truth);
  state.counters["clusters_near_truth_in_b"] = double(near_truth_in_b);
  state.counters["near_truth_centroid_inliers"] = double(near_truth_inliers);
  // Diagnostic (untimed in ms_total): the same ICP from the true transform on the segments matched
  // there, i.e. its cost when it starts in the right basin.
  {
    Eigen::Isometry3d T_true = Eigen::Isometry3d::Identity();
    T_true.linear() = f.truth.rotation;
    T_true.translation() = f.truth.translation;
    const Eigen::Isometry3d T_true_local = Eigen::Translation3d(-f.target_objects.origin) * T_true *
                                           Eigen::Translation3d(f.source_objects.origin);
    const CentroidMatch m =
        match_centroids(f.source_objects.centroids, f.target_objects.centroids, T_true_local, gcfg.d_match);
    const CloudXYZ::Ptr ms = matched_points(f.source_objects, m, true), mt = matched_points(f.target_objects, m, false);
    int it = 0;
    Stopwatch sw;
    (void)pcl_icp(ms, mt, T_true_local.matrix().cast<float>(), it);
    state.counters["icp_from_truth_ms"] = sw.lap_ms();
    state.counters["icp_from_truth_iterations"] = it;
  }
  state.counters["icp_iterations"] = icp_iterations;
  Eigen::Isometry3d T_local;
  T_local.matrix() = T.cast<double>();
  T_local.linear() = Eigen::Quaterniond(T_local.linear()).normalized().toRotationMatrix();  // float round-off
  const Eigen::Isometry3d T_world = local_to_world(T_local, f);
  const RegistrationError e = registration_error(Similarity::from_isometry(T_world), f.truth, f.site_centre);
  report_errors(state, f, T_world, found && e.rotation_deg < kMaxRotationDeg && e.translation_m < kMaxTranslationM);
  state.counters["points"] = double(src->size() + tgt->size());
  state.counters["keypoints"] = double(keypoints);
  state.counters["correspondences"] = double(correspondences);
  state.counters["clusters"] = double(clusters);
  state.counters["failed_refits"] = double(failed_refits);
  state.counters["matched_segments"] = double(matched_segments);
  state.counters["best_cluster"] = double(best_votes);
}

// --- Open3D ----------------------------------------------------------------------------------------

#ifdef CAIRN_BENCH_OPEN3D
namespace o3g = open3d::geometry;
namespace o3r = open3d::pipelines::registration;

constexpr double kO3dVoxel = 0.05;
constexpr double kO3dNormalRadius = 0.1;
constexpr double kO3dFpfhRadius = 0.25;

/// Normals oriented away from the centroid of the nearest segment point's segment (cairn's rule;
/// the voxelised clouds lost the membership, so each segment is voxelised on its own).
void orient_outward(o3g::PointCloud& c, const std::vector<Eigen::Vector3d>& centroid_of_point) {
  for (std::size_t i = 0; i < c.points_.size(); ++i)
    if (c.normals_[i].dot(c.points_[i] - centroid_of_point[i]) < 0.0) c.normals_[i] = -c.normals_[i];
}

struct O3dSet {
  o3g::PointCloud full;                      // all object points (double)
  std::vector<Eigen::Vector3d> full_centroid;
  std::vector<o3g::PointCloud> segments;     // per segment, for the per-segment voxel grid
  std::vector<Eigen::Vector3d> centroids;
};

O3dSet o3d_set(const Objects& o) {
  O3dSet s;
  s.segments.resize(o.centroids.size());
  for (const Vec3f& c : o.centroids) s.centroids.push_back(c.cast<double>());
  for (std::size_t i = 0; i < o.points.size(); ++i) {
    const Eigen::Vector3d p = o.points[i].cast<double>();
    s.full.points_.push_back(p);
    s.full_centroid.push_back(s.centroids[std::size_t(o.segment_of[i])]);
    s.segments[std::size_t(o.segment_of[i])].points_.push_back(p);
  }
  return s;
}

/// Voxelised (per segment) cloud with oriented normals.
o3g::PointCloud o3d_downsample(const O3dSet& s, std::vector<Eigen::Vector3d>& centroid_of_point) {
  o3g::PointCloud out;
  centroid_of_point.clear();
  for (std::size_t k = 0; k < s.segments.size(); ++k) {
    const auto d = s.segments[k].VoxelDownSample(kO3dVoxel);
    out.points_.insert(out.points_.end(), d->points_.begin(), d->points_.end());
    centroid_of_point.insert(centroid_of_point.end(), d->points_.size(), s.centroids[k]);
  }
  return out;
}

void BM_Open3d_FpfhRansac(benchmark::State& state) {
  const Fixture& f = fixture();
  const O3dSet src = o3d_set(f.source_objects), tgt = o3d_set(f.target_objects);
  StageClock clock;
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  std::size_t ransac_inliers = 0, down_points = 0;
  double ransac_fitness = 0.0;
  for (auto _ : state) {
    open3d::utility::random::Seed(1);
    Stopwatch sw;
    std::vector<Eigen::Vector3d> cs, ct;
    o3g::PointCloud ds = o3d_downsample(src, cs), dt = o3d_downsample(tgt, ct);
    clock.add("voxel", sw.lap_ms());
    ds.EstimateNormals(o3g::KDTreeSearchParamHybrid(kO3dNormalRadius, 30));
    dt.EstimateNormals(o3g::KDTreeSearchParamHybrid(kO3dNormalRadius, 30));
    orient_outward(ds, cs);
    orient_outward(dt, ct);
    clock.add("normals", sw.lap_ms());
    const auto feat_s = o3r::ComputeFPFHFeature(ds, o3g::KDTreeSearchParamHybrid(kO3dFpfhRadius, 100));
    const auto feat_t = o3r::ComputeFPFHFeature(dt, o3g::KDTreeSearchParamHybrid(kO3dFpfhRadius, 100));
    clock.add("descriptors", sw.lap_ms());
    const double dist = 1.5 * kO3dVoxel;
    const o3r::CorrespondenceCheckerBasedOnEdgeLength edge(0.9);
    const o3r::CorrespondenceCheckerBasedOnDistance near_check(dist);
    const o3r::RegistrationResult coarse = o3r::RegistrationRANSACBasedOnFeatureMatching(
        ds, dt, *feat_s, *feat_t, true, dist, o3r::TransformationEstimationPointToPoint(false), 3, {edge, near_check},
        o3r::RANSACConvergenceCriteria(100000, 0.999));
    clock.add("ransac", sw.lap_ms());
    o3g::PointCloud target_full = tgt.full;  // ICP target with normals at full resolution
    target_full.EstimateNormals(o3g::KDTreeSearchParamHybrid(kO3dNormalRadius, 30));
    orient_outward(target_full, tgt.full_centroid);
    Eigen::Matrix4d Ti = coarse.transformation_;
    for (const double d : {kCoarseCorrespondence, kFineCorrespondence})
      Ti = o3r::RegistrationICP(src.full, target_full, d, Ti, o3r::TransformationEstimationPointToPlane(),
                                o3r::ICPConvergenceCriteria(1e-6, 1e-6, kIcpIterations))
               .transformation_;
    clock.add("icp", sw.lap_ms());
    ++clock.iterations;
    T = Ti;
    ransac_inliers = coarse.correspondence_set_.size();
    ransac_fitness = coarse.fitness_;
    down_points = ds.points_.size() + dt.points_.size();
  }
  clock.report(state, {});
  Eigen::Isometry3d T_local;
  T_local.matrix() = T;
  const Eigen::Isometry3d T_world = local_to_world(T_local, f);
  const RegistrationError e = registration_error(Similarity::from_isometry(T_world), f.truth, f.site_centre);
  report_errors(state, f, T_world, e.rotation_deg < kMaxRotationDeg && e.translation_m < kMaxTranslationM);
  state.counters["points"] = double(src.full.points_.size() + tgt.full.points_.size());
  state.counters["voxelised_points"] = double(down_points);
  state.counters["ransac_inliers"] = double(ransac_inliers);
  state.counters["ransac_fitness"] = ransac_fitness;
}
#endif

}  // namespace

BENCHMARK(BM_Cairn_RegisterGlobal)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(3);
BENCHMARK(BM_Cairn_GroupsOnly)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(3);
BENCHMARK(BM_Pcl_Pipeline)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(1);
#ifdef CAIRN_BENCH_OPEN3D
BENCHMARK(BM_Open3d_FpfhRansac)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(1);
#endif
BENCHMARK_MAIN();
