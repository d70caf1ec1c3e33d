#pragma once
// The segment points of a simulated stone site (the input of Sec. 4.4 steps 2-4): the default
// 7-stone site sampled at 3 cm, voxelised at res_voxel = 3 cm (Table 3) and segmented; the points
// of all object segments, with PCA normals (r = 10 cm over the whole map, oriented away from the segment centroid).
// Needs cairn_sim and cairn_segmentation.
#include <vector>

#include "cairn/core/kdtree.hpp"
#include "cairn/core/normals.hpp"
#include "cairn/core/voxel_grid.hpp"
#include "cairn/segmentation/segmenter.hpp"
#include "cairn/sim/procedural_site.hpp"

namespace cairn::test {

struct SegmentPoints {
  std::vector<Vec3f> points;
  std::vector<Vec3f> normals;
  std::size_t map_size = 0;
};

/// `seed` draws the site, `sample_seed` (default: seed) its sampling: two sample seeds give two
/// independent scans of the same stones (as the LiDAR map and the drone cloud).
inline SegmentPoints site_segment_points(std::uint64_t seed, std::uint64_t sample_seed = 0) {
  const sim::Site site = sim::generate_site({}, seed);
  const PointCloud map = voxel_downsample(sim::sample_site(site, {}, sample_seed ? sample_seed : seed).cloud, {});
  const SegmentationResult seg = segment(map, {});
  const KdTree tree(map.points);
  const NormalResult normals = estimate_normals(map.points, tree, {.radius = 0.1, .viewpoint_z = 100.0});
  SegmentPoints out;
  out.map_size = map.size();
  for (const Segment& s : seg.segments) {
    if (s.planar) continue;
    for (auto i : s.indices) {
      out.points.push_back(map.points[i]);
      // Outward from the segment's centroid: stable on the steep sides of a stone, where "up"
      // is ambiguous (SHOT's cosine histogram depends on the normal's sign).
      Vec3f n = normals.normals[i];
      if (n.dot(map.points[i] - s.centroid) < 0.0f) n = -n;
      out.normals.push_back(n);
    }
  }
  return out;
}

}  // namespace cairn::test
