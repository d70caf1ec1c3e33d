// Segmentation of a ~100k-point stone-site map: cairn vs the same steps written with PCL
// (SACSegmentation + EuclideanClusterExtraction + per-cluster planarity RANSAC), same input,
// same run. Kernels (voxel grid, clustering, normals) are compared too.
#include <benchmark/benchmark.h>
#include <pcl/features/normal_3d_omp.h>
#include <pcl/filters/extract_indices.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/point_types.h>
#include <pcl/sample_consensus/method_types.h>
#include <pcl/sample_consensus/model_types.h>
#include <pcl/search/kdtree.h>
#include <pcl/segmentation/extract_clusters.h>
#include <pcl/segmentation/sac_segmentation.h>

#include "cairn/core/normals.hpp"
#include "cairn/core/voxel_grid.hpp"
#include "cairn/segmentation/segmenter.hpp"
#include "cairn/sim/procedural_site.hpp"
#include "cairn/sim/simulation.hpp"

using namespace cairn;

namespace {

/// The map as the mapping stage delivers it: a 7-stone site sampled at ~3 cm, voxelised at
/// res_voxel = 3 cm (Table 3).
const PointCloud& site_map() {
  static const PointCloud map = [] {
    const sim::Site site = sim::generate_site({}, 1);
    PointCloud c = sim::sample_site(site, {}, 1).cloud;
    return voxel_downsample(c, {});
  }();
  return map;
}

pcl::PointCloud<pcl::PointXYZ>::Ptr pcl_map() {
  static const auto cloud = [] {
    auto c = pcl::make_shared<pcl::PointCloud<pcl::PointXYZ>>();
    for (const auto& p : site_map().points) c->push_back({p.x(), p.y(), p.z()});
    return c;
  }();
  return cloud;
}

void set_counters(benchmark::State& state) { state.counters["points"] = double(site_map().size()); }

void BM_Cairn_Segment(benchmark::State& state) {
  for (auto _ : state) benchmark::DoNotOptimize(segment(site_map(), {}));
  set_counters(state);
}

/// A pile of six touching stones (the simulator's pile scenario, seed 1, on a 12 m site), the
/// same sampling and voxelisation: the splitting of touching stones at work.
const PointCloud& pile_map() {
  static const PointCloud map = [] {
    sim::SimulationConfig c = sim::scenario_config("pile", sim::default_real_mesh_dir());
    c.site.terrain.size_x = c.site.terrain.size_y = 12.0;
    PointCloud cloud = sim::sample_site(sim::make_site(c, 1), {}, 1).cloud;  // settled, as every scenario
    return voxel_downsample(cloud, {});
  }();
  return map;
}

void segment_split(benchmark::State& state, const PointCloud& map, bool split) {
  SegmentationConfig cfg;
  cfg.split.enabled = split;
  for (auto _ : state) benchmark::DoNotOptimize(segment(map, cfg));
  state.counters["points"] = double(map.size());
}

// The splitting's cost: segment with and without it, on the spread site and on a pile.
void BM_Cairn_SegmentNoSplit(benchmark::State& state) { segment_split(state, site_map(), false); }
void BM_Cairn_SegmentPile(benchmark::State& state) { segment_split(state, pile_map(), true); }
void BM_Cairn_SegmentPileNoSplit(benchmark::State& state) { segment_split(state, pile_map(), false); }

void BM_Cairn_SegmentPlaneGround(benchmark::State& state) {
  SegmentationConfig cfg;
  cfg.ground.method = "plane";  // the paper's single RANSAC plane: the same steps as the PCL pipeline
  for (auto _ : state) benchmark::DoNotOptimize(segment(site_map(), cfg));
  set_counters(state);
}

void BM_Pcl_Segment(benchmark::State& state) {
  const SegmentationConfig cfg;
  for (auto _ : state) {
    auto cloud = pcl_map();
    pcl::SACSegmentation<pcl::PointXYZ> sac;
    sac.setModelType(pcl::SACMODEL_PLANE);
    sac.setMethodType(pcl::SAC_RANSAC);
    sac.setDistanceThreshold(cfg.ground.d_plane);
    sac.setMaxIterations(cfg.ground.ransac_iterations);
    sac.setOptimizeCoefficients(true);
    sac.setInputCloud(cloud);
    auto ground = pcl::make_shared<pcl::PointIndices>();
    pcl::ModelCoefficients coef;
    sac.segment(*ground, coef);
    pcl::ExtractIndices<pcl::PointXYZ> ex;
    ex.setInputCloud(cloud);
    ex.setIndices(ground);
    ex.setNegative(true);
    auto rest = pcl::make_shared<pcl::PointCloud<pcl::PointXYZ>>();
    ex.filter(*rest);
    auto tree = pcl::make_shared<pcl::search::KdTree<pcl::PointXYZ>>();
    pcl::EuclideanClusterExtraction<pcl::PointXYZ> ec;
    ec.setClusterTolerance(cfg.clustering.tolerance);
    ec.setMinClusterSize(cfg.clustering.min_points);
    ec.setMaxClusterSize(std::numeric_limits<int>::max());
    ec.setSearchMethod(tree);
    ec.setInputCloud(rest);
    std::vector<pcl::PointIndices> clusters;
    ec.extract(clusters);
    for (const auto& cl : clusters) {  // planarity check per cluster
      pcl::SACSegmentation<pcl::PointXYZ> p;
      p.setModelType(pcl::SACMODEL_PLANE);
      p.setMethodType(pcl::SAC_RANSAC);
      p.setDistanceThreshold(cfg.planarity.distance);
      p.setMaxIterations(cfg.planarity.iterations);
      p.setInputCloud(rest);
      p.setIndices(pcl::make_shared<pcl::PointIndices>(cl));
      pcl::PointIndices inl;
      pcl::ModelCoefficients c2;
      p.segment(inl, c2);
      benchmark::DoNotOptimize(inl.indices.size());
    }
    benchmark::DoNotOptimize(clusters.size());
  }
  set_counters(state);
}

void BM_Cairn_VoxelGrid(benchmark::State& state) {
  for (auto _ : state) benchmark::DoNotOptimize(voxel_downsample(site_map(), {.res_voxel = 0.05}));
  set_counters(state);
}

void BM_Pcl_VoxelGrid(benchmark::State& state) {
  for (auto _ : state) {
    pcl::VoxelGrid<pcl::PointXYZ> vg;
    vg.setInputCloud(pcl_map());
    vg.setLeafSize(0.05f, 0.05f, 0.05f);
    pcl::PointCloud<pcl::PointXYZ> out;
    vg.filter(out);
    benchmark::DoNotOptimize(out.size());
  }
  set_counters(state);
}

void BM_Cairn_Clustering(benchmark::State& state) {
  for (auto _ : state) benchmark::DoNotOptimize(euclidean_clusters(site_map().points, {}, {.tolerance = 0.05}));
  set_counters(state);
}

void BM_Pcl_Clustering(benchmark::State& state) {
  for (auto _ : state) {
    auto tree = pcl::make_shared<pcl::search::KdTree<pcl::PointXYZ>>();
    pcl::EuclideanClusterExtraction<pcl::PointXYZ> ec;
    ec.setClusterTolerance(0.05);
    ec.setMinClusterSize(50);
    ec.setSearchMethod(tree);
    ec.setInputCloud(pcl_map());
    std::vector<pcl::PointIndices> clusters;
    ec.extract(clusters);
    benchmark::DoNotOptimize(clusters.size());
  }
  set_counters(state);
}

void BM_Cairn_Normals(benchmark::State& state) {
  for (auto _ : state) {
    const KdTree tree(site_map().points);
    benchmark::DoNotOptimize(estimate_normals(site_map().points, tree, {.radius = 0.1}));
  }
  set_counters(state);
}

void BM_Pcl_NormalsOMP(benchmark::State& state) {
  for (auto _ : state) {
    pcl::NormalEstimationOMP<pcl::PointXYZ, pcl::Normal> ne(2);
    ne.setInputCloud(pcl_map());
    ne.setSearchMethod(pcl::make_shared<pcl::search::KdTree<pcl::PointXYZ>>());
    ne.setRadiusSearch(0.1);
    pcl::PointCloud<pcl::Normal> out;
    ne.compute(out);
    benchmark::DoNotOptimize(out.size());
  }
  set_counters(state);
}

}  // namespace

BENCHMARK(BM_Cairn_Segment)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Cairn_SegmentNoSplit)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Cairn_SegmentPile)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Cairn_SegmentPileNoSplit)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Cairn_SegmentPlaneGround)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Pcl_Segment)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Cairn_VoxelGrid)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Pcl_VoxelGrid)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Cairn_Clustering)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Pcl_Clustering)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Cairn_Normals)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Pcl_NormalsOMP)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_MAIN();
