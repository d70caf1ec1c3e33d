#pragma once
// Splitting touching stones (beyond the paper, whose Sec. 7 names piles as the open problem):
// Euclidean clustering merges stones that touch. Each convex-ish stone is a hill of height above
// the local ground, and two touching stones meet at a concave crease. Three steps, on the graph
// of the cluster's occupied voxels (26-neighbourhood, in 3-D so that a stone leaning over another
// does not hide it as it would in a top-view height field):
//  1. Fine hills: the surface is flooded from the top down; a voxel drains into the hill of its
//     highest neighbour whose surface it continues (not rising in front of that neighbour's
//     tangent plane at more than max_rise_deg: the far side of a crease belongs to the other
//     stone); hills whose dip is shallower than min_crease_depth merge at once (persistence).
//  2. Stones from hills: two touching hills are two stones when the lower top rises
//     min_seam_depth above their saddle, or min_crease_depth above it while at least
//     min_crease_share of their contact (adjacent voxel pairs) is a sharp concave crease — the
//     normals of the two sides (each from its own hill's voxels) turn towards each other by
//     seam_angle_deg (LCCP's convexity criterion, Stein et al. 2014). Otherwise they merge,
//     shallowest first. The bumps and dips of one lumpy stone are smooth: deep ones are still
//     no crease, so a single stone is not split (margin: docs/segmentation.md).
//  3. Parts too small, flat or low to be a stone merge into the neighbour they share the highest
//     saddle with.
#include <cstdint>
#include <span>
#include <vector>

#include "cairn/core/point_cloud.hpp"

namespace cairn {

struct SplitConfig {
  bool enabled = true;
  double voxel_size = 0.05;        // [m] voxel of the surface graph (finer than the seams' gaps)
  double min_seam_depth = 0.35;    // [m] lower top above the saddle: two stones, crease or not
  double min_crease_depth = 0.03;  // [m] ... two stones when they meet at a sharp crease
  double seam_angle_deg = 50.0;    // [deg] a crease is sharp when the normals of its sides turn this much
  double min_crease_share = 0.25;  // ... along at least this share of the two hills' contact
  double max_rise_deg = 25.0;      // [deg] a voxel rising steeper in front of a surface is not on it
  int min_part_points = 150;       // a part with fewer points merges into its neighbour
  double min_part_area = 0.10;     // [m^2] ... as does a part of less surface (voxels x voxel^2)
  double min_part_height = 0.2;    // [m] ... or whose top is lower above the ground (terrain bumps)

  template <class V>
  void visit(V& v) {
    v("enabled", enabled, "split clusters of touching stones (piles) along the concave creases between them");
    v("voxel_size", voxel_size, "voxel of the surface graph flooded to find the seams [m]");
    v("min_seam_depth", min_seam_depth,
      "two hills are two stones when the lower top rises this far above their saddle, crease or not [m]");
    v("min_crease_depth", min_crease_depth,
      "two hills are two stones when the lower top rises this far above their saddle and they meet at a sharp crease [m]");
    v("seam_angle_deg", seam_angle_deg,
      "a crease is sharp when the surface normals on its two sides turn towards each other by this angle [deg]");
    v("min_crease_share", min_crease_share, "share of the contact between two parts that must be a sharp crease");
    v("max_rise_deg", max_rise_deg,
      "a voxel rising steeper than this in front of a neighbour's tangent plane does not drain into it (the far side of a crease) [deg]");
    v("min_part_points", min_part_points, "parts with fewer points are merged into a neighbour");
    v("min_part_height", min_part_height, "parts whose top is lower above the ground are merged into a neighbour [m]");
    v("min_part_area", min_part_area, "parts of less surface (occupied voxels x voxel area) are merged into a neighbour [m^2]");
  }
};

/// One part of a split cluster.
struct ClusterPart {
  std::vector<std::uint32_t> indices;  // into the cloud, ascending
  /// Depth of the shallowest seam separating this part from another part [m]: the part's top
  /// minus the saddle; 0 when the cluster was not split.
  double seam_depth = 0.0;
};

/// The evidence the splitting weighs, for studies and tests: the hills of the fine flooding
/// (every dip of min_crease_depth) and, for every pair that touches, the depth of its saddle
/// below the lower top and the share of its contact that is a sharp concave crease.
struct HillContacts {
  struct Contact {
    std::size_t a = 0, b = 0;  // into hills
    double depth = 0.0;        // [m]
    double crease_share = 0.0;
    std::size_t edges = 0;     // adjacent voxel pairs of the two hills
  };
  std::vector<std::vector<std::uint32_t>> hills;  // indices into the cloud
  std::vector<Contact> contacts;
};
[[nodiscard]] HillContacts hill_contacts(std::span<const Vec3f> points, std::span<const float> height,
                                         std::span<const std::uint32_t> indices, const SplitConfig& config);

/// Splits one cluster (`indices` into `points`; `height` is the height above the ground of every
/// point of the cloud) into its stones. Returns one part (the whole cluster) when nothing splits.
/// Throws ConfigError on invalid configuration values.
[[nodiscard]] std::vector<ClusterPart> split_cluster(std::span<const Vec3f> points, std::span<const float> height,
                                                     std::span<const std::uint32_t> indices,
                                                     const SplitConfig& config);

}  // namespace cairn
