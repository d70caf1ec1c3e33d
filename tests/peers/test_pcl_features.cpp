// Cross-check of cairn's feature kernels (Sec. 4.4 steps 2-4) against PCL 1.13 on identical
// inputs: ISS keypoints vs pcl::ISSKeypoint3D, SHOT352 vs pcl::SHOTEstimationOMP (same keypoints,
// same normals), descriptor matching vs pcl::KdTreeFLANN<pcl::SHOT352> as in PCL's
// correspondence-grouping tutorial, grouping vs pcl::GeometricConsistencyGrouping (same
// correspondences), and the whole tutorial (milk carton in a Kinect scene).
#include <gtest/gtest.h>
#include <pcl/features/shot_omp.h>
#include <pcl/kdtree/kdtree_flann.h>
#include <pcl/point_types.h>
#include <pcl/recognition/cg/geometric_consistency.h>
#include <pcl/registration/transformation_estimation_svd.h>
#include <pcl/search/kdtree.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>

#include "cairn/core/kdtree.hpp"
#include "cairn/core/normals.hpp"
#include "cairn/core/transform.hpp"
#include "cairn/features/iss.hpp"
#include "cairn/features/matching.hpp"
#include "cairn/features/shot.hpp"
#include "cairn/registration/consistency_grouping.hpp"
#include "support/feature_data.hpp"
#include "support/pcl_convert.hpp"
#include "support/site_segments.hpp"
#include "support/test_data.hpp"
#include "support/pcl_iss.hpp"

using namespace cairn;

namespace {

using test::to_pcl;
using test::to_pcl_normals;

using CloudXYZ = pcl::PointCloud<pcl::PointXYZ>;

std::vector<std::uint32_t> pcl_iss(std::span<const Vec3f> points, const IssConfig& cfg) {
  auto cloud = to_pcl(points);
  test::PclIss iss;
  test::configure_pcl_iss(iss, cfg);
  iss.setInputCloud(cloud);
  CloudXYZ out;
  iss.compute(out);
  std::vector<std::uint32_t> idx;
  for (auto i : iss.getKeypointsIndices()->indices) idx.push_back(std::uint32_t(i));
  std::sort(idx.begin(), idx.end());
  return idx;
}

pcl::PointCloud<pcl::SHOT352>::Ptr pcl_shot(std::span<const Vec3f> keypoints, std::span<const Vec3f> surface,
                                            std::span<const Vec3f> normals, double radius) {
  pcl::SHOTEstimationOMP<pcl::PointXYZ, pcl::Normal, pcl::SHOT352> est;
  est.setNumberOfThreads(2);
  est.setRadiusSearch(radius);
  est.setInputCloud(to_pcl(keypoints));
  est.setInputNormals(to_pcl_normals(normals));
  est.setSearchSurface(to_pcl(surface));
  auto out = pcl::make_shared<pcl::PointCloud<pcl::SHOT352>>();
  est.compute(*out);
  return out;
}

/// The tutorial's matching: every scene descriptor's nearest model descriptor, kept when the
/// squared distance is < 0.25. Returned as cairn correspondences (source = scene, target = model).
std::vector<Correspondence> pcl_match(const pcl::PointCloud<pcl::SHOT352>::Ptr& scene,
                                      const pcl::PointCloud<pcl::SHOT352>::Ptr& model) {
  pcl::KdTreeFLANN<pcl::SHOT352> match_search;
  match_search.setInputCloud(model);
  std::vector<Correspondence> out;
  for (std::size_t i = 0; i < scene->size(); ++i) {
    pcl::Indices neigh_indices(1);
    std::vector<float> neigh_sqr_dists(1);
    if (!std::isfinite(scene->at(i).descriptor[0])) continue;
    const int found = match_search.nearestKSearch(scene->at(i), 1, neigh_indices, neigh_sqr_dists);
    if (found == 1 && neigh_sqr_dists[0] < 0.25f)
      out.push_back({std::uint32_t(i), std::uint32_t(neigh_indices[0]), neigh_sqr_dists[0]});
  }
  return out;
}

struct PclGrouping {
  std::vector<Eigen::Matrix4f, Eigen::aligned_allocator<Eigen::Matrix4f>> transforms;  // model -> scene
  std::vector<pcl::Correspondences> instances;
};

/// pcl::GeometricConsistencyGrouping with the model as PCL's input (index_query) and the scene
/// as its scene (index_match), as in the tutorial. `corrs`: source = model, target = scene.
PclGrouping pcl_grouping(std::span<const Vec3f> model_kp, std::span<const Vec3f> scene_kp,
                         std::span<const Correspondence> corrs, const GroupingConfig& cfg) {
  auto pc = pcl::make_shared<pcl::Correspondences>();
  for (const auto& c : corrs) pc->push_back(pcl::Correspondence(int(c.source), int(c.target), c.squared_distance));
  pcl::GeometricConsistencyGrouping<pcl::PointXYZ, pcl::PointXYZ> gc;
  gc.setGCSize(cfg.consensus_size);
  gc.setGCThreshold(cfg.min_votes);
  gc.setInputCloud(to_pcl(model_kp));
  gc.setSceneCloud(to_pcl(scene_kp));
  gc.setModelSceneCorrespondences(pc);
  PclGrouping out;
  gc.recognize(out.transforms, out.instances);
  return out;
}

struct Inputs {
  std::vector<Vec3f> points, normals;
};

Inputs milk() {
  Inputs in;
  in.points = test::load_real_points("pcl-correspondence-grouping/milk.pcd");
  const KdTree tree(in.points);
  in.normals = estimate_normals(in.points, tree, {.k = 10}).normals;
  return in;
}

Inputs bunny() {
  Inputs in;
  in.points = test::load_real_points("pcl-bunny/bun_zipper_res3.ply");
  const KdTree tree(in.points);
  in.normals = estimate_normals(in.points, tree, {.k = 10}).normals;
  return in;
}

Inputs site() {
  const auto s = test::site_segment_points(1);
  return {s.points, s.normals};
}

/// ISS comparison: exact index sets.
void expect_same_iss(const std::vector<Vec3f>& points, const IssConfig& cfg, std::size_t min_keypoints) {
  const KdTree tree(points);
  const auto ours = iss_keypoints(points, tree, cfg);
  const auto theirs = pcl_iss(points, cfg);
  std::vector<std::uint32_t> only_ours, only_theirs;
  std::set_difference(ours.begin(), ours.end(), theirs.begin(), theirs.end(), std::back_inserter(only_ours));
  std::set_difference(theirs.begin(), theirs.end(), ours.begin(), ours.end(), std::back_inserter(only_theirs));
  std::cout << "[ ISS      ] " << points.size() << " points: cairn " << ours.size() << " keypoints, PCL "
            << theirs.size() << ", only cairn " << only_ours.size() << ", only PCL " << only_theirs.size() << "\n";
  EXPECT_GE(ours.size(), min_keypoints);
  EXPECT_EQ(ours, theirs);
}

struct ShotDiff {
  double max_abs = 0.0;
  double max_lrf = 0.0;
  std::size_t valid_mismatch = 0, valid = 0, beyond_1e4 = 0;
};

ShotDiff compare_shot(const ShotDescriptors& ours, const pcl::PointCloud<pcl::SHOT352>& theirs) {
  ShotDiff d;
  for (std::size_t i = 0; i < ours.size(); ++i) {
    const bool pcl_valid = std::isfinite(theirs[i].descriptor[0]);
    if (bool(ours.valid[i]) != pcl_valid) {
      ++d.valid_mismatch;
      continue;
    }
    if (!pcl_valid) continue;
    ++d.valid;
    double row_max = 0.0;
    for (int b = 0; b < kShotSize; ++b)
      row_max = std::max(row_max, double(std::abs(ours.descriptor(i)[std::size_t(b)] - theirs[i].descriptor[b])));
    d.max_abs = std::max(d.max_abs, row_max);
    if (row_max > 1e-4) ++d.beyond_1e4;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) d.max_lrf = std::max(d.max_lrf, double(std::abs(ours.lrf[i](r, c) - theirs[i].rf[r * 3 + c])));
  }
  return d;
}

}  // namespace

// --- ISS ----------------------------------------------------------------------------------------

TEST(PclFeatures, IssEqualsPclOnMilkCarton) {
  CAIRN_REQUIRE_REAL_DATA("pcl-correspondence-grouping/milk.pcd");
  expect_same_iss(milk().points, {.salient_radius = 0.012, .non_max_radius = 0.008}, 20);
}

TEST(PclFeatures, IssEqualsPclOnBunny) {
  CAIRN_REQUIRE_REAL_DATA("pcl-bunny/bun_zipper_res3.ply");
  expect_same_iss(bunny().points, {.salient_radius = 0.015, .non_max_radius = 0.01}, 10);
}

TEST(PclFeatures, IssEqualsPclOnSiteSegmentsTable3) {
  expect_same_iss(site().points, {}, 50);  // Table 3: R_iss = 6 cm
}

// --- SHOT ---------------------------------------------------------------------------------------

void expect_same_shot(const Inputs& in, std::span<const Vec3f> keypoints, double radius) {
  const KdTree tree(in.points);
  const ShotDescriptors ours = compute_shot(keypoints, in.points, in.normals, tree, {.radius = radius});
  const auto theirs = pcl_shot(keypoints, in.points, in.normals, radius);
  ASSERT_EQ(theirs->size(), ours.size());
  const ShotDiff d = compare_shot(ours, *theirs);
  std::cout << "[ SHOT     ] " << ours.size() << " keypoints, " << d.valid << " valid in both, validity mismatches "
            << d.valid_mismatch << ", max |bin difference| " << d.max_abs << ", descriptors beyond 1e-4 "
            << d.beyond_1e4 << ", max |LRF difference| " << d.max_lrf << "\n";
  EXPECT_EQ(d.valid_mismatch, 0u);
  EXPECT_GT(d.valid, keypoints.size() / 2);
  EXPECT_LE(d.max_abs, 1e-4);
  EXPECT_LE(d.max_lrf, 1e-4);
}

TEST(PclFeatures, ShotEqualsPclOnMilkCarton) {
  CAIRN_REQUIRE_REAL_DATA("pcl-correspondence-grouping/milk.pcd");
  const Inputs in = milk();
  const auto kp = test::gather(in.points, test::uniform_sampling(in.points, 0.01f));
  expect_same_shot(in, kp, 0.02);  // tutorial: descr_rad 0.02
}

TEST(PclFeatures, ShotEqualsPclOnBunny) {
  CAIRN_REQUIRE_REAL_DATA("pcl-bunny/bun_zipper_res3.ply");
  const Inputs in = bunny();
  const auto kp = test::gather(in.points, test::uniform_sampling(in.points, 0.01f));
  expect_same_shot(in, kp, 0.025);
}

TEST(PclFeatures, ShotEqualsPclOnSiteSegmentsTable3) {
  const Inputs in = site();
  const KdTree tree(in.points);
  const auto kp = test::gather(in.points, iss_keypoints(in.points, tree, {}));
  expect_same_shot(in, kp, 0.10);  // Table 3: R_shot = 10 cm
}

// --- Matching and grouping: the correspondence-grouping tutorial ----------------------------------

namespace {

struct Tutorial {
  Inputs model, scene;
  std::vector<Vec3f> model_kp, scene_kp;
  ShotDescriptors model_desc, scene_desc;
  pcl::PointCloud<pcl::SHOT352>::Ptr pcl_model_desc, pcl_scene_desc;
};

/// PCL's tutorial parameters: model_ss 0.01, scene_ss 0.03, descr_rad 0.02, normals k = 10.
const Tutorial& tutorial() {
  static const Tutorial t = [] {
    Tutorial t;
    t.model = milk();
    t.scene.points = test::load_real_points("pcl-correspondence-grouping/milk_cartoon_all_small_clorox.pcd");
    const KdTree model_tree(t.model.points), scene_tree(t.scene.points);
    t.scene.normals = estimate_normals(t.scene.points, scene_tree, {.k = 10}).normals;
    t.model_kp = test::gather(t.model.points, test::uniform_sampling(t.model.points, 0.01f));
    t.scene_kp = test::gather(t.scene.points, test::uniform_sampling(t.scene.points, 0.03f));
    t.model_desc = compute_shot(t.model_kp, t.model.points, t.model.normals, model_tree, {.radius = 0.02});
    t.scene_desc = compute_shot(t.scene_kp, t.scene.points, t.scene.normals, scene_tree, {.radius = 0.02});
    t.pcl_model_desc = pcl_shot(t.model_kp, t.model.points, t.model.normals, 0.02);
    t.pcl_scene_desc = pcl_shot(t.scene_kp, t.scene.points, t.scene.normals, 0.02);
    return t;
  }();
  return t;
}

std::vector<Correspondence> swapped(std::span<const Correspondence> c) {
  std::vector<Correspondence> out;
  for (const auto& x : c) out.push_back({x.target, x.source, x.squared_distance});
  return out;
}

}  // namespace

TEST(PclFeatures, ShotEqualsPclOnTutorialScene) {
  CAIRN_REQUIRE_REAL_DATA("pcl-correspondence-grouping/milk_cartoon_all_small_clorox.pcd");
  const Tutorial& t = tutorial();
  const ShotDiff d = compare_shot(t.scene_desc, *t.pcl_scene_desc);
  std::cout << "[ SHOT     ] scene: " << t.scene_kp.size() << " keypoints, " << d.valid
            << " valid, validity mismatches " << d.valid_mismatch << ", max |bin difference| " << d.max_abs
            << ", beyond 1e-4 " << d.beyond_1e4 << ", max |LRF difference| " << d.max_lrf << "\n";
  EXPECT_EQ(d.valid_mismatch, 0u);
  EXPECT_LE(d.max_abs, 1e-4);
}

TEST(PclFeatures, MatchingEqualsKdTreeFlann) {
  CAIRN_REQUIRE_REAL_DATA("pcl-correspondence-grouping/milk_cartoon_all_small_clorox.pcd");
  const Tutorial& t = tutorial();
  // Same descriptors on both sides (PCL's), so only the search is compared.
  ShotDescriptors scene = t.scene_desc, model = t.model_desc;
  for (std::size_t i = 0; i < scene.size(); ++i)
    std::copy_n(t.pcl_scene_desc->at(i).descriptor, kShotSize, scene.data.begin() + long(i) * kShotSize);
  for (std::size_t i = 0; i < model.size(); ++i)
    std::copy_n(t.pcl_model_desc->at(i).descriptor, kShotSize, model.data.begin() + long(i) * kShotSize);
  const auto theirs = pcl_match(t.pcl_scene_desc, t.pcl_model_desc);
  for (const std::string search : {"scan", "kdtree"}) {
    const auto ours = match_descriptors(scene, model, {.search = search});
    std::cout << "[ MATCH    ] " << search << ": " << scene.num_valid() << " scene descriptors -> " << ours.size()
              << " correspondences (PCL " << theirs.size() << ")\n";
    ASSERT_EQ(ours.size(), theirs.size());
    ASSERT_GT(ours.size(), 20u);
    for (std::size_t i = 0; i < ours.size(); ++i) {
      EXPECT_EQ(ours[i].source, theirs[i].source);
      EXPECT_EQ(ours[i].target, theirs[i].target);
      EXPECT_EQ(ours[i].squared_distance, theirs[i].squared_distance);  // bit-identical
    }
  }
  // On cairn's own descriptors the correspondences are the same pairs.
  const auto own = match_descriptors(t.scene_desc, t.model_desc, {});
  std::size_t same = 0;
  for (std::size_t i = 0, j = 0; i < own.size() && j < theirs.size();) {
    if (own[i].source == theirs[j].source) {
      same += own[i].target == theirs[j].target;
      ++i, ++j;
    } else if (own[i].source < theirs[j].source) {
      ++i;
    } else {
      ++j;
    }
  }
  std::cout << "[ MATCH    ] on cairn's descriptors: " << own.size() << " correspondences, " << same
            << " identical to PCL's\n";
  EXPECT_EQ(own.size(), theirs.size());
  EXPECT_EQ(same, theirs.size());
}

TEST(PclFeatures, GroupingEqualsGeometricConsistencyGrouping) {
  CAIRN_REQUIRE_REAL_DATA("pcl-correspondence-grouping/milk_cartoon_all_small_clorox.pcd");
  const Tutorial& t = tutorial();
  const auto corrs = swapped(pcl_match(t.pcl_scene_desc, t.pcl_model_desc));  // source = model
  for (const double gc_size : {0.01, 0.02}) {
    const GroupingConfig cfg{.consensus_size = gc_size, .min_votes = 5, .max_candidates = 1000, .refine = false};
    const PclGrouping theirs = pcl_grouping(t.model_kp, t.scene_kp, corrs, cfg);
    const auto clusters = consistency_clusters(t.model_kp, t.scene_kp, corrs, cfg);
    std::cout << "[ GROUPING ] gc_size " << gc_size << ": " << corrs.size() << " correspondences, cairn "
              << clusters.size() << " clusters, PCL " << theirs.instances.size() << " instances\n";
    ASSERT_EQ(clusters.size(), theirs.instances.size());
    ASSERT_GE(clusters.size(), 1u);
    for (std::size_t c = 0; c < clusters.size(); ++c) {
      // PCL's instance is the RANSAC-filtered cluster: a subset of cairn's cluster.
      std::set<std::pair<std::uint32_t, std::uint32_t>> ours;
      for (const auto& m : clusters[c]) ours.insert({m.source, m.target});
      std::size_t inside = 0;
      for (const auto& m : theirs.instances[c]) inside += ours.count({std::uint32_t(m.index_query), std::uint32_t(m.index_match)});
      EXPECT_EQ(inside, theirs.instances[c].size()) << "cluster " << c;
      // Least-squares transform of PCL's instance (TransformationEstimationSVD) vs cairn's fit on
      // the same pairs; and PCL's own (3-point RANSAC) transform vs cairn's refined candidate.
      pcl::Correspondences inst = theirs.instances[c];
      Eigen::Matrix4f svd;
      pcl::registration::TransformationEstimationSVD<pcl::PointXYZ, pcl::PointXYZ> est;
      est.estimateRigidTransformation(*to_pcl(t.model_kp), *to_pcl(t.scene_kp), inst, svd);
      std::vector<Correspondence> same_pairs;
      for (const auto& m : inst) same_pairs.push_back({std::uint32_t(m.index_query), std::uint32_t(m.index_match), m.distance});
      const auto cand = geometric_consistency_grouping(t.model_kp, t.scene_kp, same_pairs,
                                                       {.consensus_size = 1.0, .min_votes = 2, .refine = false});
      ASSERT_EQ(cand.size(), 1u);
      const Eigen::Matrix4d diff = cand[0].T_target_source.matrix() - svd.cast<double>();
      std::cout << "[ GROUPING ]   cluster " << c << ": " << clusters[c].size() << " pairs (PCL instance "
                << inst.size() << "), |T_cairn - T_pcl_svd|_max on PCL's instance " << diff.cwiseAbs().maxCoeff() << "\n";
      EXPECT_LT(diff.cwiseAbs().maxCoeff(), 1e-4);
    }
  }
}

TEST(PclFeatures, TutorialFindsTheMilkCartonLikePcl) {
  CAIRN_REQUIRE_REAL_DATA("pcl-correspondence-grouping/milk_cartoon_all_small_clorox.pcd");
  const Tutorial& t = tutorial();
  // PCL: its descriptors, its matching, its grouping (cg_size 0.01, cg_thresh 5).
  const auto pcl_corrs = swapped(pcl_match(t.pcl_scene_desc, t.pcl_model_desc));
  const PclGrouping theirs = pcl_grouping(t.model_kp, t.scene_kp, pcl_corrs, {.consensus_size = 0.01, .min_votes = 5});
  ASSERT_GE(theirs.instances.size(), 1u);
  // cairn: its descriptors, its matching, its grouping.
  const auto corrs = swapped(match_descriptors(t.scene_desc, t.model_desc, {}));
  const auto cands = geometric_consistency_grouping(t.model_kp, t.scene_kp, corrs, {.consensus_size = 0.01, .min_votes = 5});
  ASSERT_EQ(cands.size(), theirs.instances.size());
  // PCL returns its instances in discovery order; the carton is the one with most pairs.
  std::size_t best = 0;
  for (std::size_t i = 0; i < theirs.instances.size(); ++i) {
    std::cout << "[ TUTORIAL ] PCL instance " << i << ": " << theirs.instances[i].size() << " pairs; cairn candidate "
              << i << ": " << cands[i].votes << " votes\n";
    if (theirs.instances[i].size() > theirs.instances[best].size()) best = i;
  }
  Eigen::Isometry3d T_pcl;
  T_pcl.matrix() = theirs.transforms[best].cast<double>();
  const Eigen::Isometry3d& T = cands[0].T_target_source;
  Vec3d centroid = Vec3d::Zero();
  for (const auto& p : t.model.points) centroid += p.cast<double>();
  centroid /= double(t.model.points.size());
  const double shift = (T * centroid - T_pcl * centroid).norm();
  const double angle = rotation_angle(T_pcl.linear().transpose() * T.linear()) * 180.0 / M_PI;
  const double ours_overlap = test::overlap(t.model.points, t.scene.points, T, 0.005);
  const double pcl_overlap = test::overlap(t.model.points, t.scene.points, T_pcl, 0.005);
  // Keypoint residuals of both poses on the cluster's pairs (PCL's instance = the same 31 pairs).
  const auto keypoint_rms = [&](const Eigen::Isometry3d& X) {
    double sum = 0.0;
    for (const auto& m : cands[0].inliers)
      sum += (t.scene_kp[m.target].cast<double>() - X * t.model_kp[m.source].cast<double>()).squaredNorm();
    return std::sqrt(sum / double(cands[0].inliers.size()));
  };
  std::cout << "[ TUTORIAL ] cairn " << cands[0].votes << " votes / " << cands[0].inliers.size()
            << " inliers, PCL instance " << theirs.instances[best].size() << " pairs; pose difference (model centroid) "
            << shift * 1000 << " mm, " << angle << " deg; model points within 5 mm of the scene: cairn "
            << ours_overlap * 100 << " %, PCL " << pcl_overlap * 100 << " %; RMS model-to-scene distance: cairn "
            << test::rms_to_nearest(t.model.points, t.scene.points, T) * 1000 << " mm, PCL "
            << test::rms_to_nearest(t.model.points, t.scene.points, T_pcl) * 1000 << " mm; keypoint RMS: cairn "
            << keypoint_rms(T) * 1000 << " mm, PCL " << keypoint_rms(T_pcl) * 1000 << " mm\n";
  // PCL's pose is the best 3-point RANSAC sample of the cluster, cairn's the least-squares fit of
  // all its pairs, so they differ by the keypoint noise: ~1.4 mm / 1.1 deg here. 1 cm / 2 deg.
  EXPECT_LT(shift, 0.01);
  EXPECT_LT(angle, 2.0);
  EXPECT_LE(keypoint_rms(T), keypoint_rms(T_pcl));
  EXPECT_GE(ours_overlap, 0.9);
}
