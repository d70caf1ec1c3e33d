// Convex decomposition of stone meshes (issue #15, item 4): exact hull volumes, exact cuts of
// solids whose answer is known, and the real scanned stones within the 5 %.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <array>
#include <cstdio>
#include <filesystem>
#include <map>
#include <set>
#include <tuple>

#include "cairn/core/error.hpp"
#include "cairn/core/io/io.hpp"
#include "cairn/sim/convex_decomposition.hpp"
#include "cairn/sim/procedural_site.hpp"

namespace cairn::sim {
namespace {

using Eigen::Vector3d;
using Cell = std::array<int, 3>;
using Triangles = std::vector<std::array<std::uint32_t, 3>>;

/// The closed, outward-oriented surface of a union of unit cubes (cells): every cube face not
/// shared with another cell, as two triangles.
struct CellMesh {
  std::vector<Vector3d> v;
  Triangles t;
};
CellMesh cell_solid(const std::set<Cell>& cells) {
  CellMesh m;
  std::map<Cell, std::uint32_t> index;
  const auto vertex = [&](const Cell& c) {
    auto [it, added] = index.emplace(c, static_cast<std::uint32_t>(m.v.size()));
    if (added) m.v.emplace_back(c[0], c[1], c[2]);
    return it->second;
  };
  for (const Cell& c : cells) {
    for (int axis = 0; axis < 3; ++axis) {
      for (int side : {0, 1}) {
        Cell n = c;
        n[static_cast<std::size_t>(axis)] += side ? 1 : -1;
        if (cells.count(n) != 0) continue;
        const auto u = static_cast<std::size_t>((axis + 1) % 3), w = static_cast<std::size_t>((axis + 2) % 3);
        std::array<Cell, 4> q;
        for (int k = 0; k < 4; ++k) {
          Cell p = c;
          p[static_cast<std::size_t>(axis)] += side;
          p[u] += (k == 1 || k == 2) ? 1 : 0;
          p[w] += (k >= 2) ? 1 : 0;
          q[static_cast<std::size_t>(k)] = p;
        }
        // (u, w) ordered counter-clockwise seen from +axis: outward on side 1, flipped on side 0.
        std::array<std::uint32_t, 4> i = {vertex(q[0]), vertex(q[1]), vertex(q[2]), vertex(q[3])};
        if (side == 1) {
          m.t.push_back({i[0], i[1], i[2]});
          m.t.push_back({i[0], i[2], i[3]});
        } else {
          m.t.push_back({i[0], i[2], i[1]});
          m.t.push_back({i[0], i[3], i[2]});
        }
      }
    }
  }
  return m;
}

/// An L of three cubes (volume 3, hull 3.5) in the xz plane, one cube deep.
std::set<Cell> l_shape() { return {{0, 0, 0}, {1, 0, 0}, {0, 0, 1}}; }

TEST(ConvexDecomposition, HullAndMeshVolumesAreExact) {
  const CellMesh box = cell_solid({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}});
  EXPECT_NEAR(mesh_volume(box.v, box.t), 4.0, 1e-12);
  EXPECT_NEAR(convex_hull_volume(box.v), 4.0, 1e-9);
  const CellMesh l = cell_solid(l_shape());
  EXPECT_NEAR(mesh_volume(l.v, l.t), 3.0, 1e-12);
  EXPECT_NEAR(convex_hull_volume(l.v), 3.5, 1e-9);
  // Degenerate sets: fewer than 4 points, coplanar points, non-finite points.
  EXPECT_EQ(convex_hull_volume(std::vector<Vector3d>{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}), 0.0);
  // (qhull rejects the flat set; its joggled retry answers a volume of ~1e-10)
  EXPECT_NEAR(convex_hull_volume(std::vector<Vector3d>{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}, {2, 3, 0}}), 0.0, 1e-9);
  EXPECT_EQ(convex_hull_volume(std::vector<Vector3d>{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, NAN}}), 0.0);
}

TEST(ConvexDecomposition, AConvexSolidStaysOnePart) {
  const CellMesh box = cell_solid({{0, 0, 0}, {1, 0, 0}});
  const ConvexDecomposition d = decompose_convex(box.v, box.t);
  EXPECT_TRUE(d.parts.empty());
  EXPECT_NEAR(d.parts_volume, 2.0, 1e-9);
}

TEST(ConvexDecomposition, AnLIsCutIntoItsTwoBoxes) {
  const CellMesh l = cell_solid(l_shape());
  const ConvexDecomposition d = decompose_convex(l.v, l.t);
  ASSERT_EQ(d.parts.size(), 2U);
  EXPECT_NEAR(d.mesh_volume, 3.0, 1e-12);
  EXPECT_NEAR(d.hull_volume, 3.5, 1e-9);
  EXPECT_NEAR(d.parts_volume, 3.0, 1e-6);  // two exact boxes (1 + 2 or 2 + 1)
  // Every vertex of the L lies in a part; the parts' points lie on the L's surface.
  std::vector<bool> covered(l.v.size(), false);
  for (const CollisionPart& part : d.parts) {
    for (const MeshPoint& q : part) {
      if (q.w[0] == 1.0) covered[q.i[0]] = true;
      EXPECT_NEAR(q.w[0] + q.w[1] + q.w[2] + q.w[3], 1.0, 1e-9);
    }
  }
  for (std::size_t i = 0; i < covered.size(); ++i) EXPECT_TRUE(covered[i]) << "vertex " << i;
}

TEST(ConvexDecomposition, PartsMoveWithTheMesh) {
  const CellMesh l = cell_solid(l_shape());
  const ConvexDecomposition d = decompose_convex(l.v, l.t);
  ASSERT_FALSE(d.parts.empty());
  const Eigen::Isometry3d T = Eigen::Translation3d(4.0, -2.0, 1.5) * Eigen::AngleAxisd(0.7, Vector3d(1, 2, 3).normalized());
  std::vector<Vector3d> moved;
  for (const Vector3d& p : l.v) moved.push_back(T * p);
  for (const CollisionPart& part : d.parts) {
    const std::vector<Vector3d> before = part_points(part, l.v), after = part_points(part, moved);
    ASSERT_EQ(before.size(), after.size());
    for (std::size_t i = 0; i < before.size(); ++i) EXPECT_LT((T * before[i] - after[i]).norm(), 1e-6);
    EXPECT_NEAR(convex_hull_volume(before), convex_hull_volume(after), 1e-6);
  }
}

TEST(ConvexDecomposition, PartsOfARealStoneMoveWithItsMesh) {
  // low_res_E34: many cuts, so parts hold inner corners (affine weights of four vertices).
  const io::Mesh mesh = prepare_real_stone_mesh(
      io::read_ply_mesh(std::filesystem::path(CAIRN_SOURCE_DIR) / "data" / "stones" / "low_res_E34.ply"), 0.8);
  std::vector<Vector3d> v, moved;
  const Eigen::Isometry3d T = Eigen::Translation3d(-3.0, 7.0, 0.4) * Eigen::AngleAxisd(2.1, Vector3d(0.3, -1, 0.2).normalized());
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
    v.push_back(mesh.vertices.world(i));
    moved.push_back(T * v.back());
  }
  const ConvexDecomposition d = decompose_convex(v, mesh.triangles);
  ASSERT_GE(d.parts.size(), 3U);
  int inner = 0;
  double sum_before = 0.0, sum_after = 0.0;
  for (const CollisionPart& part : d.parts) {
    for (const MeshPoint& q : part) inner += q.w[3] != 0.0 ? 1 : 0;
    const std::vector<Vector3d> before = part_points(part, v), after = part_points(part, moved);
    for (std::size_t i = 0; i < before.size(); ++i) ASSERT_LT((T * before[i] - after[i]).norm(), 1e-9);
    sum_before += convex_hull_volume(before);
    sum_after += convex_hull_volume(after);
  }
  EXPECT_GT(inner, 0);
  EXPECT_NEAR(sum_before, d.parts_volume, 1e-9);
  EXPECT_NEAR(sum_after, sum_before, 1e-9);
  EXPECT_GE(sum_before, d.mesh_volume * (1.0 - 1e-6));
}

TEST(ConvexDecomposition, BadTrianglesAreErrors) {
  const CellMesh l = cell_solid(l_shape());
  Triangles bad = l.t;
  bad.back()[1] = static_cast<std::uint32_t>(l.v.size());
  EXPECT_THROW(decompose_convex(l.v, bad), InputError);
}

TEST(ConvexDecomposition, ANegativeExcessNeverDecomposes) {
  const CellMesh l = cell_solid(l_shape());
  ConvexDecompositionConfig c;
  c.max_excess = -1.0;
  EXPECT_TRUE(decompose_convex(l.v, l.t, c).parts.empty());
}

TEST(ConvexDecomposition, RealStonesAreHeldWithinFivePercent) {
  // The shipped scanned stones (data/stones): the hull of each adds 0–25 % to its volume; the
  // parts' hulls together add at most the 5 % (or the cuts stop at max_parts: reported).
  const std::filesystem::path dir = std::filesystem::path(CAIRN_SOURCE_DIR) / "data" / "stones";
  int meshes = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    if (e.path().extension() != ".ply") continue;
    ++meshes;
    const io::Mesh mesh = prepare_real_stone_mesh(io::read_ply_mesh(e.path()), 1.0);
    std::vector<Vector3d> v;
    for (std::size_t i = 0; i < mesh.vertices.size(); ++i) v.push_back(mesh.vertices.world(i));
    const ConvexDecomposition d = decompose_convex(v, mesh.triangles);
    std::printf("%-28s mesh %.4f m^3, hull / mesh %.3f, %zu parts: parts / mesh %.3f\n",
                e.path().filename().c_str(), d.mesh_volume, d.hull_volume / d.mesh_volume, d.parts.size(),
                d.parts_volume / d.mesh_volume);
    EXPECT_NEAR(d.mesh_volume, 1.0, 1e-6) << e.path();
    EXPECT_LE(d.parts_volume, 1.05 * d.mesh_volume) << e.path();
    // Each part's hull holds its piece of the solid (inner corners included: without them the
    // parts of remeshed_high_res_A0 held only 0.990 of it), so together they hold the stone.
    EXPECT_GE(d.parts_volume, d.mesh_volume * (1.0 - 1e-6)) << e.path();
    EXPECT_LE(d.parts_volume, d.hull_volume + 1e-9) << e.path();
    EXPECT_GE(d.parts.size(), 3U) << e.path();  // every shipped stone's hull adds > 5 %
  }
  EXPECT_EQ(meshes, 5);
}

}  // namespace
}  // namespace cairn::sim
