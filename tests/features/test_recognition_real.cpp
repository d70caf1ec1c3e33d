// PCL's correspondence-grouping tutorial with cairn (real Kinect data): the milk carton model is
// found in the cluttered scene. Tutorial parameters: model_ss 0.01, scene_ss 0.03, descr_rad 0.02,
// cg_size 0.01, cg_thresh 5, normals k = 10, uniform-sampling keypoints.
#include <gtest/gtest.h>

#include "cairn/core/kdtree.hpp"
#include "cairn/core/normals.hpp"
#include "cairn/features/matching.hpp"
#include "cairn/features/shot.hpp"
#include "cairn/registration/consistency_grouping.hpp"
#include "support/feature_data.hpp"

using namespace cairn;

TEST(RecognitionReal, TutorialFindsTheMilkCarton) {
  CAIRN_REQUIRE_REAL_DATA("pcl-correspondence-grouping/milk_cartoon_all_small_clorox.pcd");
  const auto model = test::load_real_points("pcl-correspondence-grouping/milk.pcd");
  const auto scene = test::load_real_points("pcl-correspondence-grouping/milk_cartoon_all_small_clorox.pcd");
  const KdTree model_tree(model), scene_tree(scene);
  const auto model_normals = estimate_normals(model, model_tree, {.k = 10}).normals;
  const auto scene_normals = estimate_normals(scene, scene_tree, {.k = 10}).normals;
  const auto model_kp = test::gather(model, test::uniform_sampling(model, 0.01f));
  const auto scene_kp = test::gather(scene, test::uniform_sampling(scene, 0.03f));
  const auto model_desc = compute_shot(model_kp, model, model_normals, model_tree, {.radius = 0.02});
  const auto scene_desc = compute_shot(scene_kp, scene, scene_normals, scene_tree, {.radius = 0.02});
  // As the tutorial: each scene descriptor's nearest model descriptor. Grouping with source =
  // model, so the candidate is T_scene_model.
  std::vector<Correspondence> matches;
  for (const auto& m : match_descriptors(scene_desc, model_desc, {})) matches.push_back({m.target, m.source, m.squared_distance});
  const auto cands = geometric_consistency_grouping(model_kp, scene_kp, matches, {.consensus_size = 0.01, .min_votes = 5});
  ASSERT_FALSE(cands.empty());
  const double within = test::overlap(model, scene, cands[0].T_target_source, 0.005);
  std::cout << "[ TUTORIAL ] " << model_kp.size() << " model / " << scene_kp.size() << " scene keypoints, "
            << matches.size() << " matches, " << cands.size() << " candidates, top: " << cands[0].votes
            << " votes; " << within * 100 << " % of the model within 5 mm of the scene\n";
  EXPECT_GE(within, 0.9);
}
