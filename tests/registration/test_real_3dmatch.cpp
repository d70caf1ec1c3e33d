// Descriptor-only global registration (registration.segments = false) on real data: the
// GeoTransformer demo pair of 3DMatch fragments (indoor RGB-D, 2.5 cm voxels, ~19° and 0.5 m
// apart, ~40 % overlap) against its ground-truth pose. There is no ground plane and no object
// to segment, so ISS + SHOT run on the whole clouds and each consistency group is refined by ICP
// and judged by its mutual overlap.
#include <gtest/gtest.h>

#include "cairn/registration/global_registration.hpp"
#include "support/threedmatch.hpp"
#include "cairn/core/units.hpp"

using namespace cairn;

namespace {

using cairn::kDeg;

/// Table 3's radii are for stones in 3 cm maps; an indoor fragment needs wider SHOT support to
/// be distinctive: at R_shot = 0.1 m only 5 of ~450 matches are right (within 10 cm), at 0.2 m
/// 48 of 850. Every descriptor's nearest neighbour is a match (no distance cut), and the scene
/// overlaps only ~40 %, so candidates need 35 % mutual overlap (the right one has 44 %, wrong ones
/// 21 %, the best pose against a mirrored copy of the room 27 %).
GlobalRegistrationConfig indoor_config() {
  GlobalRegistrationConfig c;
  c.segments = false;
  c.source_voxel.res_voxel = 0.025;  // the fragments' own voxel size
  c.shot.radius = 0.2;
  c.matching.max_squared_distance = 4.0;  // SHOT rows have unit length: every nearest neighbour
  c.acceptance.min_overlap = 0.35;
  return c;
}

}  // namespace

class Real3DMatchPair : public ::testing::TestWithParam<bool> {};

// Both estimators of the descriptor candidates: the paper's consistency grouping and the maximum
// clique (TEASER++'s inlier selection).
INSTANTIATE_TEST_SUITE_P(Estimators, Real3DMatchPair, ::testing::Values(false, true));  // max clique off, on

TEST_P(Real3DMatchPair, FragmentsRegisterWithoutSegments) {
  CAIRN_REQUIRE_REAL_DATA("geotransformer-3dmatch-demo/gt.npy");
  const auto p = test::load_3dmatch_pair();
  GlobalRegistrationConfig cfg = indoor_config();
  cfg.max_clique.enabled = GetParam();
  const GlobalRegistrationResult r = register_global(p.source, p.target, {}, cfg);
  ASSERT_TRUE(r.success) << r.reason;
  const auto e = test::error_at_centroid(r.T_target_source, p.T_gt, p.source);
  // The ground truth is not the geometric optimum: the same two ICP passes started AT the ground
  // truth move 5.7 cm at the centroid and 1.8° to a pose with more overlap and a smaller RMSE
  // (PCL's ICP: 5.6 cm, 2.0°, tests/peers/test_pcl_icp.cpp). cairn must land on that optimum, and
  // within 2° / 6 cm of the stated truth (measured 1.67°, 5.75 cm: little margin, by the nature
  // of the reference; the 1 cm check against the optimum is the sharp one). The objective is flat about an axis through the
  // centroid: runs from the two starts end ~0.6° apart but within a millimetre at the centroid.
  const IcpTarget target = IcpTarget::from_cloud(p.target, cfg.normals);
  IcpConfig icp = cfg.icp;  // the registration's two passes, both on every source point
  icp.max_correspondence_distance = cfg.coarse_correspondence_distance;
  Eigen::Isometry3d T_opt = register_icp(p.source.points, target, p.T_gt, icp).T_target_source;
  T_opt = register_icp(p.source.points, target, T_opt, cfg.icp).T_target_source;
  const auto e_opt = test::error_at_centroid(r.T_target_source, T_opt, p.source);
  const auto e_gt_opt = test::error_at_centroid(T_opt, p.T_gt, p.source);
  std::printf("%s: ", GetParam() ? "max clique" : "grouping");
  std::printf("3DMatch pair: %zu/%zu keypoints, %zu matches, %zu candidates; overlap %.3f rmse %.4f; error vs gt "
              "%.3f deg, %.4f m at the centroid; vs ICP-from-gt %.3f deg, %.4f m (which is %.3f deg, %.4f m from "
              "gt); %.0f ms\n",
              r.source_keypoints, r.target_keypoints, r.correspondences, r.candidates, r.overlap, r.rmse,
              e.rotation / kDeg, e.translation, e_opt.rotation / kDeg, e_opt.translation, e_gt_opt.rotation / kDeg,
              e_gt_opt.translation, r.timings.total());
  EXPECT_LT(e.rotation, 2.0 * kDeg);
  EXPECT_LT(e.translation, 0.06);
  EXPECT_LT(e_opt.rotation, 1.0 * kDeg);
  EXPECT_LT(e_opt.translation, 0.01);
  EXPECT_GT(r.overlap, 0.4);
  EXPECT_LT(r.rmse, cfg.acceptance.e_icp);
  // Every wrong refined candidate stays below the acceptance overlap.
  for (const CandidateReport& c : r.reports) {
    if (!c.refined) continue;
    const auto ec = test::error_at_centroid(c.T_target_source, p.T_gt, p.source);
    if (ec.rotation > 5.0 * kDeg || ec.translation > 0.2) {
      EXPECT_FALSE(c.accepted) << "wrong candidate accepted: overlap " << c.overlap;
    }
  }
}

TEST_P(Real3DMatchPair, MirroredSceneIsRefused) {
  // The target mirrored (x -> -x) is a room that does not exist: no rigid motion explains the
  // source, and the descriptor path must say so rather than return its best guess.
  CAIRN_REQUIRE_REAL_DATA("geotransformer-3dmatch-demo/gt.npy");
  auto p = test::load_3dmatch_pair();
  for (Vec3f& q : p.target.points) q.x() = -q.x();
  GlobalRegistrationConfig cfg = indoor_config();
  cfg.max_clique.enabled = GetParam();
  const GlobalRegistrationResult r = register_global(p.source, p.target, {}, cfg);
  EXPECT_FALSE(r.success);
  double best = 0.0;
  std::size_t refined = 0;
  for (const CandidateReport& c : r.reports) {
    best = std::max(best, c.overlap);
    refined += c.refined;
  }
  ASSERT_GT(refined, 0u) << "no candidate was refined: the overlap test was never reached";
  std::printf("%s: ", GetParam() ? "max clique" : "grouping");
  std::printf("mirrored 3DMatch target: %zu candidates, best overlap %.3f (%s)\n", r.candidates, best, r.reason.c_str());
  EXPECT_LT(best, indoor_config().acceptance.min_overlap);
}
