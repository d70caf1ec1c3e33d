// NaN and infinite points in the kernels (issue #20 item 6): a cloud with such points mixed in
// gives the kd-tree, the voxel grid, the normals, ISS and SHOT exactly the answers of the same
// cloud without them — they are never found, belong to no voxel, get no normal — and no integer
// is ever made of a NaN (the sanitizer build checks float-cast-overflow).
#include <gtest/gtest.h>

#include <algorithm>
#include <limits>

#include "cairn/core/kdtree.hpp"
#include "cairn/core/normals.hpp"
#include "cairn/core/voxel_grid.hpp"
#include "cairn/features/iss.hpp"
#include "cairn/features/shot.hpp"
#include "shapes.hpp"

namespace cairn {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr float kInf = std::numeric_limits<float>::infinity();

/// The clean surface and the same with a non-finite point after every 97th: `index[i]` is where
/// clean point i went.
struct Dirty {
  std::vector<Vec3f> clean, dirty;
  std::vector<std::uint32_t> index;
};

Dirty dirty_surface() {
  Dirty d;
  d.clean = test::bumpy_surface(4000, 5);
  const Vec3f bad[] = {{kNaN, 0, 0}, {0, kInf, 0}, {0, 0, -kInf}, {kNaN, kNaN, kNaN}};
  for (std::size_t i = 0; i < d.clean.size(); ++i) {
    if (i % 97 == 0) d.dirty.push_back(bad[(i / 97) % 4]);
    d.index.push_back(std::uint32_t(d.dirty.size()));
    d.dirty.push_back(d.clean[i]);
  }
  return d;
}

TEST(NonFinite, KdTreeNeverFindsThemAndANanQueryFindsNothing) {
  const Dirty d = dirty_surface();
  const KdTree clean(d.clean), dirty(d.dirty);
  Neighbors a, b;
  for (std::size_t i = 0; i < d.clean.size(); i += 50) {
    clean.knn(d.clean[i], 12, a);
    dirty.knn(d.clean[i], 12, b);
    ASSERT_EQ(a.size(), b.size());
    for (std::size_t k = 0; k < a.size(); ++k) EXPECT_EQ(d.index[a.indices[k]], b.indices[k]);
    clean.radius(d.clean[i], 0.05f, a, true);
    dirty.radius(d.clean[i], 0.05f, b, true);
    ASSERT_EQ(a.size(), b.size());
    std::vector<std::uint32_t> ia, ib = b.indices;  // the same points, as indices of each cloud
    for (std::uint32_t j : a.indices) ia.push_back(d.index[j]);
    std::sort(ia.begin(), ia.end());
    std::sort(ib.begin(), ib.end());
    EXPECT_EQ(ia, ib);
    for (std::size_t k = 0; k < a.size(); ++k) EXPECT_EQ(a.sq_dists[k], b.sq_dists[k]);
    float d2 = -1.0f;
    EXPECT_EQ(dirty.nearest(d.clean[i] + Vec3f(0.001f, 0, 0), &d2), d.index[clean.nearest(d.clean[i] + Vec3f(0.001f, 0, 0))]);
  }
  dirty.knn({kNaN, 0, 0}, 5, b);
  EXPECT_EQ(b.size(), 0u);
  dirty.radius({0, kInf, 0}, 1e30f, b);
  EXPECT_EQ(b.size(), 0u);
  float d2 = 0.0f;
  (void)dirty.nearest({kNaN, kNaN, kNaN}, &d2);
  EXPECT_EQ(d2, kInf);
  const std::vector<Vec3f> none = {{kNaN, 0, 0}, {kInf, 0, 0}};
  const KdTree empty(none);
  empty.knn({0, 0, 0}, 3, b);
  EXPECT_EQ(b.size(), 0u);
  (void)empty.nearest({0, 0, 0}, &d2);
  EXPECT_EQ(d2, kInf);
}

TEST(NonFinite, VoxelGridDropsThem) {
  const Dirty d = dirty_surface();
  PointCloud clean, dirty;
  clean.points = d.clean;
  dirty.points = d.dirty;
  const PointCloud a = voxel_downsample(clean, {.res_voxel = 0.05});
  const PointCloud b = voxel_downsample(dirty, {.res_voxel = 0.05});
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) EXPECT_EQ(a.points[i], b.points[i]);
  PointCloud only_bad;
  only_bad.points = {{kNaN, 1, 2}, {kInf, 0, 0}};
  EXPECT_TRUE(voxel_downsample(only_bad, {.res_voxel = 0.05}).empty());
  // Finite but beyond what a voxel index holds: refused, never an overflowing cast.
  PointCloud far;
  far.points = {{0, 0, 0}, {3e38f, 0, 0}};
  EXPECT_THROW((void)voxel_downsample(far, {.res_voxel = 0.05}), ConfigError);
}

TEST(NonFinite, NormalsIssAndShotAreThoseOfTheCleanCloud) {
  const Dirty d = dirty_surface();
  const KdTree clean_tree(d.clean), dirty_tree(d.dirty);
  const NormalConfig nc{.radius = 0.06};
  const NormalResult na = estimate_normals(d.clean, clean_tree, nc);
  const NormalResult nb = estimate_normals(d.dirty, dirty_tree, nc);
  EXPECT_EQ(nb.num_invalid, na.num_invalid + (d.dirty.size() - d.clean.size()));  // no normal at a NaN point
  for (std::size_t i = 0; i < d.clean.size(); ++i) {
    ASSERT_TRUE(nb.normals[d.index[i]].isApprox(na.normals[i], 1e-4f) ||
                (na.normals[i].isZero() && nb.normals[d.index[i]].isZero()))
        << i;
  }
  const IssConfig ic{.salient_radius = 0.06, .non_max_radius = 0.04};
  const std::vector<std::uint32_t> ka = iss_keypoints(d.clean, clean_tree, ic);
  const std::vector<std::uint32_t> kb = iss_keypoints(d.dirty, dirty_tree, ic);
  ASSERT_FALSE(ka.empty());
  ASSERT_EQ(ka.size(), kb.size());
  for (std::size_t k = 0; k < ka.size(); ++k) EXPECT_EQ(d.index[ka[k]], kb[k]);
  std::vector<Vec3f> keypoints;
  for (std::uint32_t k : ka) keypoints.push_back(d.clean[k]);
  keypoints.push_back({kNaN, 0, 0});  // a NaN keypoint: an invalid descriptor, nothing else
  const ShotDescriptors sa = compute_shot(keypoints, d.clean, na.normals, clean_tree, {});
  const ShotDescriptors sb = compute_shot(keypoints, d.dirty, nb.normals, dirty_tree, {});
  ASSERT_EQ(sa.size(), sb.size());
  EXPECT_FALSE(sb.valid.back());
  for (std::size_t k = 0; k + 1 < sa.size(); ++k) {
    ASSERT_EQ(sa.valid[k], sb.valid[k]);
    if (!sa.valid[k]) continue;
    for (int j = 0; j < kShotSize; ++j) EXPECT_NEAR(sa.descriptor(k)[std::size_t(j)], sb.descriptor(k)[std::size_t(j)], 1e-5f);
  }
}

}  // namespace
}  // namespace cairn
