#include "cairn/grasp/planning_cloud.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "cairn/core/cell_map.hpp"
#include "cairn/core/error.hpp"
#include "cairn/core/kdtree.hpp"
#include "cairn/core/normals.hpp"
#include "cairn/core/voxel_grid.hpp"
#include "cairn/core/units.hpp"

namespace cairn::grasp {
namespace {

constexpr unsigned kGroundSeed = 1;  // RANSAC of the ground plane (deterministic planning)
constexpr float kSearchMargin = 1e-3f;   // relative: the object test's ball beyond the float rounding
constexpr std::size_t kLabelGrain = 2048;  // points per parallel task

struct CropRegion {
  Vec3d centre = Vec3d::Zero();  // the model's centroid
  double radius = 0.0;           // horizontal
  double z_min = 0.0, z_max = 0.0;
  [[nodiscard]] bool contains(const Vec3d& p) const {
    return (p - centre).head<2>().norm() <= radius && p.z() >= z_min && p.z() <= z_max;
  }
};

CropRegion crop_region(const PointCloud& object, double margin) {
  CropRegion r;
  r.centre = object.origin + centroid(object.points).cast<double>();
  double reach = 0.0, z_lo = std::numeric_limits<double>::max(), z_hi = std::numeric_limits<double>::lowest();
  for (std::size_t i = 0; i < object.size(); ++i) {
    const Vec3d p = object.world(i);
    reach = std::max(reach, (p - r.centre).head<2>().norm());
    z_lo = std::min(z_lo, p.z());
    z_hi = std::max(z_hi, p.z());
  }
  r.radius = reach + margin;
  r.z_min = z_lo - margin;
  r.z_max = z_hi + margin;
  return r;
}

/// Appends the points of `source` inside the crop (relative to out.origin), labelled `kind`.
void add_cropped(PointCloud& out, const PointCloud& source, const CropRegion& crop, std::int32_t kind) {
  for (std::size_t i = 0; i < source.size(); ++i) {
    const Vec3d p = source.world(i);
    if (!crop.contains(p)) continue;
    out.points.push_back((p - out.origin).cast<float>());
    out.labels.push_back(kind);
  }
}

/// Object points: within `distance` of the model.
void label_object(PointCloud& cloud, const PointCloud& model, double distance) {
  std::vector<Vec3f> local(model.size());
  for (std::size_t i = 0; i < model.size(); ++i) local[i] = (model.world(i) - cloud.origin).cast<float>();
  const KdTree tree(local);
  const float d2 = float(distance * distance);
  // A model point at squared distance <= d2 (the nearest's test) lies strictly inside the
  // slightly larger search radius, with its distance computed as the nearest search would: the
  // same labels as from the nearest point, at the cost of a small-ball search.
  const float search = std::sqrt(d2) * (1.0f + kSearchMargin);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, cloud.size(), kLabelGrain), [&](const auto& r) {
    for (std::size_t i = r.begin(); i != r.end(); ++i) {
      bool near = false;
      tree.for_each_in_radius(cloud.points[i], search, [&](std::uint32_t, float sq) { near = near || sq <= d2; });
      cloud.labels[i] = near ? kObject : kEnvironment;
    }
  });
}

std::optional<Plane> ground_plane(const PointCloud& cloud, const PlanningCloudConfig& c) {
  std::vector<std::uint32_t> env;
  for (std::size_t i = 0; i < cloud.size(); ++i)
    if (cloud.labels[i] == kEnvironment) env.push_back(std::uint32_t(i));
  if (env.size() < 3) return std::nullopt;
  RansacPlaneConfig rc{.distance = c.ground_distance, .axis = Vec3f::UnitZ(), .max_tilt = c.ground_max_tilt_deg * kDeg};
  std::mt19937_64 rng(kGroundSeed);
  const PlaneFit fit = fit_plane_ransac(cloud.points, env, rc, rng);
  if (!fit.found) return std::nullopt;
  Plane p = fit.plane;
  if (p.normal.z() < 0) {
    p.normal = -p.normal;
    p.d = -p.d;
  }
  return p;
}

}  // namespace

double gripper_full_width(const GripperConfig& g) {
  const double jaws = max_opening(g) + 2.0 * g.jaw_thickness;
  return std::max({g.palm_width, jaws, g.hinge_spacing + 2.0 * g.jaw_thickness});
}

namespace {

/// Per voxel-sized column of the fill grid: what was seen there.
struct FillCell {
  bool environment = false;
  float object_z = std::numeric_limits<float>::max();
  double residual = 0.0;  // the seen ground's mean height above the plane (ground points only)
  int ground = 0;         // seen ground points (environment within the band of the plane)
  bool known = false;     // residual known: seen ground, or propagated from it
};

/// Carries the seen ground's height above the plane into the columns nobody saw, ring by ring
/// from the seen ones (each new column the mean of its known 8-neighbours): the fill follows the
/// terrain next to it instead of the plane, which undulating ground leaves by up to its band.
void propagate_residuals(std::vector<FillCell>& cells, std::size_t nx, std::size_t ny) {
  const auto for_neighbours = [&](std::size_t k, auto&& f) {
    const std::size_t ix = k % nx, iy = k / nx;
    for (std::size_t y = iy > 0 ? iy - 1 : 0; y <= std::min(ny - 1, iy + 1); ++y)
      for (std::size_t x = ix > 0 ? ix - 1 : 0; x <= std::min(nx - 1, ix + 1); ++x)
        if (y * nx + x != k) f(y * nx + x);
  };
  std::vector<std::uint8_t> queued(cells.size(), 0);
  std::vector<std::size_t> ring, next;
  for (std::size_t k = 0; k < cells.size(); ++k) {
    cells[k].known = cells[k].ground > 0;
    queued[k] = cells[k].known;
  }
  for (std::size_t k = 0; k < cells.size(); ++k)  // the first ring: unknown next to seen ground
    if (cells[k].known) for_neighbours(k, [&](std::size_t j) { if (!queued[j]) queued[j] = 1, ring.push_back(j); });
  std::vector<double> value;
  while (!ring.empty()) {
    value.assign(ring.size(), 0.0);
    for (std::size_t r = 0; r < ring.size(); ++r) {
      double sum = 0.0;
      int n = 0;
      for_neighbours(ring[r], [&](std::size_t j) { if (cells[j].known) sum += cells[j].residual, ++n; });
      value[r] = sum / n;  // n > 0: a ring cell borders a known one
    }
    next.clear();
    for (std::size_t r = 0; r < ring.size(); ++r) {
      cells[ring[r]].residual = value[r];
      cells[ring[r]].known = true;
      for_neighbours(ring[r], [&](std::size_t j) { if (!queued[j]) queued[j] = 1, next.push_back(j); });
    }
    ring.swap(next);
  }
}

}  // namespace

std::size_t fill_ground(PointCloud& cloud, const Plane& plane, double voxel, double follow_band) {
  if (cloud.empty() || std::abs(plane.normal.z()) < 1e-3f) return 0;
  const Aabb box = bounds(cloud.points);
  const auto nx = std::size_t(std::floor((box.max.x() - box.min.x()) / voxel)) + 1;
  const auto ny = std::size_t(std::floor((box.max.y() - box.min.y()) / voxel)) + 1;
  std::vector<FillCell> cells(nx * ny);
  auto cell_of = [&](const Vec3f& p) {
    const auto ix = std::min(nx - 1, std::size_t((p.x() - box.min.x()) / voxel));
    const auto iy = std::min(ny - 1, std::size_t((p.y() - box.min.y()) / voxel));
    return iy * nx + ix;
  };
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    FillCell& c = cells[cell_of(cloud.points[i])];
    if (cloud.labels[i] == kObject) {
      c.object_z = std::min(c.object_z, cloud.points[i].z());
      continue;
    }
    c.environment = true;
    const double r = plane.signed_distance(cloud.points[i]);
    if (std::abs(r) <= follow_band) c.residual += (r - c.residual) / ++c.ground;  // running mean
  }
  if (follow_band > 0.0) propagate_residuals(cells, nx, ny);
  std::size_t added = 0;
  for (std::size_t iy = 0; iy < ny; ++iy) {
    for (std::size_t ix = 0; ix < nx; ++ix) {
      const FillCell& c = cells[iy * nx + ix];
      if (c.environment) continue;
      const float x = box.min.x() + float((double(ix) + 0.5) * voxel), y = box.min.y() + float((double(iy) + 0.5) * voxel);
      const float z = (float(c.residual) - (plane.normal.x() * x + plane.normal.y() * y + plane.d)) / plane.normal.z();
      if (z > c.object_z - float(voxel)) continue;  // the object rests here: no ground inside it
      cloud.points.emplace_back(x, y, z);
      cloud.labels.push_back(kGroundFill);
      ++added;
    }
  }
  return added;
}

Vec3d solid_centroid(const PointCloud& cloud, const Plane& plane, double voxel) {
  CellMap index;  // column cell -> position in `top`
  std::vector<Vec3d> top;  // per column: its highest object point
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    if (cloud.labels[i] != kObject) continue;
    const Vec3f& p = cloud.points[i];
    const auto next = std::uint32_t(top.size());
    const std::uint32_t at = index.insert(
        CellMap::key(std::int64_t(std::floor(p.x() / voxel)), std::int64_t(std::floor(p.y() / voxel)), 0), next);
    if (at == next) top.push_back(p.cast<double>());
    else if (double(p.z()) > top[at].z()) top[at] = p.cast<double>();
  }
  Vec3d sum = Vec3d::Zero();
  double mass = 0.0;
  const Vec3d n = plane.normal.cast<double>();
  for (const Vec3d& t : top) {
    const double h = n.dot(t) + double(plane.d);  // height above the ground
    if (h <= 0.0) continue;
    sum += h * (t - 0.5 * h * n);
    mass += h;
  }
  if (mass > 0.0) return sum / mass;
  Vec3d mean = Vec3d::Zero();  // nothing above the ground: the object points' mean
  double count = 0.0;
  for (std::size_t i = 0; i < cloud.size(); ++i)
    if (cloud.labels[i] == kObject) mean += cloud.points[i].cast<double>(), count += 1.0;
  return count > 0.0 ? Vec3d(mean / count) : mean;
}

void orient_normals(PointCloud& cloud, double radius, const Vec3f& object_centroid, const Vec3f& up) {
  const KdTree tree(cloud.points);
  std::vector<Vec3f> object;
  std::vector<std::size_t> where;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    if (cloud.labels[i] != kObject) continue;
    object.push_back(cloud.points[i]);
    where.push_back(i);
  }
  NormalConfig nc;
  nc.radius = radius;
  const NormalResult r = estimate_normals(object, tree, nc);
  cloud.normals.assign(cloud.size(), up);
  for (std::size_t k = 0; k < where.size(); ++k) {
    Vec3f n = r.normals[k];
    if (n.dot(object[k] - object_centroid) < 0) n = -n;
    cloud.normals[where[k]] = n;
  }
}

PlanningCloud build_planning_cloud(const PointCloud& map, const PointCloud& object, const PointCloud* drone,
                                   const GripperConfig& gripper, const PlanningCloudConfig& c) {
  if (object.empty()) throw InputError("grasp planning: the object's model has no points");
  object.check_finite("object model");
  map.check_finite("map");
  if (drone) drone->check_finite("drone cloud");
  const CropRegion crop = crop_region(object, c.margin_factor * gripper_full_width(gripper));
  PlanningCloud pc;
  pc.centroid = crop.centre;
  PointCloud merged;
  merged.origin = crop.centre;
  add_cropped(merged, map, crop, kEnvironment);
  add_cropped(merged, drone ? *drone : object, crop, kEnvironment);  // Sec. 5.2: drone, else the model
  label_object(merged, object, c.object_distance_voxels * c.voxel);
  pc.cloud = voxel_downsample(merged, {.res_voxel = c.voxel, .n_min = 1});
  pc.ground = ground_plane(pc.cloud, c);
  if (pc.ground) {
    if (c.ground_fill)
      pc.fill_points = fill_ground(pc.cloud, *pc.ground, c.voxel, c.fill_follows_ground ? c.ground_distance : 0.0);
    pc.ground_normal = pc.ground->normal.cast<double>();
  }
  pc.mass_centroid = pc.ground ? pc.cloud.origin + solid_centroid(pc.cloud, *pc.ground, c.voxel) : pc.centroid;
  // Columns down to the ground fill the space under a rounded stone's belly (too low); the
  // surface points lie on its top and sides (too high): the height between the two.
  pc.mass_centroid.z() = 0.5 * (pc.mass_centroid.z() + pc.centroid.z());
  orient_normals(pc.cloud, c.normal_radius_voxels * c.voxel, Vec3f::Zero(), pc.ground_normal.cast<float>());
  for (const std::int32_t l : pc.cloud.labels) (l == kObject ? pc.object_points : pc.environment_points) += 1;
  pc.environment_points -= pc.fill_points;
  return pc;
}

}  // namespace cairn::grasp
