// Grasp planning (Sec. 5): local frames on analytic shapes, collision, jaw closing and force
// closure on a box, ranking order, ground fill, and the whole planner on a box on the ground.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <random>
#include <set>

#include "cairn/core/error.hpp"
#include "cairn/core/kdtree.hpp"
#include "cairn/grasp/force_closure.hpp"
#include "cairn/grasp/planner.hpp"
#include "cairn/core/io/io.hpp"
#include "scenes.hpp"
#include "support/test_data.hpp"
#include "cairn/core/units.hpp"

namespace cairn::grasp {
namespace {

using Eigen::Vector3d;
using cairn::kDeg;
constexpr double kInf = std::numeric_limits<double>::infinity();

std::vector<Vec3f> normals_within(const PointCloud& c, const Vec3f& p, double r) {
  std::vector<Vec3f> out;
  for (std::size_t i = 0; i < c.size(); ++i)
    if ((c.points[i] - p).norm() < r) out.push_back(c.normals[i]);
  return out;
}

TEST(LocalReferenceFrame, OnASphereTheApproachAxisIsTheNormal) {
  const PointCloud s = test::sphere_surface(Vector3d::Zero(), 0.5, 4000);
  for (const std::size_t i : {10u, 1000u, 2500u}) {
    const Eigen::Matrix3d F = local_reference_frame(normals_within(s, s.points[i], 0.15), s.normals[i].cast<double>());
    EXPECT_GT(F.col(0).dot(s.normals[i].cast<double>()), 0.99);
    EXPECT_NEAR(F.determinant(), 1.0, 1e-9);
  }
}

TEST(LocalReferenceFrame, OnACylinderTheMinimalCurvatureAxisIsTheCylinderAxis) {
  const Vector3d axis = Vector3d(1.0, 1.0, 0.3).normalized();
  const PointCloud c = test::cylinder_surface(Vector3d(1, 2, 0.5), axis, 0.3, 0.8, 0.02);
  const std::size_t i = c.size() / 2;
  const Eigen::Matrix3d F = local_reference_frame(normals_within(c, c.points[i], 0.15), c.normals[i].cast<double>());
  EXPECT_GT(std::abs(F.col(2).dot(axis)), 0.99);
  EXPECT_GT(F.col(0).dot(c.normals[i].cast<double>()), 0.95);
}

TEST(LocalReferenceFrame, OnABoxEdgeTheMinimalCurvatureAxisIsTheEdge) {
  const PointCloud b = test::box_surface(Vector3d::Zero(), Vector3d(0.5, 0.5, 0.5), 0.02);
  const Vec3f edge(0.5f, 0.0f, 0.5f);  // the edge along y between the +x and +z faces
  const Eigen::Matrix3d F = local_reference_frame(normals_within(b, edge, 0.1), Vector3d(1, 0, 1).normalized());
  EXPECT_GT(std::abs(F.col(2).y()), 0.999);
  EXPECT_GT(F.col(0).dot(Vector3d(1, 0, 1).normalized()), 0.7);  // x in the xz-plane, outwards
}

TEST(Collision, TheGripperAdvancesUntilPalmOrJawTouches) {
  const GripperConfig g;
  const std::vector<SweptBox> boxes = swept_boxes(gripper_parts(g, max_opening(g)));
  const std::vector<Vector3d> ahead{{2.0, 0.0, 0.0}};  // on the axis: the palm's face meets it
  EXPECT_NEAR(advance_to_contact(boxes, ahead).value(), 2.0, 1e-9);
  const double tip_y = 0.5 * g.hinge_spacing + g.jaw_length * std::sin(g.max_jaw_angle_deg * kDeg);
  const double tip_x = g.jaw_length * std::cos(g.max_jaw_angle_deg * kDeg);
  const std::vector<Vector3d> under_tip{{tip_x + 0.3, -(tip_y + 0.01), 0.0}};  // in the left jaw's path
  EXPECT_NEAR(advance_to_contact(boxes, under_tip).value(), 0.3, 0.02);
  const std::vector<Vector3d> inside_palm{{-0.2, 0.0, 0.0}};
  EXPECT_FALSE(advance_to_contact(boxes, inside_palm).has_value());
  const std::vector<Vector3d> beside{{1.0, 0.0, 2.0}};  // above the gripper: never touched
  EXPECT_TRUE(std::isinf(advance_to_contact(boxes, beside).value()));
}

// The push's box shadows only skip points the exact slab test rejects: on random points around
// gripper poses turned about z (every box), the advance equals a sweep over the points one at a
// time (a point's first contact is a min over points, so one by one gives the reference).
TEST(Collision, BoxShadowsRejectOnlyPointsNoBoxCanTouch) {
  const GripperConfig g;
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-3.0, 3.0);
  for (const double opening : {max_opening(g), 0.55 * max_opening(g), 0.9}) {
    const std::vector<SweptBox> boxes = swept_boxes(gripper_parts(g, opening), 0.1);
    int touched = 0;
    for (int k = 0; k < 4000; ++k) {
      const Vector3d q(u(rng), u(rng), 0.3 * u(rng));
      const std::optional<double> s = advance_to_contact(boxes, std::vector<Vector3d>{q});
      // Reference: the slab test without shadows, box by box.
      std::optional<double> ref = std::numeric_limits<double>::infinity();
      for (const SweptBox& b : boxes) {
        SweptBox wide = b;
        wide.shadow = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
        const std::optional<double> one = advance_to_contact(std::vector<SweptBox>{wide}, std::vector<Vector3d>{q});
        if (!one) ref = std::nullopt;
        if (ref && one) ref = std::min(*ref, *one);
      }
      ASSERT_EQ(s.has_value(), ref.has_value()) << q.transpose();
      if (s) {
        EXPECT_EQ(*s, *ref) << q.transpose();
        touched += std::isfinite(*s) ? 1 : 0;
      }
    }
    EXPECT_GT(touched, 100);  // the random points do reach the boxes
  }
}

/// A gathered set in a fixed order (object points with their normals, the environment's).
std::vector<std::array<double, 6>> sorted_points(const LocalPoints& p) {
  std::vector<std::array<double, 6>> out;
  for (std::size_t i = 0; i < p.object.size(); ++i)
    out.push_back({p.object[i].x(), p.object[i].y(), p.object[i].z(), p.normals[i].x(), p.normals[i].y(), p.normals[i].z()});
  for (const Vector3d& q : p.environment) out.push_back({q.x(), q.y(), q.z(), kInf, kInf, kInf});
  std::sort(out.begin(), out.end());
  return out;
}

// Gathering a pose's points during the kd-tree visit (a few spheres along the region) gives the
// points gathering the indices of the one sphere around the region gives, each once, bit for bit;
// and every one lies in the closing region.
TEST(Collision, GatheringDuringTheTreeVisitEqualsGatheringTheIndices) {
  PointCloud cloud = test::ground_square(2.5, 0.0, 0.05);
  const PointCloud box = test::box_surface(Vector3d(0.3, 0.1, 0.4), Vector3d(0.4, 0.3, 0.4), 0.05);
  cloud.labels.assign(cloud.size(), kEnvironment);
  for (std::size_t i = 0; i < box.size(); ++i) {
    cloud.points.push_back(box.points[i]);
    cloud.normals.push_back(box.normals[i]);
    cloud.labels.push_back(kObject);
  }
  cloud.normals.resize(cloud.size(), Vec3f::UnitZ());
  const KdTree tree(cloud.points);
  const GripperConfig g;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(0.5 * std::numbers::pi, Vector3d::UnitY()).toRotationMatrix() *
               Eigen::AngleAxisd(0.3, Vector3d::UnitX()).toRotationMatrix();  // approach downwards, tilted
  T.translation() = Vector3d(0.3, 0.1, 1.0);  // the tips reach the ground
  for (const double share : {1.0, 0.7, 0.3}) {
    const double opening = share * max_opening(g), clearance = 0.05;
    Neighbors nb;
    tree.radius(closing_centre(g, T).cast<float>(), float(closing_reach(g, opening) + clearance), nb);
    LocalPoints a, b;
    gather_local(cloud, nb.indices, T, opening, g, a, clearance);
    gather_local(cloud, tree, T, opening, g, b, clearance);
    EXPECT_GT(a.object.size(), 50u);
    EXPECT_GT(a.environment.size(), 50u);
    EXPECT_EQ(sorted_points(a), sorted_points(b)) << "opening " << opening;
    for (const Vector3d& q : b.environment) {
      EXPECT_LE(std::abs(q.y()), closing_lateral(g, opening));
      EXPECT_LE(std::abs(q.z()), 0.5 * g.jaw_height + 1e-6);
      EXPECT_GT(q.x(), 0.0);
      EXPECT_LE(q.x(), g.jaw_length + clearance + 1e-6);
    }
  }
}

// Every point between the open jaws is gathered, at openings wider and narrower than the pivots'
// spacing (jaws turned inwards still span the pivots at their roots), checked against the jaws'
// own lines, not the gatherer's bounds.
TEST(Collision, EveryPointBetweenTheOpenJawsIsGathered) {
  const GripperConfig g;
  PointCloud cloud;  // a block of object points in G (T = identity), 5 cm apart
  for (double x = 0.025; x < g.jaw_length; x += 0.05)
    for (double y = -1.6; y <= 1.6; y += 0.05)
      for (double z = -0.2; z <= 0.2; z += 0.1) {
        cloud.points.emplace_back(float(x), float(y), float(z));
        cloud.normals.push_back(Vec3f::UnitX());
        cloud.labels.push_back(kObject);
      }
  const KdTree tree(cloud.points);
  for (const double share : {1.0, 0.55, 0.3, 0.1}) {
    const double opening = share * max_opening(g);
    const JawLines open = jaw_lines(g, jaw_angle_for(g, opening));
    LocalPoints local;
    gather_local(cloud, tree, Eigen::Isometry3d::Identity(), opening, g, local);
    std::set<std::array<float, 3>> gathered;
    for (const Vector3d& q : local.object) gathered.insert({float(q.x()), float(q.y()), float(q.z())});
    int between = 0;
    for (const Vec3f& p : cloud.points) {
      if (!open.encloses(p.cast<double>())) continue;
      ++between;
      EXPECT_TRUE(gathered.count({p.x(), p.y(), p.z()})) << "share " << share << ": " << p.transpose();
    }
    EXPECT_GT(between, 100) << "share " << share;
  }
}

/// A box in G: centre (0.5, 0, 0), 0.8 deep along x, 0.6 across (y), 0.4 high (z): the jaws,
/// converging at their tips (pivots 1.4 m apart), touch its far vertical edges.
struct BoxInGripper {
  std::vector<Vector3d> points, normals;
  BoxInGripper() {
    const PointCloud b = test::box_surface(Vector3d(0.5, 0.0, 0.0), Vector3d(0.4, 0.3, 0.2), 0.02);
    for (std::size_t i = 0; i < b.size(); ++i) {
      points.push_back(b.points[i].cast<double>());
      normals.push_back(b.normals[i].cast<double>());
    }
  }
};

TEST(ForceClosure, OppositeFacesOfABoxAreInForceClosureWithFriction) {
  const GripperConfig g;
  const BoxInGripper box;
  const Closing c = close_jaws(g, max_jaw_angle(g), box.points, box.normals, {}, 0.05);
  ASSERT_TRUE(c.closed) << c.failure;
  const double expected = std::atan2(-(0.7 - 0.3), 0.9);  // the jaw line through the far edge
  EXPECT_NEAR(c.angle, expected, 0.01);
  EXPECT_NEAR(c.contacts[0].y(), -0.3, 0.01);
  EXPECT_NEAR(c.contacts[1].y(), 0.3, 0.01);
  EXPECT_NEAR(c.shift, 0.0, 0.01);
  // Each jaw pushes along its face normal, tilted by |angle| = 24 deg from the contact line.
  EXPECT_TRUE(force_closure(c, 0.6));   // atan(0.6) = 31 deg
  EXPECT_FALSE(force_closure(c, 0.3));  // atan(0.3) = 17 deg
  EXPECT_FALSE(force_closure(c, 0.0));
}

TEST(ForceClosure, AdjacentFacesAreNot) {
  Closing c;
  c.closed = true;
  c.contacts = {Vector3d(0.5, -0.3, 0.0), Vector3d(0.9, 0.1, 0.0)};  // -y face and +x face
  c.forces = {Vector3d(0, 1, 0), Vector3d(-1, 0, 0)};
  EXPECT_FALSE(force_closure(c, 0.6));
  EXPECT_NEAR(cone_margin(c, 0.6), std::atan(0.6) - std::numbers::pi / 4, 1e-9);
  EXPECT_FALSE(force_closure(c, 10.0) && cone_margin(c, 0.9) > 0);  // 45 deg needs mu >= 1
}

TEST(ForceClosure, ClosingOnTheGroundIsACollisionAndAnEmptyGripIsEmpty) {
  const GripperConfig g;
  const BoxInGripper box;
  const std::vector<Vector3d> ground{{0.95, -0.8, 0.0}};  // in the left jaw's sweep
  EXPECT_EQ(close_jaws(g, max_jaw_angle(g), box.points, box.normals, ground, 0.05).failure, "collision_close");
  const std::vector<Vector3d> tiny{{0.5, 0.0, 0.0}};  // nearer the palm than where the tips meet
  const std::vector<Vector3d> n{{-1.0, 0.0, 0.0}};
  EXPECT_EQ(close_jaws(g, max_jaw_angle(g), tiny, n, {}, 0.05).failure, "empty");
  EXPECT_EQ(close_jaws(g, max_jaw_angle(g), {}, {}, {}, 0.05).failure, "empty");
}

TEST(ForceClosure, TheTipsKeepTheirClearanceFromTheGround) {
  const GripperConfig g;
  const BoxInGripper box;
  // 3 cm beyond the arc the left tip sweeps, straight ahead of its pivot (y = -hinge_spacing / 2):
  // clear without a clearance and with 2 cm, hit with 5 cm.
  const std::vector<Vector3d> beyond_tip{{g.jaw_length + 0.03, -0.5 * g.hinge_spacing, 0.0}};
  EXPECT_TRUE(close_jaws(g, max_jaw_angle(g), box.points, box.normals, beyond_tip, 0.05, 0.0).closed);
  EXPECT_EQ(close_jaws(g, max_jaw_angle(g), box.points, box.normals, beyond_tip, 0.05, 0.05).failure,
            "collision_close");
  EXPECT_TRUE(close_jaws(g, max_jaw_angle(g), box.points, box.normals, beyond_tip, 0.05, 0.02).closed);
}

TEST(Ranking, AlignmentThenEnclosingThenDistance) {
  const std::vector<Costs> costs{{0.10, 0.5, 0.30}, {0.20, 0.2, 0.10}, {0.90, 0.1, 0.00}, {0.15, 0.3, 0.05}};
  const RankingConfig rc{.keep_align = 3, .keep_enclose = 2, .output = 10};
  EXPECT_EQ(rank_hierarchically(costs, rc), (std::vector<std::size_t>{3, 1}));
}

TEST(Ranking, ClosestOrdersByEnclosingPlusDistance) {
  const std::vector<Costs> costs{{0.10, 0.5, 0.30}, {0.20, 0.2, 0.10}, {0.90, 0.1, 0.00}, {0.15, 0.3, 0.05}};
  EXPECT_EQ(rank_closest(costs), (std::vector<std::size_t>{2, 1, 3, 0}));
  RankingConfig rc{.method = "closest", .keep_align = 3, .keep_enclose = 2, .output = 10};
  EXPECT_EQ(rank_grasps(costs, rc), rank_closest(costs));
  EXPECT_DOUBLE_EQ(search_key(costs[0], rc), 0.8);
  rc.method = "hierarchical";
  EXPECT_EQ(rank_grasps(costs, rc), (std::vector<std::size_t>{3, 1}));
  EXPECT_DOUBLE_EQ(search_key(costs[0], rc), 0.10);
}

TEST(Ranking, CostsOfATopDownGrasp) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Vector3d(0, 0, 1);
  T.linear() << 0, 1, 0, 0, 0, -1, -1, 0, 0;  // x = -z (down), y = x_world... right-handed
  ASSERT_NEAR(T.linear().determinant(), 1.0, 1e-12);
  const Costs c = grasp_costs(T, Vector3d(0, 0.1, 0.5), Vector3d::UnitZ());
  EXPECT_NEAR(c.align, 0.0, 1e-9);
  EXPECT_NEAR(c.enclose, 0.5, 1e-9);
  EXPECT_NEAR(c.dist, 0.1, 1e-9);
}

/// A box stone on flat ground whose ground is unobserved within `hole` of it.
struct BoxOnGround {
  PointCloud map, object;
  explicit BoxOnGround(double hole = 0.0) {
    object = test::box_surface(Vector3d(0, 0, 0.25), Vector3d(0.4, 0.3, 0.25), 0.03, /*with_bottom=*/false);
    map = test::ground_square(3.5, 0.0, 0.03, hole);
    append(map, object);
  }
};

TEST(PlanningCloud, TheOccludedGroundIsFilledByThePlaneAndNeverInsideTheObject) {
  const BoxOnGround scene(/*hole=*/1.2);
  const PlanningCloudConfig cfg;
  const PlanningCloud pc = build_planning_cloud(scene.map, scene.object, nullptr, GripperConfig{}, cfg);
  ASSERT_TRUE(pc.ground.has_value());
  EXPECT_GT(pc.ground_normal.z(), 0.999);
  EXPECT_GT(pc.fill_points, 1000u);  // the hole: ~4.5 m^2 at 5 cm, partly under the box
  const KdTree tree(pc.cloud.points);
  for (std::size_t i = 0; i < pc.cloud.size(); ++i) {
    if (pc.cloud.labels[i] != kGroundFill) continue;
    const Vec3d p = pc.cloud.world(i);
    ASSERT_NEAR(p.z(), 0.0, 0.01);
  }
  for (double r = 0.5; r < 1.2; r += 0.1)  // every part of the hole now has ground points
    for (double a = 0; a < 2 * std::numbers::pi; a += 0.3) {
      const Vec3d q(r * std::cos(a), r * std::sin(a), 0.0);
      float d2 = 0;
      (void)tree.nearest((q - pc.cloud.origin).cast<float>(), &d2);
      ASSERT_LT(std::sqrt(d2), cfg.voxel) << q.transpose();
    }
  EXPECT_GT(pc.object_points, 200u);
}

// Undulating ground (8 cm waves, inside RANSAC's 10 cm band: one plane for all of it), unseen
// within 1.2 m of the box: the fill follows the seen ground next to it, the plane alone does not.
TEST(PlanningCloud, TheFillFollowsTheSeenGroundNextToIt) {
  const auto terrain = [](double x, double y) { return 0.08 * std::sin(1.3 * x + 0.4) * std::cos(0.9 * y); };
  BoxOnGround scene(/*hole=*/1.2);
  for (Vec3f& p : scene.map.points)
    if (p.z() == 0.0f) p.z() = float(terrain(p.x(), p.y()));
  PlanningCloudConfig plane_only, following;
  plane_only.fill_follows_ground = false;
  following.fill_follows_ground = true;
  const auto fill_error = [&](const PlanningCloudConfig& cfg, double within) {  // mean |z - terrain|
    const PlanningCloud pc = build_planning_cloud(scene.map, scene.object, nullptr, GripperConfig{}, cfg);
    double sum = 0.0;
    int n = 0;
    for (std::size_t i = 0; i < pc.cloud.size(); ++i) {
      const Vec3d p = pc.cloud.world(i);
      if (pc.cloud.labels[i] != kGroundFill || std::hypot(p.x(), p.y()) < 1.2 - within) continue;
      sum += std::abs(p.z() - terrain(p.x(), p.y()));
      ++n;
    }
    EXPECT_GT(n, 100);
    return sum / n;
  };
  const double plane_all = fill_error(plane_only, 1.2), follow_all = fill_error(following, 1.2);
  const double plane_rim = fill_error(plane_only, 0.25), follow_rim = fill_error(following, 0.25);
  std::printf("fill's mean height error: plane %.3f m (rim %.3f), following %.3f m (rim %.3f)\n", plane_all, plane_rim,
              follow_all, follow_rim);
  EXPECT_GT(plane_all, 0.02);
  EXPECT_LT(follow_all, 0.6 * plane_all);
  EXPECT_LT(follow_rim, 0.015);  // next to the seen ground: its height
}

// Normals (Sec. 5.2): on the object outwards from its centroid — a box's face normals on its
// faces' interiors — and the ground plane's normal on everything else.
TEST(PlanningCloud, ObjectNormalsPointOutwardsAndTheRestAlongTheGroundNormal) {
  const BoxOnGround scene;
  const PlanningCloud pc = build_planning_cloud(scene.map, scene.object, nullptr, GripperConfig{}, PlanningCloudConfig{});
  ASSERT_TRUE(pc.ground.has_value());
  ASSERT_EQ(pc.cloud.normals.size(), pc.cloud.size());
  int faces = 0;
  for (std::size_t i = 0; i < pc.cloud.size(); ++i) {
    const Vec3d p = pc.cloud.world(i);
    const Vec3d n = pc.cloud.normals[i].cast<double>();
    if (pc.cloud.labels[i] != kObject) {
      EXPECT_NEAR((n - pc.ground_normal).norm(), 0.0, 1e-6) << p.transpose();
      continue;
    }
    // Inside a face (away from the edges by more than the normal radius): the face's normal.
    const Vec3d local = p - Vec3d(0, 0, 0.25), half(0.4, 0.3, 0.25);
    const Vec3d depth = half - local.cwiseAbs();  // distance to each pair of faces
    int axis = 0;
    depth.minCoeff(&axis);
    Vec3d sorted = depth;
    std::sort(sorted.data(), sorted.data() + 3);
    if (sorted[1] < 0.2) continue;  // near an edge
    ++faces;
    EXPECT_GT(n[axis] * (local[axis] > 0 ? 1.0 : -1.0), 0.95) << p.transpose();
  }
  EXPECT_GT(faces, 50);
}

TEST(Planner, GraspsABoxFromAboveAcrossItsShortSide) {
  // The paper's hierarchical ranking (Sec. 5.4).
  const BoxOnGround scene;
  const GripperConfig g;
  GraspConfig config;
  config.ranking.method = "hierarchical";
  const GraspPlanning p = plan_grasps(scene.map, scene.object, nullptr, g, config);
  ASSERT_FALSE(p.grasps.empty());
  EXPECT_GT(p.counts.hypotheses, p.counts.force_closure);
  const Grasp& best = p.grasps.front();
  EXPECT_EQ(best.rank, 1);
  EXPECT_TRUE(best.force_closure);
  EXPECT_GE(best.robustness, 0.75);
  // From above, tilted: straight down the 1 m jaws would close through the ground beside a box
  // half their length tall (Eq. 5 ranks the least tilted first).
  EXPECT_LT(best.costs.align, 40.0 * kDeg);
  EXPECT_LT(best.costs.dist, 0.1);  // through the centroid (Eq. 7)
  EXPECT_LE(best.contact_angle, 0.0);  // converging jaws (ForceClosureConfig::max_contact_angle_deg)
  EXPECT_GT(best.contacts[0].z(), 0.0);      // on the box's sides, above the ground
  EXPECT_GT(best.contacts[1].z(), 0.0);
  const double across = (best.contacts[1] - best.contacts[0]).head<2>().norm();
  EXPECT_TRUE(std::abs(across - 0.6) < 0.06 || std::abs(across - 0.8) < 0.06) << across;
  // Collision-free: no map point inside the open gripper at the grasp pose.
  for (const ConvexPart& part : gripper_parts(g, best.opening))
    for (std::size_t i = 0; i < scene.map.size(); ++i)
      ASSERT_FALSE(part.contains(best.T_map_gripper.inverse() * scene.map.world(i))) << part.name;
  EXPECT_EQ(p.force_closure_costs.size(), p.counts.force_closure);
  EXPECT_LE(p.selected_costs.size(), std::size_t(GraspConfig{}.ranking.keep_enclose));
  for (std::size_t i = 1; i < p.grasps.size(); ++i)  // ordered by Eq. 7 after the two filters
    EXPECT_LE(p.grasps[i - 1].costs.dist, p.grasps[i].costs.dist);
}

TEST(Planner, ClosestRankingPutsThePalmNearTheCentreOfMass) {
  // The default ranking (beyond the paper): by c_enc + c_dist.
  const BoxOnGround scene;
  const GripperConfig g;
  const GraspConfig config;
  ASSERT_EQ(config.ranking.method, "closest");
  const GraspPlanning p = plan_grasps(scene.map, scene.object, nullptr, g, config);
  ASSERT_FALSE(p.grasps.empty());
  for (std::size_t i = 1; i < p.grasps.size(); ++i)
    EXPECT_LE(p.grasps[i - 1].costs.enclose + p.grasps[i - 1].costs.dist,
              p.grasps[i].costs.enclose + p.grasps[i].costs.dist + 1e-12);
  const Grasp& best = p.grasps.front();
  EXPECT_GE(best.robustness, 0.75);
  EXPECT_LT(best.costs.dist, 0.1);
  // The vertical family closes along the shortest horizontal extent (y) turned by its yaws.
  EXPECT_NEAR(std::abs(minor_horizontal_axis(p.cloud.cloud, Vector3d::UnitZ()).y()), 1.0, 1e-6);
}

TEST(Planner, RefusesAnEmptyObjectAndNonFinitePoints) {
  const BoxOnGround scene;
  EXPECT_THROW((void)plan_grasps(scene.map, PointCloud{}, nullptr, GripperConfig{}, GraspConfig{}), InputError);
  PointCloud bad = scene.map;
  bad.points[5].x() = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THROW((void)plan_grasps(bad, scene.object, nullptr, GripperConfig{}, GraspConfig{}), InputError);
  GraspConfig c;
  c.candidates.samples = 0;
  EXPECT_THROW((void)plan_grasps(scene.map, scene.object, nullptr, GripperConfig{}, c), ConfigError);
  c = GraspConfig{};
  c.ranking.method = "best";
  EXPECT_THROW((void)plan_grasps(scene.map, scene.object, nullptr, GripperConfig{}, c), ConfigError);
  c = GraspConfig{};
  c.candidates.backoff_voxels = {};
  EXPECT_THROW((void)plan_grasps(scene.map, scene.object, nullptr, GripperConfig{}, c), ConfigError);
}

/// GPD's tutorial cloud (a Krylon spray can, ~6 cm across, 11 cm tall, a partial view) with the
/// gripper scaled to GPD's hand size (x 0.06: jaws 6 cm, pivots 8.4 cm apart) and a 3 mm voxel:
/// every length of the planner follows.
TEST(RealPartialViews, GraspsGpdsKrylonCanWithAScaledGripper) {
  CAIRN_REQUIRE_REAL_DATA("gpd-tutorial/krylon.pcd");
  const PointCloud can = io::load_cloud(test::real_data("gpd-tutorial/krylon.pcd"));
  constexpr double kScale = 0.06;
  GripperConfig g;
  for (double* v : {&g.palm_depth, &g.palm_width, &g.palm_height, &g.hinge_spacing, &g.jaw_length, &g.jaw_thickness,
                    &g.jaw_height, &g.closed_gap, &g.tcp_depth})
    *v *= kScale;
  GraspConfig c;
  c.cloud.voxel = 0.003;
  const GraspPlanning p = plan_grasps(can, can, nullptr, g, c);
  ASSERT_FALSE(p.grasps.empty()) << p.counts.hypotheses << " hypotheses, " << p.counts.force_closure << " in force closure";
  const Aabb box = bounds(can.points);
  const double diameter = std::min(box.max.x() - box.min.x(), box.max.y() - box.min.y());
  const KdTree tree(can.points);
  for (const Grasp& gr : p.grasps) {
    EXPECT_TRUE(gr.force_closure);
    EXPECT_LT(gr.closed_opening, max_opening(g));
    for (const auto& contact : gr.contacts) {  // on the can's surface
      float d2 = 0;
      (void)tree.nearest((contact - can.origin).cast<float>(), &d2);
      EXPECT_LT(std::sqrt(d2), 3.0 * c.cloud.voxel);
    }
    // Across the can: the contacts lie about a diameter apart (or across its 11 cm length).
    const double span = (gr.contacts[1] - gr.contacts[0]).norm();
    EXPECT_GT(span, 0.5 * diameter);
    EXPECT_LT(span, 1.3 * (box.max - box.min).norm());
  }
}

}  // namespace
}  // namespace cairn::grasp
