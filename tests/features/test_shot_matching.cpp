// SHOT descriptors and descriptor matching (Sec. 4.4 steps 2-3) on synthetic shapes.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numeric>

#include "cairn/core/error.hpp"
#include "cairn/core/normals.hpp"
#include "cairn/features/iss.hpp"
#include "cairn/features/matching.hpp"
#include "cairn/features/shot.hpp"
#include "shapes.hpp"

using namespace cairn;

namespace {

/// A bumpy stone surface with outward normals, its ISS keypoints, and the same rigidly moved.
struct Scene {
  std::vector<Vec3f> points, normals, keypoints;
};

Scene stone(std::uint32_t seed) {
  Scene s;
  s.points = test::bumpy_surface(30000, seed);
  const KdTree tree(s.points);
  s.normals = estimate_normals(s.points, tree, {.k = 15}).normals;
  for (std::size_t i = 0; i < s.points.size(); ++i)
    if (s.normals[i].dot(s.points[i]) < 0) s.normals[i] = -s.normals[i];  // outward
  for (auto i : iss_keypoints(s.points, tree, {})) s.keypoints.push_back(s.points[i]);
  return s;
}

Scene moved(const Scene& s, const Eigen::Isometry3d& T) {
  return {test::transformed(s.points, T), test::rotated(s.normals, T.linear()), test::transformed(s.keypoints, T)};
}

ShotDescriptors describe(const Scene& s, double radius = 0.10) {
  const KdTree tree(s.points);
  return compute_shot(s.keypoints, s.points, s.normals, tree, {.radius = radius});
}

ShotDescriptors hand_made(const std::vector<std::vector<std::pair<int, float>>>& rows) {
  ShotDescriptors d;
  d.data.assign(rows.size() * kShotSize, 0.0f);
  d.lrf.assign(rows.size(), Eigen::Matrix3f::Identity());
  d.valid.assign(rows.size(), 1);
  for (std::size_t i = 0; i < rows.size(); ++i)
    for (auto [bin, v] : rows[i]) d.data[i * kShotSize + std::size_t(bin)] = v;
  return d;
}

}  // namespace

TEST(Shot, InvariantToRigidMotion) {
  const Scene a = stone(5);
  ASSERT_GT(a.keypoints.size(), 30u);
  const Eigen::Isometry3d T = test::make_pose(0.7, -0.4, 2.1, {3.0, -1.0, 0.5});
  const Scene b = moved(a, T);
  const ShotDescriptors da = describe(a), db = describe(b);
  ASSERT_EQ(da.size(), db.size());
  std::size_t compared = 0, within = 0;
  double worst = 0.0;
  for (std::size_t i = 0; i < da.size(); ++i) {
    ASSERT_EQ(da.valid[i], db.valid[i]);
    if (!da.valid[i]) continue;
    ++compared;
    double m = 0.0;
    for (int k = 0; k < kShotSize; ++k) m = std::max(m, double(std::abs(da.descriptor(i)[k] - db.descriptor(i)[k])));
    worst = std::max(worst, m);
    within += m <= 1e-4;
    // The LRF turns with the object.
    const Eigen::Matrix3f expected = da.lrf[i] * T.linear().transpose().cast<float>();
    EXPECT_LT((db.lrf[i] - expected).cwiseAbs().maxCoeff(), 1e-4f) << "keypoint " << i;
  }
  std::cout << "[ SHOT     ] " << within << " of " << compared << " descriptors within 1e-4 after a rigid motion, worst "
            << worst << "\n";
  EXPECT_EQ(compared, da.size());
  // A neighbour exactly on a bin border may fall on the other side after the motion (float
  // rounding); allow 2 % of the keypoints to differ by more.
  EXPECT_GE(double(within), 0.98 * double(compared));
}

TEST(Shot, UnitNormAndNonNegative) {
  const ShotDescriptors d = describe(stone(6));
  ASSERT_GT(d.num_valid(), 0u);
  for (std::size_t i = 0; i < d.size(); ++i) {
    if (!d.valid[i]) continue;
    double sq = 0.0;
    for (float v : d.descriptor(i)) {
      EXPECT_GE(v, -1e-6f);
      sq += double(v) * v;
    }
    EXPECT_NEAR(std::sqrt(sq), 1.0, 1e-5);
  }
}

TEST(Shot, InvalidWithTooFewNeighbours) {
  const Scene s = stone(7);
  const KdTree tree(s.points);
  std::vector<Vec3f> kp = {s.points[0], Vec3f(10, 10, 10), s.points[100]};
  // A keypoint with only 4 surface points around it: too few for the LRF.
  std::vector<Vec3f> sparse = {Vec3f(0, 0, 0), Vec3f(0.01f, 0, 0), Vec3f(0, 0.01f, 0), Vec3f(0, 0, 0.01f),
                               Vec3f(0.01f, 0.01f, 0)};
  const std::vector<Vec3f> sparse_normals(sparse.size(), Vec3f::UnitZ());
  const KdTree sparse_tree(sparse);
  const ShotDescriptors few = compute_shot(std::vector<Vec3f>{Vec3f(0, 0, 0)}, sparse, sparse_normals, sparse_tree, {});
  ASSERT_EQ(few.size(), 1u);
  EXPECT_EQ(few.valid[0], 0);  // 4 neighbours besides the keypoint itself
  EXPECT_TRUE(std::isnan(few.descriptor(0)[0]));

  const ShotDescriptors d = compute_shot(kp, s.points, s.normals, tree, {});
  EXPECT_EQ(d.valid[0], 1);
  EXPECT_EQ(d.valid[1], 0);  // nothing within the radius
  EXPECT_EQ(d.valid[2], 1);
  EXPECT_EQ(d.num_valid(), 2u);
  // Without any normal the histogram is empty: invalid.
  const std::vector<Vec3f> no_normals(s.points.size(), Vec3f::Zero());
  const ShotDescriptors none = compute_shot(kp, s.points, no_normals, tree, {});
  EXPECT_EQ(none.num_valid(), 0u);
}

TEST(Shot, RejectsBadInput) {
  const Scene s = stone(8);
  const KdTree tree(s.points);
  EXPECT_THROW((void)compute_shot(s.keypoints, s.points, s.normals, tree, {.radius = 0.0}), ConfigError);
  const std::vector<Vec3f> short_normals(10, Vec3f::UnitZ());
  EXPECT_THROW((void)compute_shot(s.keypoints, s.points, short_normals, tree, {}), InputError);
  EXPECT_EQ(compute_shot({}, s.points, s.normals, tree, {}).size(), 0u);
}

TEST(Matching, FindsPartnersInRotatedCopy) {
  const Scene a = stone(9);
  const Scene b = moved(a, test::make_pose(-0.3, 1.2, 0.4, {0.2, 0.1, -2.0}));
  const ShotDescriptors da = describe(a), db = describe(b);
  const auto m = match_descriptors(da, db, {});
  std::size_t right = 0;
  for (const auto& c : m) {
    right += c.source == c.target;
    EXPECT_LT(c.squared_distance, 0.25f);
  }
  std::cout << "[ MATCH    ] " << right << " of " << m.size() << " matches to the moved copy are the same keypoint\n";
  EXPECT_EQ(m.size(), da.num_valid());
  EXPECT_GE(double(right), 0.98 * double(m.size()));
  // Ascending source order.
  for (std::size_t i = 1; i < m.size(); ++i) EXPECT_LT(m[i - 1].source, m[i].source);
}

TEST(Matching, ScanEqualsKdTree) {
  const Scene a = stone(10), b = stone(11);  // two different stones: few, far matches
  const ShotDescriptors da = describe(a), db = describe(b);
  for (const double threshold : {0.05, 0.25, 4.0}) {
    for (const bool mutual : {false, true}) {
      const auto scan = match_descriptors(da, db, {.max_squared_distance = threshold, .mutual = mutual});
      const auto tree =
          match_descriptors(da, db, {.max_squared_distance = threshold, .mutual = mutual, .search = "kdtree"});
      ASSERT_EQ(scan.size(), tree.size()) << threshold << " " << mutual;
      for (std::size_t i = 0; i < scan.size(); ++i) {
        EXPECT_EQ(scan[i].source, tree[i].source);
        EXPECT_EQ(scan[i].target, tree[i].target);
        EXPECT_EQ(scan[i].squared_distance, tree[i].squared_distance);
      }
      if (threshold == 4.0 && !mutual) {
        EXPECT_EQ(scan.size(), da.num_valid());
      }
    }
  }
  EXPECT_THROW((void)match_descriptors(da, db, {.search = "flann"}), ConfigError);
}

TEST(Matching, ThresholdIsStrictAndSquared) {
  // Source 0 is at squared distance 0.16 from target 0, source 1 at 0.36 from target 1.
  const ShotDescriptors src = hand_made({{{0, 1.0f}}, {{5, 1.0f}}});
  const ShotDescriptors tgt = hand_made({{{0, 0.6f}}, {{5, 0.4f}}});
  const auto m = match_descriptors(src, tgt, {});
  ASSERT_EQ(m.size(), 1u);
  EXPECT_EQ(m[0].source, 0u);
  EXPECT_EQ(m[0].target, 0u);
  EXPECT_NEAR(m[0].squared_distance, 0.16f, 1e-6f);
  EXPECT_EQ(match_descriptors(src, tgt, {.max_squared_distance = 0.5}).size(), 2u);
  EXPECT_TRUE(match_descriptors(src, tgt, {.max_squared_distance = 0.16f}).size() <= 1u);
  EXPECT_TRUE(match_descriptors(src, tgt, {.max_squared_distance = 0.1}).empty());
}

TEST(Matching, MutualAndInvalid) {
  // Sources 0 and 1 both have target 0 as nearest; target 0's nearest is source 1.
  const ShotDescriptors src = hand_made({{{0, 0.5f}}, {{0, 0.9f}}, {{7, 1.0f}}});
  ShotDescriptors tgt = hand_made({{{0, 1.0f}}, {{7, 1.0f}}, {{9, 1.0f}}});
  const auto all = match_descriptors(src, tgt, {.max_squared_distance = 1.0});
  ASSERT_EQ(all.size(), 3u);
  EXPECT_EQ(all[0].target, 0u);
  EXPECT_EQ(all[1].target, 0u);
  const auto mutual = match_descriptors(src, tgt, {.max_squared_distance = 1.0, .mutual = true});
  ASSERT_EQ(mutual.size(), 2u);
  EXPECT_EQ(mutual[0].source, 1u);
  EXPECT_EQ(mutual[1].source, 2u);
  // Invalid target descriptors are never matched, invalid sources never queried.
  tgt.valid[1] = 0;
  ShotDescriptors src2 = src;
  src2.valid[0] = 0;
  const auto m = match_descriptors(src2, tgt, {.max_squared_distance = 10.0});
  ASSERT_EQ(m.size(), 2u);
  EXPECT_EQ(m[0].source, 1u);
  EXPECT_NE(m[1].target, 1u);
  EXPECT_TRUE(match_descriptors(src, ShotDescriptors{}, {}).empty());
  EXPECT_THROW((void)match_descriptors(src, tgt, {.max_squared_distance = 0.0}), ConfigError);
}
