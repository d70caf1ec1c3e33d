// Map and object updates under manipulation (Sec. 4.5): Eq. 3 on known transforms, the grasp's map
// edit (object voxels vs the paper's sphere) on a hand-made scene, re-alignment after release,
// and association of a re-segmentation (matched, moved/bumped, new, vanished).
#include <gtest/gtest.h>

#include <numbers>

#include "cairn/core/error.hpp"
#include "cairn/core/kdtree.hpp"
#include "cairn/core/transform.hpp"
#include "cairn/mapping/local_map.hpp"
#include "cairn/objects/association.hpp"
#include "cairn/objects/updates.hpp"
#include "scene.hpp"
#include "support/poses.hpp"

namespace cairn {
namespace {

using Eigen::Isometry3d;

using test::pose;

ObjectRecord record(std::int64_t id, PointCloud cloud, ObjectStatus status = ObjectStatus::on_ground) {
  ObjectRecord r;
  r.id = id;
  r.status = status;
  r.centroid = cloud.origin + centroid(cloud.points).cast<double>();
  r.num_points = cloud.size();
  r.cloud = std::move(cloud);
  return r;
}

PointCloud moved(PointCloud c, const Isometry3d& T) {
  transform_cloud(c, T);
  return c;
}

/// Share of `part`'s points that are no longer in `map` (exact positions).
double share_removed(const PointCloud& part, const PointCloud& map) {
  const PointCloud local = moved(part, pure_translation(-map.origin.x(), -map.origin.y(), -map.origin.z()));
  const KdTree tree(map.points);
  std::size_t gone = 0;
  for (std::size_t i = 0; i < local.size(); ++i) {
    float d2 = 0;
    (void)tree.nearest((local.origin + local.points[i].cast<double>()).cast<float>(), &d2);
    gone += d2 > 1e-8f;
  }
  return double(gone) / double(part.size());
}

TEST(ObjectUpdates, Eq3MovesTheObjectWithTheGripper) {
  const Isometry3d grasp = pose(3.0, 1.0, 1.5, 0.3, 0.2);
  const Isometry3d release = pose(-2.0, 4.0, 1.2, 1.9, -0.1);
  const Isometry3d T = release_transform(grasp, release);
  // A point fixed in the gripper frame goes where the gripper took it.
  const Vec3d in_gripper(0.1, -0.2, -0.6);
  EXPECT_LT((T * (grasp * in_gripper) - release * in_gripper).norm(), 1e-12);
  EXPECT_TRUE(release_transform(grasp, grasp).isApprox(Isometry3d::Identity(), 1e-12));
  // Applied to the stored cloud and centroid by the release operation.
  const ObjectRecord held = [&] {
    ObjectRecord r = record(4, test::stone(Vec3d(3.0, 1.0, 0.3), 0.3), ObjectStatus::grasped);
    r.T_map_gripper_grasp = grasp;
    return r;
  }();
  const Operation op = release_operation(held, release, 10.0);
  ASSERT_EQ(op.changes.size(), 1u);
  const PointCloud& c = *op.changes[0].cloud;
  for (std::size_t i = 0; i < c.size(); i += 97) EXPECT_LT((c.world(i) - T * held.cloud.world(i)).norm(), 1e-5);
  EXPECT_EQ(op.changes[0].status, ObjectStatus::placed);
  EXPECT_EQ(op.changes[0].cause, PoseCause::release);
}

TEST(ObjectUpdates, GraspRemovesTheObjectsVoxelsNotItsNeighboursOrTheGround) {
  // A stone with a neighbour 10 cm away, on ground: the paper's 1 m sphere takes all three. The
  // ground under the stones (within 25 cm of their centres) is hidden from the sensors.
  const PointCloud a = test::stone(Vec3d(0.0, 0.0, 0.3), 0.3);
  const PointCloud b = test::stone(Vec3d(0.7, 0.0, 0.3), 0.3);
  const ObjectRecord obj = record(1, a);
  GraspRemovalConfig voxels;  // defaults: object_voxels
  GraspRemovalConfig sphere;
  sphere.method = "sphere";
  PointCloud g, ground_in_sphere;
  {
    const PointCloud grid = test::ground(0.0, 0.0, 2.0);
    std::vector<std::uint32_t> seen, in_sphere;
    for (std::size_t i = 0; i < grid.size(); ++i) {
      const Vec3d p = grid.world(i);
      if (p.head<2>().norm() < 0.25 || (p.head<2>() - Eigen::Vector2d(0.7, 0.0)).norm() < 0.25) continue;
      seen.push_back(std::uint32_t(i));
      if ((p - obj.centroid).norm() <= sphere.R_obj) in_sphere.push_back(std::uint32_t(i));
    }
    g = select(grid, seen);
    ground_in_sphere = select(grid, in_sphere);
  }
  PointCloud map = g;
  append(map, a);
  append(map, b);
  PointCloud by_voxels = map, by_sphere = map;
  (void)apply_edit(by_voxels, grasp_map_edit(obj, voxels));
  (void)apply_edit(by_sphere, grasp_map_edit(obj, sphere));
  EXPECT_EQ(share_removed(a, by_voxels), 1.0);
  EXPECT_EQ(share_removed(b, by_voxels), 0.0);
  EXPECT_LT(share_removed(ground_in_sphere, by_voxels), 0.01);  // only right at the contact
  EXPECT_EQ(share_removed(a, by_sphere), 1.0);
  EXPECT_GT(share_removed(b, by_sphere), 0.5);
  EXPECT_EQ(share_removed(ground_in_sphere, by_sphere), 1.0);
  // The streaming map applies the same edit to its voxels: the same voxels as on its snapshot.
  LocalMapConfig raw;
  raw.smoothing_radius = 0.0;
  LocalMap local(raw);
  local.insert(map);
  PointCloud snapshot = local.snapshot();
  const std::size_t on_snapshot = apply_edit(snapshot, grasp_map_edit(obj, voxels));
  EXPECT_GT(on_snapshot, 0u);
  EXPECT_EQ(local.apply(grasp_map_edit(obj, voxels)), on_snapshot);
  EXPECT_EQ(local.num_voxels(), snapshot.size());
}

TEST(ObjectUpdates, RealignFindsTheReleasedStoneReportsARollAndLosesAMissingOne) {
  const Vec3d where(5.0, 2.0, 0.35);
  const Vec3d axes(0.6, 0.35, 0.3);
  const PointCloud truth = test::ellipsoid(where, axes);
  PointCloud map = test::ground(5.0, 2.0, 2.0);
  {  // The map sees the upper 70 % of the stone.
    std::vector<std::uint32_t> top;
    for (std::size_t i = 0; i < truth.size(); ++i)
      if (truth.world(i).z() > where.z() - 0.15) top.push_back(std::uint32_t(i));
    append(map, select(truth, top));
  }
  const RealignConfig cfg;
  // Predicted 3.6 cm and 3 deg off (the state estimate's drift): found, corrected to within 1 cm,
  // not reported.
  const Isometry3d err = Eigen::Translation3d(where) * pose(0.03, -0.02, 0.0, 3.0 * std::numbers::pi / 180) *
                         Eigen::Translation3d(-where);
  const ObjectRecord predicted = record(3, moved(truth, err), ObjectStatus::placed);
  const RealignResult r = realign_object(predicted, map, cfg);
  ASSERT_TRUE(r.found) << r.reason;
  EXPECT_FALSE(r.large) << r.reason;
  const PointCloud fixed = moved(predicted.cloud, r.correction);
  for (std::size_t i = 0; i < fixed.size(); i += 50) EXPECT_LT((fixed.world(i) - truth.world(i)).norm(), 0.01);
  const Operation op = realign_operation(predicted, r, 20.0);
  EXPECT_EQ(op.changes[0].cause, PoseCause::realign);
  EXPECT_EQ(op.changes[0].status, ObjectStatus::placed);
  // Predicted 20 cm off (it rolled): found and reported.
  const Isometry3d roll = Eigen::Translation3d(where) * pose(0.2, 0.0, 0.0, 0.0) * Eigen::Translation3d(-where);
  const RealignResult rolled = realign_object(record(3, moved(truth, roll), ObjectStatus::placed), map, cfg);
  EXPECT_TRUE(rolled.found) << rolled.reason;
  EXPECT_TRUE(rolled.large);
  EXPECT_NE(rolled.reason.find("fell or rolled"), std::string::npos) << rolled.reason;
  // Not there at all (only ground): lost, with the reason; the cloud stays.
  const RealignResult gone = realign_object(predicted, test::ground(5.0, 2.0, 2.0), cfg);
  EXPECT_FALSE(gone.found);
  EXPECT_NE(gone.reason.find("not found"), std::string::npos) << gone.reason;
  const Operation lost = realign_operation(predicted, gone, 21.0);
  EXPECT_EQ(lost.changes[0].status, ObjectStatus::lost);
  EXPECT_FALSE(lost.changes[0].cloud.has_value());
}

/// An egg lying on the ground with its long axis along x (one end 1.8x longer: no symmetry),
/// sampled with n points over the whole surface, moved by T; the points above the ground (z > 2 cm).
PointCloud egg(const Isometry3d& T, int n) {
  PointCloud s = test::ellipsoid(Vec3d(0, 0, 0.25), Vec3d(0.35, 0.3, 0.25), n);
  for (Vec3f& p : s.points)
    if (p.x() + s.origin.x() > 0) p.x() = float((p.x() + s.origin.x()) * 1.8 - s.origin.x());
  const PointCloud m = moved(s, T);
  std::vector<std::uint32_t> seen;
  for (std::size_t i = 0; i < m.size(); ++i)
    if (m.world(i).z() > 0.02) seen.push_back(std::uint32_t(i));
  return select(m, seen);
}

TEST(ObjectUpdates, TheSearchFindsAFallenStoneAndNeverTakesAnotherObjectsSegment) {
  // Object 1 was released at (5, 2), lying, and fell 1.2 m away onto its blunt end; object 2, a
  // stone of the same shape lying as object 1 was released, is 1.25 m the other way. Both are
  // within the search radius.
  const Isometry3d released = Eigen::Translation3d(5.0, 2.0, 0.0) * Isometry3d::Identity();
  const Isometry3d fell = Eigen::Translation3d(6.2, 2.0, 0.3) *
                          Eigen::AngleAxisd(-0.5 * std::numbers::pi, Eigen::Vector3d::UnitY()) *
                          Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitX()) * Eigen::Translation3d(0, 0, -0.25);
  const Isometry3d neighbour = Eigen::Translation3d(3.8, 2.35, 0.0) * Eigen::AngleAxisd(1.2, Eigen::Vector3d::UnitZ());
  // The stored model is sampled every ~6 cm (500 points; the map's objects ~5 cm), the map sees the
  // surfaces densely.
  const ObjectRecord stone = record(1, egg(released, 500), ObjectStatus::placed);
  const ObjectRecord other = record(2, egg(neighbour, 2000), ObjectStatus::on_ground);
  const PointCloud fallen = egg(fell, 2000);
  PointCloud map = test::ground(5.0, 2.0, 2.6, 0.04);  // the search's reach: model radius + 2 m
  append(map, fallen);
  append(map, other.cloud);
  const ObjectsConfig cfg;
  const SegmentationConfig seg;
  ASSERT_FALSE(realign_object(stone, map, cfg.realign).found);  // nothing where it was released

  // Searched with the other objects: found where it fell, the model laid onto the fallen stone.
  const RealignResult r = relocate_object(stone, map, {stone, other}, cfg, seg);
  ASSERT_TRUE(r.found) << r.reason;
  EXPECT_TRUE(r.large);
  const Vec3d truth = fell * released.inverse() * stone.centroid;  // where the model's centroid went
  EXPECT_LT((r.correction * stone.centroid - truth).norm(), 0.05) << r.reason;

  // Without knowing object 2, the search takes its segment, the better fit of a model posed as
  // it: the duplicate the exclusion prevents. A lost object claims nothing (its cloud is where it
  // was, not where it is), nor one the map no longer shows where its cloud is.
  const RealignResult blind = relocate_object(stone, map, {}, cfg, seg);
  ASSERT_TRUE(blind.found) << blind.reason;
  EXPECT_LT((blind.correction * stone.centroid - neighbour * released.inverse() * stone.centroid).norm(), 0.05)
      << blind.reason;
  ObjectRecord lost = other;
  lost.status = ObjectStatus::lost;
  const RealignResult unclaimed = relocate_object(stone, map, {lost}, cfg, seg);
  EXPECT_TRUE(unclaimed.found) << unclaimed.reason;
  EXPECT_TRUE(unclaimed.correction.isApprox(blind.correction)) << unclaimed.reason;
  ObjectRecord elsewhere = other;
  transform_cloud(elsewhere.cloud, Eigen::Translation3d(0.0, 0.6, 0.0) * Isometry3d::Identity());
  const RealignResult stale = relocate_object(stone, map, {elsewhere}, cfg, seg);
  EXPECT_TRUE(stale.correction.isApprox(blind.correction)) << stale.reason;

  // The sampling alone puts the right fit above the near-prediction limit (association.max_rmse:
  // 2.3 cm for 97 % of the segment on the model); the search's own limit accepts it, a limit below
  // refuses, with the reason.
  ObjectsConfig strict = cfg;
  strict.realign.search_max_rmse = cfg.association.max_rmse;
  const RealignResult refused = relocate_object(stone, map, {stone, other}, strict, seg);
  EXPECT_FALSE(refused.found);
  EXPECT_NE(refused.reason.find("segments of objects 2 not tried"), std::string::npos) << refused.reason;
}

TEST(ObjectUpdates, TheSearchTakesTheStonesOwnSegmentWhereItsStaleCloudLies) {
  // Released lying at (5, 2), the stone turned 69 deg about the vertical where it lay: not found
  // from the prediction, and its stored cloud, still mostly on map points, covers most of its new
  // segment. The stone owns no segment itself: the search finds it (counted as its own owner,
  // it would be lost).
  const Isometry3d released = Eigen::Translation3d(5.0, 2.0, 0.0) * Isometry3d::Identity();
  const Isometry3d turned = Eigen::Translation3d(5.0, 2.0, 0.0) * Eigen::AngleAxisd(1.2, Eigen::Vector3d::UnitZ());
  const ObjectRecord stone = record(1, egg(released, 2000), ObjectStatus::placed);
  const PointCloud now = egg(turned, 2000);
  PointCloud map = test::ground(5.0, 2.0, 2.6, 0.04);
  append(map, now);
  const ObjectsConfig cfg;
  ASSERT_FALSE(realign_object(stone, map, cfg.realign).found);
  const RealignResult r = relocate_object(stone, map, {stone}, cfg, SegmentationConfig{});
  ASSERT_TRUE(r.found) << r.reason;
  const Vec3d truth = turned * released.inverse() * stone.centroid;
  EXPECT_LT((r.correction * stone.centroid - truth).norm(), 0.05) << r.reason;
}

TEST(ObjectAssociation, MatchedMovedNewAndVanished) {
  // Stored: four stones. Rescan: stone 1 where it was, stone 2 bumped 40 cm and turned 30 deg,
  // stone 3 gone (ground visible), stone 4 out of the map; plus a new stone.
  const Vec3d axes(0.5, 0.3, 0.25);
  const PointCloud s1 = test::ellipsoid(Vec3d(0, 0, 0.25), axes);
  const PointCloud s2 = test::ellipsoid(Vec3d(2.0, 0, 0.25), axes);
  const PointCloud s3 = test::ellipsoid(Vec3d(0, 2.0, 0.25), axes);
  const PointCloud s4 = test::ellipsoid(Vec3d(30, 0, 0.25), axes);
  const PointCloud s5 = test::stone(Vec3d(-2.0, -1.0, 0.3), 0.3);
  const std::vector<ObjectRecord> db = {record(1, s1), record(2, s2), record(3, s3), record(4, s4)};
  const Isometry3d bump = Eigen::Translation3d(2.3, 0.2, 0.25) * pose(0, 0, 0, 30.0 * std::numbers::pi / 180) *
                          Eigen::Translation3d(-2.0, 0.0, -0.25);
  auto top = [](const PointCloud& c) {  // what the LiDAR sees: the upper part
    std::vector<std::uint32_t> k;
    for (std::size_t i = 0; i < c.size(); ++i)
      if (c.world(i).z() > 0.15) k.push_back(std::uint32_t(i));
    return select(c, k);
  };
  const std::vector<PointCloud> segments = {top(s1), top(moved(s2, bump)), top(s5)};
  PointCloud map = test::ground(0.0, 0.0, 4.0);
  for (const PointCloud& s : segments) append(map, s);
  const Association a = associate(segments, db, map, AssociationConfig{});
  ASSERT_EQ(a.matched.size(), 1u);
  EXPECT_EQ(a.matched[0], (std::pair<std::size_t, std::int64_t>(0, 1)));
  ASSERT_EQ(a.moved.size(), 1u);
  EXPECT_EQ(a.moved[0].id, 2);
  EXPECT_EQ(a.moved[0].segment, 1u);
  const Vec3d c2 = db[1].centroid;
  EXPECT_LT((a.moved[0].motion * c2 - bump * c2).norm(), 0.02);
  EXPECT_LT(rotation_angle(a.moved[0].motion.linear() * bump.linear().transpose()) * 180 / std::numbers::pi, 1.0);
  EXPECT_EQ(a.new_segments, std::vector<std::size_t>{2});
  EXPECT_EQ(a.vanished, std::vector<std::int64_t>{3});
  EXPECT_EQ(a.out_of_view, std::vector<std::int64_t>{4});
  // Stored as one operation: one new object, stone 2 moved, stone 3 lost; nothing duplicated.
  const Operation op = association_operation(a, segments, db, 30.0, "segmentation");
  ASSERT_EQ(op.changes.size(), 3u);
  EXPECT_EQ(op.changes[0].id, 2);
  EXPECT_EQ(op.changes[0].cause, PoseCause::reassociated);
  EXPECT_EQ(op.changes[1].id, 3);
  EXPECT_EQ(op.changes[1].status, ObjectStatus::lost);
  EXPECT_EQ(op.changes[2].id, 0);
  // A second rescan of the same scene after storing: everything matched, nothing new.
  std::vector<ObjectRecord> after = db;
  after[1].cloud = *op.changes[0].cloud;
  after[1].centroid = after[1].cloud.origin + centroid(after[1].cloud.points).cast<double>();
  after[2].status = ObjectStatus::lost;
  after.push_back(record(5, segments[2]));
  const Association again = associate(segments, after, map, AssociationConfig{});
  EXPECT_EQ(again.matched.size(), 3u);
  EXPECT_TRUE(again.new_segments.empty());
  EXPECT_TRUE(again.moved.empty());
  EXPECT_EQ(association_operation(again, segments, after, 31.0, "segmentation").changes.size(), 0u);
}

// A stone lost after a failed grasp may have fallen over and rolled far (issue #18: the slipped
// stone of exp1 was found "moved 1.24 m, turned 78.1 deg"): the re-segmentation tries a lost
// object's model at any distance (and from every face down) and finds it again, here stood on its
// end. The same stone not marked lost is searched for only within search_radius: not found.
// (The 90-degree turn is reached by ICP from the 8 upright yaws too: this test proves the lost
// object's unlimited search distance, not the face-down starts.)
TEST(ObjectAssociation, ALostStoneThatRolledOntoItsSideIsFoundAgain) {
  // An egg (one end longer: no symmetry), seen from all sides, stood on its blunt end.
  PointCloud s = test::ellipsoid(Vec3d(0, 0, 0.25), Vec3d(0.35, 0.3, 0.25));
  for (Vec3f& p : s.points)
    if (p.x() + s.origin.x() > 0) p.x() = float((p.x() + s.origin.x()) * 1.8 - s.origin.x());
  const Isometry3d roll = Eigen::Translation3d(4.0, 1.5, 0.35) *
                          Eigen::AngleAxisd(-0.5 * std::numbers::pi, Eigen::Vector3d::UnitY()) *
                          Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitX()) * Eigen::Translation3d(0, 0, -0.25);
  ASSERT_GT((roll * Vec3d(0, 0, 0.25)).head<2>().norm(), AssociationConfig{}.search_radius);
  std::vector<std::uint32_t> top;  // what the LiDAR sees of the rolled stone: its upper part
  const PointCloud rolled = moved(s, roll);
  for (std::size_t i = 0; i < rolled.size(); ++i)
    if (rolled.world(i).z() > 0.2) top.push_back(std::uint32_t(i));
  const std::vector<PointCloud> segments = {select(rolled, top)};
  PointCloud map = test::ground(2.0, 0.0, 5.0);
  append(map, segments[0]);
  const std::vector<ObjectRecord> lost = {record(7, s, ObjectStatus::lost)};
  const Association a = associate(segments, lost, map, AssociationConfig{});
  ASSERT_EQ(a.moved.size(), 1u);
  EXPECT_EQ(a.moved[0].id, 7);
  // The found pose lays the model onto the rolled stone (the ellipsoid's symmetries aside).
  const PointCloud found = moved(s, a.moved[0].motion);
  const KdTree tree(rolled.points);
  double worst = 0.0;
  for (std::size_t i = 0; i < found.size(); ++i) {
    float d2 = 0;
    (void)tree.nearest((found.world(i) - rolled.origin).cast<float>(), &d2);
    worst = std::max(worst, double(std::sqrt(d2)));
  }
  EXPECT_LT(worst, 0.03);
  const Operation op = association_operation(a, segments, lost, 40.0, "segmentation");
  ASSERT_EQ(op.changes.size(), 1u);
  EXPECT_EQ(op.changes[0].status, ObjectStatus::on_ground);
  EXPECT_EQ(op.changes[0].cause, PoseCause::reassociated);
  EXPECT_NE(op.changes[0].reason.find("found again"), std::string::npos) << op.changes[0].reason;
  // Not lost: searched upright within search_radius only; the segment becomes a new object.
  const Association b = associate(segments, {record(7, s)}, map, AssociationConfig{});
  EXPECT_TRUE(b.moved.empty());
  EXPECT_EQ(b.new_segments, std::vector<std::size_t>{0});
}

}  // namespace
}  // namespace cairn
