#include "cairn/mapping/map_edit.hpp"

#include <cmath>
#include <cstdint>
#include <vector>

#include "cairn/core/error.hpp"
#include "cairn/core/transform.hpp"

namespace cairn {

MapEdit MapEdit::sphere(const Vec3d& center, double radius) {
  MapEdit e;
  e.kind = Kind::remove_sphere;
  e.center = center;
  e.radius = radius;
  return e;
}

MapEdit MapEdit::near(PointCloud points, double distance, const Vec3d& center, double radius) {
  MapEdit e;
  e.kind = Kind::remove_near;
  e.points = std::move(points);
  e.distance = distance;
  e.center = center;
  e.radius = radius;
  return e;
}

MapEdit MapEdit::add(PointCloud points) {
  MapEdit e;
  e.kind = Kind::insert;
  e.points = std::move(points);
  return e;
}

void MapEdit::validate() const {
  const std::string what = std::string("map edit (") + to_string(kind) + ")";
  if (kind != Kind::insert && (!center.allFinite() || !std::isfinite(radius) || radius < 0))
    throw InputError(what + ": needs a finite centre and radius >= 0");
  if (kind == Kind::remove_near && (!std::isfinite(distance) || distance <= 0))
    throw InputError(what + ": needs a finite distance > 0");
  if (kind == Kind::remove_near && points.empty()) throw InputError(what + ": needs the object's points");
  if (kind != Kind::remove_sphere) {
    if (!points.origin.allFinite()) throw InputError(what + ": the points' origin is not finite");
    points.check_finite(what + " points");
  }
}

MapEdit MapEdit::transformed(const Eigen::Isometry3d& D) const {
  MapEdit e = *this;
  e.center = D * center;
  if (!points.empty()) transform_cloud(e.points, D);
  return e;
}

const char* to_string(MapEdit::Kind kind) {
  switch (kind) {
    case MapEdit::Kind::remove_sphere: return "remove_sphere";
    case MapEdit::Kind::remove_near: return "remove_near";
    case MapEdit::Kind::insert: return "insert";
  }
  return "?";
}

MapEdit::Kind map_edit_kind_from_string(const std::string& name) {
  for (auto k : {MapEdit::Kind::remove_sphere, MapEdit::Kind::remove_near, MapEdit::Kind::insert})
    if (name == to_string(k)) return k;
  throw InputError("unknown map edit kind '" + name + "' (remove_sphere, remove_near, insert)");
}

MapEditRegion::MapEditRegion(const MapEdit& edit) : edit_(edit) {
  if (edit.kind == MapEdit::Kind::remove_near) tree_ = std::make_unique<KdTree>(edit.points.points);
}

MapEditRegion::~MapEditRegion() = default;

bool MapEditRegion::removes(const Vec3d& world) const {
  if (edit_.kind == MapEdit::Kind::insert) return false;
  if ((world - edit_.center).squaredNorm() > edit_.radius * edit_.radius) return false;
  if (edit_.kind == MapEdit::Kind::remove_sphere) return true;
  float d2 = 0.0f;
  (void)tree_->nearest_within((world - edit_.points.origin).cast<float>(), sq_dist_bound(edit_.distance), &d2);
  return double(d2) <= edit_.distance * edit_.distance;
}

std::size_t apply_edit(PointCloud& map, const MapEdit& edit) {
  edit.validate();
  if (edit.kind == MapEdit::Kind::insert) {
    append(map, edit.points);
    return 0;
  }
  const MapEditRegion region(edit);
  std::vector<std::uint32_t> keep;
  keep.reserve(map.size());
  for (std::size_t i = 0; i < map.size(); ++i)
    if (!region.removes(map.world(i))) keep.push_back(std::uint32_t(i));
  const std::size_t removed = map.size() - keep.size();
  if (removed > 0) map = select(map, keep);
  return removed;
}

}  // namespace cairn
