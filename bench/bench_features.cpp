// Feature kernels of the segment-based registration (Sec. 4.4 steps 2-4): cairn vs PCL 1.13 on
// identical inputs in the same run.
//  - ISS: cairn::iss_keypoints vs pcl::ISSKeypoint3D (2 threads).
//  - SHOT: cairn::compute_shot vs pcl::SHOTEstimationOMP (2 threads), same keypoints and normals.
//  - Matching: cairn::match_descriptors vs pcl::KdTreeFLANN<pcl::SHOT352> (tree build + one
//    nearest-neighbour query per source descriptor, as PCL's correspondence-grouping tutorial).
//  - Grouping: cairn::geometric_consistency_grouping vs pcl::GeometricConsistencyGrouping, same
//    correspondences.
// Inputs:
//  - Site: the segment points of the simulated 7-stone site (default site, seed 1; 3 cm map,
//    Table 3 radii R_iss = 6 cm, R_shot = 10 cm). The "map" and the "drone" sets are two
//    independent samplings of the same site; matching/grouping run map -> drone.
//  - Milk: PCL's correspondence-grouping tutorial (real Kinect data): ISS on the model (12.5k
//    points, radii 12 / 8 mm), SHOT at the scene's uniform-sampling keypoints (3 cm) over the full
//    241k-point scene (descr_rad 2 cm), matching scene -> model, grouping cg_size 1 cm, cg_thresh 5.
// Normals for both (cairn's PCA normals) are computed outside the timed region.
#include <benchmark/benchmark.h>
#include <pcl/features/shot_omp.h>
#include <pcl/kdtree/kdtree_flann.h>
#include <pcl/point_types.h>
#include <pcl/recognition/cg/geometric_consistency.h>
#include <pcl/search/kdtree.h>

#include <cmath>
#include <limits>

#include "cairn/core/kdtree.hpp"
#include "cairn/core/normals.hpp"
#include "cairn/features/iss.hpp"
#include "cairn/features/matching.hpp"
#include "cairn/features/shot.hpp"
#include "cairn/registration/consistency_grouping.hpp"
#include "support/feature_data.hpp"
#include "support/site_segments.hpp"
#include "support/pcl_convert.hpp"
#include "support/pcl_iss.hpp"

using namespace cairn;

namespace {

using test::to_pcl;
using test::to_pcl_normals;

using CloudXYZ = pcl::PointCloud<pcl::PointXYZ>;
using Descriptors = pcl::PointCloud<pcl::SHOT352>;

/// One cloud prepared for both libraries.
struct Set {
  std::vector<Vec3f> points, normals, keypoints;
  std::unique_ptr<KdTree> tree;
  IssConfig iss;
  double shot_radius = 0.1;
  CloudXYZ::Ptr pcl_points, pcl_keypoints;
  pcl::PointCloud<pcl::Normal>::Ptr pcl_normals;
  ShotDescriptors desc;
  Descriptors::Ptr pcl_desc;

  void finish(bool iss_keypoints_as_keypoints) {
    tree = std::make_unique<KdTree>(points);
    if (iss_keypoints_as_keypoints) keypoints = test::gather(points, iss_keypoints(points, *tree, iss));
    pcl_points = to_pcl(points);
    pcl_keypoints = to_pcl(keypoints);
    pcl_normals = to_pcl_normals(normals);
    desc = compute_shot(keypoints, points, normals, *tree, {.radius = shot_radius});
  }
};

Set site_set(std::uint64_t sample_seed) {
  const auto s = test::site_segment_points(1, sample_seed);
  Set set;
  set.points = s.points;
  set.normals = s.normals;
  set.finish(true);
  return set;
}

const Set& site_map() {
  static const Set s = site_set(1);
  return s;
}
const Set& site_drone() {
  static const Set s = site_set(2);
  return s;
}

const Set& milk_model() {
  static const Set s = [] {
    Set set;
    set.points = test::load_real_points("pcl-correspondence-grouping/milk.pcd");
    const KdTree tree(set.points);
    set.normals = estimate_normals(set.points, tree, {.k = 10}).normals;
    set.keypoints = test::gather(set.points, test::uniform_sampling(set.points, 0.01f));
    set.iss = {.salient_radius = 0.012, .non_max_radius = 0.008};
    set.shot_radius = 0.02;
    set.finish(false);
    return set;
  }();
  return s;
}

const Set& milk_scene() {
  static const Set s = [] {
    Set set;
    set.points = test::load_real_points("pcl-correspondence-grouping/milk_cartoon_all_small_clorox.pcd");
    const KdTree tree(set.points);
    set.normals = estimate_normals(set.points, tree, {.k = 10}).normals;
    set.keypoints = test::gather(set.points, test::uniform_sampling(set.points, 0.03f));
    set.shot_radius = 0.02;
    set.finish(false);
    return set;
  }();
  return s;
}

const Set& set_of(int which) { return which == 0 ? site_map() : which == 1 ? milk_model() : milk_scene(); }

Descriptors::Ptr pcl_shot(const Set& s) {
  pcl::SHOTEstimationOMP<pcl::PointXYZ, pcl::Normal, pcl::SHOT352> est;
  est.setNumberOfThreads(2);
  est.setRadiusSearch(s.shot_radius);
  est.setInputCloud(s.pcl_keypoints);
  est.setInputNormals(s.pcl_normals);
  est.setSearchSurface(s.pcl_points);
  auto out = pcl::make_shared<Descriptors>();
  est.compute(*out);
  return out;
}

std::vector<Correspondence> pcl_match(const Descriptors::Ptr& source, const Descriptors::Ptr& target) {
  pcl::KdTreeFLANN<pcl::SHOT352> search;
  search.setInputCloud(target);
  std::vector<Correspondence> out;
  pcl::Indices idx(1);
  std::vector<float> d2(1);
  for (std::size_t i = 0; i < source->size(); ++i) {
    if (!std::isfinite(source->at(i).descriptor[0])) continue;
    if (search.nearestKSearch(source->at(i), 1, idx, d2) == 1 && d2[0] < 0.25f)
      out.push_back({std::uint32_t(i), std::uint32_t(idx[0]), d2[0]});
  }
  return out;
}

/// A matching problem: source/target sets and the correspondences (cairn's) for the grouping.
struct MatchProblem {
  const Set* source;
  const Set* target;
  GroupingConfig grouping;
  std::vector<Correspondence> matches;
  Descriptors::Ptr pcl_source, pcl_target;
};

const MatchProblem& problem(int which) {
  static const MatchProblem site = [] {
    MatchProblem p{&site_map(), &site_drone(), {}, {}, nullptr, nullptr};
    p.matches = match_descriptors(p.source->desc, p.target->desc, {});
    p.pcl_source = pcl_shot(*p.source);
    p.pcl_target = pcl_shot(*p.target);
    return p;
  }();
  static const MatchProblem milk = [] {
    MatchProblem p{&milk_scene(), &milk_model(), {.consensus_size = 0.01, .min_votes = 5}, {}, nullptr, nullptr};
    p.matches = match_descriptors(p.source->desc, p.target->desc, {});
    p.pcl_source = pcl_shot(*p.source);
    p.pcl_target = pcl_shot(*p.target);
    return p;
  }();
  return which == 0 ? site : milk;
}

// --- ISS -----------------------------------------------------------------------------------------

void BM_Cairn_Iss(benchmark::State& state) {
  const Set& s = set_of(int(state.range(0)));
  std::size_t n = 0;
  for (auto _ : state) {
    const KdTree tree(s.points);  // PCL builds its tree inside compute() too
    n = iss_keypoints(s.points, tree, s.iss).size();
  }
  state.counters["points"] = double(s.points.size());
  state.counters["keypoints"] = double(n);
}

void BM_Pcl_Iss(benchmark::State& state) {
  const Set& s = set_of(int(state.range(0)));
  std::size_t n = 0;
  for (auto _ : state) {
    test::PclIss iss;
    test::configure_pcl_iss(iss, s.iss);
    iss.setInputCloud(s.pcl_points);
    CloudXYZ out;
    iss.compute(out);
    n = out.size();
  }
  state.counters["points"] = double(s.points.size());
  state.counters["keypoints"] = double(n);
}

// --- SHOT ----------------------------------------------------------------------------------------

void BM_Cairn_Shot(benchmark::State& state) {
  const Set& s = set_of(int(state.range(0)));
  for (auto _ : state) {
    const KdTree tree(s.points);
    benchmark::DoNotOptimize(compute_shot(s.keypoints, s.points, s.normals, tree, {.radius = s.shot_radius}));
  }
  state.counters["keypoints"] = double(s.keypoints.size());
  state.counters["surface"] = double(s.points.size());
}

void BM_Pcl_ShotOMP(benchmark::State& state) {
  const Set& s = set_of(int(state.range(0)));
  for (auto _ : state) benchmark::DoNotOptimize(pcl_shot(s));
  state.counters["keypoints"] = double(s.keypoints.size());
  state.counters["surface"] = double(s.points.size());
}

// --- Matching and grouping -------------------------------------------------------------------------

void BM_Cairn_Match(benchmark::State& state) {
  const MatchProblem& p = problem(int(state.range(0)));
  std::size_t n = 0;
  for (auto _ : state) n = match_descriptors(p.source->desc, p.target->desc, {}).size();
  state.counters["source"] = double(p.source->desc.num_valid());
  state.counters["target"] = double(p.target->desc.num_valid());
  state.counters["matches"] = double(n);
}

void BM_Pcl_MatchKdTreeFLANN(benchmark::State& state) {
  const MatchProblem& p = problem(int(state.range(0)));
  std::size_t n = 0;
  for (auto _ : state) n = pcl_match(p.pcl_source, p.pcl_target).size();
  state.counters["matches"] = double(n);
}

void BM_Cairn_Grouping(benchmark::State& state) {
  const MatchProblem& p = problem(int(state.range(0)));
  std::size_t n = 0;
  for (auto _ : state)
    n = geometric_consistency_grouping(p.source->keypoints, p.target->keypoints, p.matches, p.grouping).size();
  state.counters["correspondences"] = double(p.matches.size());
  state.counters["candidates"] = double(n);
}

void BM_Pcl_GeometricConsistencyGrouping(benchmark::State& state) {
  const MatchProblem& p = problem(int(state.range(0)));
  auto corrs = pcl::make_shared<pcl::Correspondences>();
  for (const auto& c : p.matches) corrs->push_back(pcl::Correspondence(int(c.source), int(c.target), c.squared_distance));
  const auto src = to_pcl(p.source->keypoints), tgt = to_pcl(p.target->keypoints);
  std::size_t n = 0;
  for (auto _ : state) {
    pcl::GeometricConsistencyGrouping<pcl::PointXYZ, pcl::PointXYZ> gc;
    gc.setGCSize(p.grouping.consensus_size);
    gc.setGCThreshold(p.grouping.min_votes);
    gc.setInputCloud(src);
    gc.setSceneCloud(tgt);
    gc.setModelSceneCorrespondences(corrs);
    std::vector<Eigen::Matrix4f, Eigen::aligned_allocator<Eigen::Matrix4f>> T;
    std::vector<pcl::Correspondences> inst;
    gc.recognize(T, inst);
    n = T.size();
  }
  state.counters["correspondences"] = double(p.matches.size());
  state.counters["candidates"] = double(n);
}

/// Steps 2-4 on the site as the registration runs them: ISS + SHOT on both segment sets (kd-trees
/// included), matching, grouping. Segmentation, normals and ICP are not included.
void BM_Cairn_SiteSteps2to4(benchmark::State& state) {
  const Set& a = site_map();
  const Set& b = site_drone();
  for (auto _ : state) {
    const auto describe = [](const Set& s) {
      const KdTree tree(s.points);
      const auto kp = test::gather(s.points, iss_keypoints(s.points, tree, {}));
      return std::pair{kp, compute_shot(kp, s.points, s.normals, tree, {})};
    };
    const auto [kp_a, da] = describe(a);
    const auto [kp_b, db] = describe(b);
    const auto m = match_descriptors(da, db, {});
    benchmark::DoNotOptimize(geometric_consistency_grouping(kp_a, kp_b, m, {}));
  }
  state.counters["points"] = double(a.points.size() + b.points.size());
}

// Arg 0: site segments (Table 3 radii); 1: milk model (ISS) / milk scene (SHOT).
BENCHMARK(BM_Cairn_Iss)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Pcl_Iss)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Cairn_Shot)->Arg(0)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Pcl_ShotOMP)->Arg(0)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
// Arg 0: site map -> drone; 1: milk scene -> model (tutorial).
BENCHMARK(BM_Cairn_Match)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Pcl_MatchKdTreeFLANN)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Cairn_Grouping)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Pcl_GeometricConsistencyGrouping)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Cairn_SiteSteps2to4)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
