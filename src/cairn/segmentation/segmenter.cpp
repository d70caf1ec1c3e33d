#include "cairn/segmentation/segmenter.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <tbb/parallel_for.h>

#include <deque>
#include <limits>

#include "cairn/core/cell_map.hpp"
#include "cairn/core/error.hpp"
#include "cairn/core/kdtree.hpp"
#include "cairn/segmentation/grid2d.hpp"

namespace cairn {

std::size_t SegmentationResult::num_objects() const {
  return std::size_t(std::count_if(segments.begin(), segments.end(), [](const Segment& s) { return !s.planar; }));
}

namespace {

/// xy footprint of the core object points, dilated by a radius, on a grid of radius/2 cells.
class Footprint {
 public:
  Footprint(std::span<const Vec3f> pts, const std::vector<std::vector<std::uint32_t>>& clusters, double radius)
      : frame_(GridFrame::covering(pts, float(radius / 2.0), "segmentation: ground.attach_radius")),
        occupied_(frame_.num_cells(), 0) {
    constexpr int kReach = 2;  // radius = 2 cells
    for (const auto& cl : clusters)
      for (auto i : cl) {
        const int cx = frame_.ix(pts[i].x()), cy = frame_.iy(pts[i].y());
        for (int y = std::max(0, cy - kReach); y <= std::min(frame_.ny - 1, cy + kReach); ++y)
          for (int x = std::max(0, cx - kReach); x <= std::min(frame_.nx - 1, cx + kReach); ++x)
            occupied_[frame_.index(x, y)] = 1;
      }
  }
  [[nodiscard]] bool covers(const Vec3f& p) const { return occupied_[frame_.index_of(p)]; }

 private:
  GridFrame frame_;
  std::vector<std::uint8_t> occupied_;
};

/// Stone bottoms: points of the low band (attach_height < h <= the ground band) under the dilated xy
/// footprint of the objects (attach_radius, to the resolution of a radius/2 grid) join the
/// cluster of an object point within attach_distance (the first cluster that reaches them).
/// Visible stone bottoms continue straight up into the stone's core points, so one hop suffices;
/// with attach_chain, attached points attach further ones breadth-first (more complete, but the
/// chain runs on through terrain points that noise lifts into the band).
void attach_low_band(std::span<const Vec3f> pts, const GroundResult& ground, const SegmentationConfig& c,
                     std::vector<std::vector<std::uint32_t>>& clusters) {
  if (clusters.empty()) return;
  const std::vector<float>& height = ground.height;
  const Footprint footprint(pts, clusters, c.ground.attach_radius);
  std::vector<std::uint32_t> band;
  std::vector<Vec3f> band_pts;
  for (std::uint32_t i = 0; i < pts.size(); ++i)
    if (height[i] > c.ground.attach_height && ground.is_ground(i) && footprint.covers(pts[i])) {
      band.push_back(i);
      band_pts.push_back(pts[i]);
    }
  if (band.empty()) return;
  const KdTree tree(band_pts);
  std::vector<std::int32_t> owner(band.size(), -1);
  std::deque<std::pair<Vec3f, std::int32_t>> frontier;
  const float tol = float(c.ground.attach_distance);
  for (std::size_t s = 0; s < clusters.size(); ++s)
    for (auto i : clusters[s])
      if (height[i] <= float(ground.band(i)) + tol) frontier.emplace_back(pts[i], std::int32_t(s));  // only these can reach
  while (!frontier.empty()) {
    const auto [p, s] = frontier.front();
    frontier.pop_front();
    tree.for_each_in_radius(p, tol, [&, s = s](std::uint32_t k, float) {
      if (owner[k] >= 0) return;
      owner[k] = s;
      if (c.ground.attach_chain) frontier.emplace_back(band_pts[k], s);
    });
  }
  for (std::size_t k = 0; k < band.size(); ++k)
    if (owner[k] >= 0) clusters[std::size_t(owner[k])].push_back(band[k]);
  for (auto& cl : clusters) std::sort(cl.begin(), cl.end());
}

/// Share of the points lying in xy columns whose z spread exceeds the column height.
double stacked_fraction(std::span<const Vec3f> pts, std::span<const std::uint32_t> idx, const VerticalityConfig& v) {
  if (idx.empty()) return 0.0;
  const float inv = 1.0f / float(v.column_size);
  const auto key = [&](const Vec3f& p) {
    return CellMap::key(std::int64_t(std::floor(p.x() * inv)), std::int64_t(std::floor(p.y() * inv)), 0);
  };
  CellMap column(idx.size());
  std::vector<std::pair<float, float>> range;  // per column: zmin, zmax
  std::vector<std::uint32_t> column_of(idx.size());
  for (std::size_t k = 0; k < idx.size(); ++k) {
    const Vec3f& p = pts[idx[k]];
    const std::uint32_t c = column.insert(key(p), std::uint32_t(range.size()));
    if (c == range.size()) range.emplace_back(p.z(), p.z());
    range[c] = {std::min(range[c].first, p.z()), std::max(range[c].second, p.z())};
    column_of[k] = c;
  }
  std::size_t stacked = 0;
  for (auto c : column_of) stacked += range[c].second - range[c].first > float(v.column_height);
  return double(stacked) / double(idx.size());
}

Segment make_segment(std::span<const Vec3f> pts, std::vector<std::uint32_t> idx, const SegmentationConfig& c,
                     std::mt19937_64& rng) {
  const PlanarityConfig& pc = c.planarity;
  Segment s;
  s.indices = std::move(idx);
  s.centroid = centroid(pts, s.indices);
  for (auto i : s.indices) {
    s.box.min = s.box.min.cwiseMin(pts[i]);
    s.box.max = s.box.max.cwiseMax(pts[i]);
  }
  if (pc.enabled) {
    RansacPlaneConfig rc;
    rc.distance = pc.distance;
    rc.max_iterations = pc.iterations;
    rc.refine = false;
    rc.max_scored_points = pc.scored_points > 0 ? std::size_t(pc.scored_points)
                                                : std::numeric_limits<std::size_t>::max();  // 0: all points
    const PlaneFit fit = fit_plane_ransac(pts, s.indices, rc, rng);
    s.plane_inlier_ratio = fit.found ? double(fit.inliers.size()) / double(s.indices.size()) : 0.0;
    s.planar = s.plane_inlier_ratio > pc.max_inlier_ratio;
  }
  if (c.verticality.enabled) s.stacked_fraction = stacked_fraction(pts, s.indices, c.verticality);
  return s;
}

struct SplitPart {
  ClusterPart part;
  std::int32_t cluster = -1;
  bool split = false;
};

/// Every cluster split into its stones (in parallel), the parts ordered largest first.
std::vector<SplitPart> split_clusters(std::span<const Vec3f> pts, std::span<const float> height,
                                      const std::vector<std::vector<std::uint32_t>>& clusters,
                                      const SplitConfig& config) {
  std::vector<std::vector<ClusterPart>> split(clusters.size());
  tbb::parallel_for(std::size_t{0}, clusters.size(),
                    [&](std::size_t k) { split[k] = split_cluster(pts, height, clusters[k], config); });
  std::vector<SplitPart> parts;
  for (std::size_t k = 0; k < split.size(); ++k)
    for (auto& p : split[k]) parts.push_back({std::move(p), std::int32_t(k), split[k].size() > 1});
  std::stable_sort(parts.begin(), parts.end(), [](const SplitPart& a, const SplitPart& b) {
    return a.part.indices.size() > b.part.indices.size();
  });
  return parts;
}

/// A split part that the shape checks reject (terrain, planar) is no stone of its own: it goes
/// back to the largest object part of its cluster (a stone's foot or flank the seam cut off),
/// as it was before the split; without such a sibling it stays rejected.
void return_rejected_parts(std::span<const Vec3f> pts, std::vector<Segment>& rejected, std::vector<Segment>& objects) {
  std::erase_if(rejected, [&](Segment& part) {
    if (!part.split) return false;
    Segment* sibling = nullptr;
    for (Segment& o : objects)
      if (o.cluster == part.cluster && (sibling == nullptr || o.indices.size() > sibling->indices.size())) sibling = &o;
    if (sibling == nullptr) return false;
    sibling->indices.insert(sibling->indices.end(), part.indices.begin(), part.indices.end());
    std::sort(sibling->indices.begin(), sibling->indices.end());
    sibling->centroid = centroid(pts, sibling->indices);
    sibling->box.min = sibling->box.min.cwiseMin(part.box.min);
    sibling->box.max = sibling->box.max.cwiseMax(part.box.max);
    std::size_t parts = 0;
    for (const Segment& o : objects) parts += o.cluster == part.cluster;
    sibling->split = parts > 1;
    return true;
  });
}

/// Ground heights and the Euclidean clusters above the ground with their bottoms (steps 1-3).
struct Clusters {
  GroundResult ground;
  std::vector<std::vector<std::uint32_t>> clusters;
};
Clusters clusters_above_ground(std::span<const Vec3f> pts, const SegmentationConfig& config, std::mt19937_64& rng,
                               Timings& timings, Stopwatch& sw) {
  Clusters c{estimate_ground(pts, config.ground, rng), {}};
  timings.add("ground", sw.lap_ms());
  std::vector<std::uint32_t> above;
  for (std::uint32_t i = 0; i < pts.size(); ++i)
    if (!c.ground.is_ground(i)) above.push_back(i);
  c.clusters = euclidean_clusters(pts, above, config.clustering);
  timings.add("clustering", sw.lap_ms());
  attach_low_band(pts, c.ground, config, c.clusters);
  timings.add("attach_bottoms", sw.lap_ms());
  return c;
}

void check_input(const PointCloud& cloud) {
  if (cloud.empty()) throw InputError("segmentation: the cloud is empty");
  cloud.check_finite("segmentation input");
}

}  // namespace

std::vector<HillContacts> split_evidence(const PointCloud& cloud, const SegmentationConfig& config) {
  check_input(cloud);
  std::mt19937_64 rng(config.seed);
  Timings timings;
  Stopwatch sw;
  const Clusters c = clusters_above_ground(cloud.points, config, rng, timings, sw);
  std::vector<HillContacts> out;
  for (const auto& cluster : c.clusters) out.push_back(hill_contacts(cloud.points, c.ground.height, cluster, config.split));
  return out;
}

SegmentationResult segment(const PointCloud& cloud, const SegmentationConfig& config) {
  check_input(cloud);
  SegmentationResult res;
  std::mt19937_64 rng(config.seed);
  Stopwatch sw;
  const std::span<const Vec3f> pts = cloud.points;

  const Clusters above = clusters_above_ground(pts, config, rng, res.timings, sw);
  const GroundResult& ground = above.ground;
  res.ground_plane = ground.plane;
  std::vector<SplitPart> parts = split_clusters(pts, ground.height, above.clusters, config.split);
  res.timings.add("split", sw.lap_ms());

  // Shape checks per part in parallel; part k draws from its own generator (seed, k).
  std::vector<Segment> checked(parts.size());
  tbb::parallel_for(std::size_t{0}, parts.size(), [&](std::size_t k) {
    std::mt19937_64 gen(config.seed + 0x9E3779B97F4A7C15ull * (k + 1));
    checked[k] = make_segment(pts, std::move(parts[k].part.indices), config, gen);
    checked[k].cluster = parts[k].cluster;
    checked[k].split = parts[k].split;
    checked[k].seam_depth = parts[k].part.seam_depth;
  });
  std::vector<Segment> objects, planar, terrain;
  for (auto& s : checked) {
    if (s.stacked_fraction < config.verticality.min_stacked_fraction)
      terrain.push_back(std::move(s));
    else
      (s.planar ? planar : objects).push_back(std::move(s));
  }
  return_rejected_parts(pts, terrain, objects);
  return_rejected_parts(pts, planar, objects);
  res.timings.add("shape_checks", sw.lap_ms());

  res.labels.assign(pts.size(), kLabelNone);
  for (std::uint32_t i = 0; i < pts.size(); ++i)
    if (ground.is_ground(i)) res.labels[i] = kLabelGround;
  for (const auto& s : terrain)
    for (auto i : s.indices) res.labels[i] = kLabelGround;
  std::int32_t next_id = 0;
  for (auto& s : objects) {
    s.id = next_id++;
    for (auto i : s.indices) res.labels[i] = s.id;
  }
  for (auto& s : planar) {
    s.id = next_id++;  // listed for inspection; their points stay kLabelNone (no object)
    for (auto i : s.indices) res.labels[i] = kLabelNone;
  }
  res.num_ground = std::size_t(std::count(res.labels.begin(), res.labels.end(), kLabelGround));
  res.segments = std::move(objects);
  res.segments.insert(res.segments.end(), std::make_move_iterator(planar.begin()),
                      std::make_move_iterator(planar.end()));
  res.timings.add("labels", sw.lap_ms());
  spdlog::debug("segmentation: {} points, {} ground, {} objects, {} planar", pts.size(), res.num_ground,
                res.num_objects(), res.segments.size() - res.num_objects());
  return res;
}

}  // namespace cairn
