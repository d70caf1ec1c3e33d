#pragma once
// Collision shapes of a stone: MuJoCo collides a mesh as its convex hull, which bridges the
// concavities of a real scanned stone (up to ~25 % more volume: docs/simulator-physics.md). A
// stone whose hull adds more than `max_excess` of its volume is cut by planes into parts whose
// hulls together hold it closely (an approximate convex decomposition in the manner of V-HACD,
// Mamou 2016, on an exact surface: Debian ships neither V-HACD nor CoACD).
//
// Each part is the set of corners of the solid's piece: the mesh's vertices inside it, the points
// where the cutting planes cross its triangles, and where three cutting planes meet inside the
// stone — each as affine weights of mesh vertices, so a part moves with the mesh however the
// stone is moved (issue #15, item 4).
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <span>
#include <vector>

namespace cairn::sim {

/// A point fixed to a mesh: sum of w[k] v[i[k]] (weights sum to 1: on a triangle, three of them
/// in [0, 1]; inside the solid, affine weights of four vertices spanning it).
struct MeshPoint {
  std::array<std::uint32_t, 4> i{};
  std::array<double, 4> w{1.0, 0.0, 0.0, 0.0};
};

/// One convex part of a stone: the hull of these points.
using CollisionPart = std::vector<MeshPoint>;

struct ConvexDecompositionConfig {
  /// Decompose when the mesh's hull exceeds its volume by more than this share, and cut until the
  /// parts' hulls together exceed it by at most this share (issue #15: ~5 %). < 0: never.
  double max_excess = 0.05;
  int max_parts = 20;           // MuJoCo collides every part with the terrain and its neighbours
  int planes_per_axis = 9;      // candidate cuts per axis of the part, evenly over its extent
  int grid_cells = 40;          // interior samples along the mesh's longest side (part volumes)
  double min_part_share = 0.02;  // no part smaller than this share of the stone's volume (> 0)

  template <class V>
  void visit(V& v) {
    v("max_excess", max_excess, "decompose until the parts' hulls exceed the mesh volume by at most this share (< 0: never)");
    v("max_parts", max_parts, "most convex parts per stone");
    v("planes_per_axis", planes_per_axis, "candidate cutting planes per axis of a part");
    v("grid_cells", grid_cells, "interior samples along the longest side (part volumes)");
    v("min_part_share", min_part_share, "smallest part, as a share of the stone's volume");
  }
};

struct ConvexDecomposition {
  /// Empty when the mesh's own hull is close enough (or the mesh is degenerate): one part, the
  /// whole mesh.
  std::vector<CollisionPart> parts;
  double mesh_volume = 0.0;  // [m^3] enclosed by the mesh
  double hull_volume = 0.0;  // [m^3] of the mesh's convex hull (not computed, 0, when max_excess < 0)
  double parts_volume = 0.0;  // [m^3] the parts' hulls together (= hull_volume with no parts)
};

/// Volume [m^3] of the convex hull of the points (qhull; 0 for fewer than 4, coplanar or
/// non-finite points).
double convex_hull_volume(std::span<const Eigen::Vector3d> points);

/// Volume enclosed by a closed, outward-oriented triangle mesh.
double mesh_volume(std::span<const Eigen::Vector3d> vertices,
                   std::span<const std::array<std::uint32_t, 3>> triangles);

/// Cuts a closed mesh into parts (best first: the part whose hull adds most is cut by the
/// candidate plane that most reduces its children's hulls) until the parts' hulls exceed the
/// mesh's volume by at most config.max_excess, no cut helps, or max_parts. Deterministic. The
/// mesh must be closed (inside tests count crossings); throws InputError on a triangle that
/// indexes no vertex.
ConvexDecomposition decompose_convex(std::span<const Eigen::Vector3d> vertices,
                                     std::span<const std::array<std::uint32_t, 3>> triangles,
                                     const ConvexDecompositionConfig& config = {});

/// The points of a part on the mesh with these vertices.
std::vector<Eigen::Vector3d> part_points(const CollisionPart& part, std::span<const Eigen::Vector3d> vertices);

}  // namespace cairn::sim
