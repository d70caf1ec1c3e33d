#include "cairn/segmentation/segmenter.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <unordered_map>
#include <tbb/parallel_for.h>

#include <deque>

#include "cairn/core/error.hpp"
#include "cairn/core/kdtree.hpp"

namespace cairn {

std::size_t SegmentationResult::num_objects() const {
  return std::size_t(std::count_if(segments.begin(), segments.end(), [](const Segment& s) { return !s.planar; }));
}

namespace {

/// Stone bottoms: points of the low band (attach_height < h <= d_plane) whose horizontal distance
/// to a core object point is at most attach_radius are eligible; the clusters grow into the
/// eligible points breadth-first (a point joins the first cluster that reaches it). Bottoms lie
/// under the stone's own footprint, so growth never spreads across the surrounding terrain.
void attach_low_band(std::span<const Vec3f> pts, const std::vector<float>& height, const SegmentationConfig& c,
                     std::vector<std::vector<std::uint32_t>>& clusters) {
  if (clusters.empty()) return;
  std::vector<Vec3f> footprint;  // core points projected to z = 0
  for (const auto& cl : clusters)
    for (auto i : cl) footprint.emplace_back(pts[i].x(), pts[i].y(), 0.0f);
  const KdTree flat(footprint);
  const float r2 = float(c.ground.attach_radius * c.ground.attach_radius);
  std::vector<std::uint8_t> eligible(pts.size(), 0);
  tbb::parallel_for(std::size_t{0}, pts.size(), [&](std::size_t i) {
    if (height[i] <= c.ground.attach_height || height[i] > c.ground.d_plane) return;
    float d2 = 0;
    (void)flat.nearest({pts[i].x(), pts[i].y(), 0.0f}, &d2);
    eligible[i] = d2 <= r2;
  });
  std::vector<std::uint32_t> band;
  std::vector<Vec3f> band_pts;
  for (std::uint32_t i = 0; i < pts.size(); ++i)
    if (eligible[i]) band.push_back(i), band_pts.push_back(pts[i]);
  if (band.empty()) return;
  const KdTree tree(band_pts);
  std::vector<std::int32_t> owner(band.size(), -1);
  std::deque<std::pair<Vec3f, std::int32_t>> frontier;
  for (std::size_t s = 0; s < clusters.size(); ++s)
    for (auto i : clusters[s]) frontier.emplace_back(pts[i], std::int32_t(s));
  const float tol = float(c.clustering.tolerance);
  while (!frontier.empty()) {
    const auto [p, s] = frontier.front();
    frontier.pop_front();
    tree.for_each_in_radius(p, tol, [&, s = s](std::uint32_t k, float) {
      if (owner[k] >= 0) return;
      owner[k] = s;
      frontier.emplace_back(band_pts[k], s);
    });
  }
  for (std::size_t k = 0; k < band.size(); ++k)
    if (owner[k] >= 0) clusters[std::size_t(owner[k])].push_back(band[k]);
  for (auto& cl : clusters) std::sort(cl.begin(), cl.end());
}

/// Share of the points lying in xy columns whose z spread exceeds the column height.
double stacked_fraction(std::span<const Vec3f> pts, std::span<const std::uint32_t> idx, const VerticalityConfig& v) {
  std::unordered_map<std::uint64_t, std::pair<float, float>> columns;  // key → (zmin, zmax)
  const float inv = 1.0f / float(v.column_size);
  const auto key = [&](const Vec3f& p) {
    return (std::uint64_t(std::uint32_t(std::int32_t(std::floor(p.x() * inv)))) << 32) |
           std::uint32_t(std::int32_t(std::floor(p.y() * inv)));
  };
  columns.reserve(idx.size());
  for (auto i : idx) {
    auto [it, fresh] = columns.try_emplace(key(pts[i]), pts[i].z(), pts[i].z());
    it->second.first = std::min(it->second.first, pts[i].z());
    it->second.second = std::max(it->second.second, pts[i].z());
  }
  std::size_t stacked = 0;
  for (auto i : idx) {
    const auto& [lo, hi] = columns.at(key(pts[i]));
    stacked += hi - lo > float(v.column_height);
  }
  return idx.empty() ? 0.0 : double(stacked) / double(idx.size());
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
    const PlaneFit fit = fit_plane_ransac(pts, s.indices, rc, rng);
    s.plane_inlier_ratio = fit.found ? double(fit.inliers.size()) / double(s.indices.size()) : 0.0;
    s.planar = s.plane_inlier_ratio > pc.max_inlier_ratio;
  }
  if (c.verticality.enabled) s.stacked_fraction = stacked_fraction(pts, s.indices, c.verticality);
  return s;
}

}  // namespace

SegmentationResult segment(const PointCloud& cloud, const SegmentationConfig& config) {
  if (cloud.empty()) throw InputError("segmentation: the cloud is empty");
  cloud.check_finite("segmentation input");
  SegmentationResult res;
  std::mt19937_64 rng(config.seed);
  Stopwatch sw;
  const std::span<const Vec3f> pts = cloud.points;

  const GroundResult ground = estimate_ground(pts, config.ground, rng);
  res.ground_plane = ground.plane;
  res.num_ground = ground.num_ground;
  res.timings.add("ground", sw.lap_ms());

  std::vector<std::uint32_t> above;
  for (std::uint32_t i = 0; i < pts.size(); ++i)
    if (ground.height[i] > config.ground.d_plane) above.push_back(i);
  auto clusters = euclidean_clusters(pts, above, config.clustering);
  attach_low_band(pts, ground.height, config, clusters);
  res.timings.add("clustering", sw.lap_ms());

  std::vector<Segment> objects, planar, terrain;
  for (auto& cl : clusters) {
    Segment s = make_segment(pts, std::move(cl), config, rng);
    if (s.stacked_fraction < config.verticality.min_stacked_fraction)
      terrain.push_back(std::move(s));
    else
      (s.planar ? planar : objects).push_back(std::move(s));
  }
  res.timings.add("shape_checks", sw.lap_ms());

  res.labels.assign(pts.size(), kLabelNone);
  for (std::uint32_t i = 0; i < pts.size(); ++i)
    if (ground.height[i] <= config.ground.d_plane) res.labels[i] = kLabelGround;
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
