#pragma once
// Map segmentation (Sec. 4.3): ground removal → Euclidean clustering → splitting touching stones
// (beyond the paper) → planarity check → segments with centroids.
#include <cstdint>
#include <vector>

#include "cairn/core/log.hpp"
#include "cairn/segmentation/clustering.hpp"
#include "cairn/segmentation/ground.hpp"
#include "cairn/segmentation/split.hpp"

namespace cairn {

struct PlanarityConfig {
  bool enabled = true;
  double distance = 0.05;         // RANSAC inlier distance for the planarity test [m]
  double max_inlier_ratio = 0.85; // segments with a larger share of plane inliers are planar
  int iterations = 200;
  int scored_points = 1024;       // hypotheses scored on a random subset of this size (0: all)

  template <class V>
  void visit(V& v) {
    v("enabled", enabled, "drop nearly planar segments (walls, slabs, leftover terrain)");
    v("distance", distance, "RANSAC inlier distance of the planarity check [m]");
    v("max_inlier_ratio", max_inlier_ratio, "a segment is planar above this share of plane inliers");
    v("iterations", iterations, "RANSAC iterations of the planarity check");
    v("scored_points", scored_points, "RANSAC hypotheses are scored on a random subset of this size (0: all points)");
  }
};

/// Terrain check (beyond the paper): terrain is a height field — one surface per xy location —
/// while a stone has steep sides where points stack vertically. A cluster with too small a share
/// of its points in "stacked" xy columns (z spread > column_height) is leftover terrain (a
/// ridge the ground model cut off) and is labelled ground.
struct VerticalityConfig {
  bool enabled = true;
  double column_size = 0.05;       // xy column edge [m]
  double column_height = 0.12;     // a column is stacked when its z spread exceeds this [m]
  double min_stacked_fraction = 0.03;

  template <class V>
  void visit(V& v) {
    v("enabled", enabled, "relabel clusters without steep sides (terrain ridges) as ground");
    v("column_size", column_size, "xy column edge of the verticality test [m]");
    v("column_height", column_height, "z spread that makes a column stacked [m]");
    v("min_stacked_fraction", min_stacked_fraction, "objects have at least this share of points in stacked columns");
  }
};

struct SegmentationConfig {
  GroundConfig ground;
  ClusterConfig clustering;
  SplitConfig split;
  PlanarityConfig planarity;
  VerticalityConfig verticality;
  std::uint64_t seed = 42;  // RANSAC generator seed: results are reproducible

  template <class V>
  void visit(V& v) {
    v("ground", ground, "ground removal");
    v("clustering", clustering, "Euclidean clustering of the non-ground points");
    v("split", split, "splitting clusters of touching stones (piles) along their seams");
    v("planarity", planarity, "planarity check of the clusters");
    v("verticality", verticality, "terrain check of the clusters (steep sides)");
    v("seed", seed, "random seed of the RANSAC steps");
  }
};

/// Labels of the contract: segment id >= 0, ground, or no object.
inline constexpr std::int32_t kLabelGround = -1;
inline constexpr std::int32_t kLabelNone = -2;

struct Segment {
  std::int32_t id = 0;
  std::vector<std::uint32_t> indices;  // into the input cloud, ascending
  Vec3f centroid = Vec3f::Zero();
  Aabb box;
  bool planar = false;
  double plane_inlier_ratio = 0.0;
  double stacked_fraction = 1.0;  // share of points in vertically stacked xy columns
  std::int32_t cluster = -1;      // the Euclidean cluster it came from (clusters largest first)
  bool split = false;             // one of several parts of that cluster (touching stones)
  double seam_depth = 0.0;        // split parts: depth of the shallowest seam to another part [m]
};

struct SegmentationResult {
  std::vector<std::int32_t> labels;  // per input point
  std::vector<Segment> segments;     // objects first (ids 0..k-1, largest first), then planar ones
  Plane ground_plane;
  std::size_t num_ground = 0;
  Timings timings;
  [[nodiscard]] std::size_t num_objects() const;
};

/// Segments a cloud (positions must be finite; throws InputError otherwise or when empty).
[[nodiscard]] SegmentationResult segment(const PointCloud& cloud, const SegmentationConfig& config);

/// What the splitting of touching stones weighs, per Euclidean cluster (for studies and tests:
/// the hills and their contacts, split.hpp). Same input contract as segment().
[[nodiscard]] std::vector<HillContacts> split_evidence(const PointCloud& cloud, const SegmentationConfig& config);

}  // namespace cairn
