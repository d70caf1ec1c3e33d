#include "cairn/objects/support.hpp"

#include <algorithm>
#include <cmath>

#include "cairn/core/error.hpp"
#include "cairn/core/kdtree.hpp"
#include "cairn/core/units.hpp"

namespace cairn {
namespace {

/// The object's points in one frame (`origin`) for a kd-tree shared by every pair.
std::vector<Vec3f> points_in(const PointCloud& c, const Vec3d& origin) {
  std::vector<Vec3f> p;
  p.reserve(c.size());
  for (std::size_t i = 0; i < c.size(); ++i) p.push_back((c.world(i) - origin).cast<float>());
  return p;
}

Eigen::AlignedBox3d bounds(const PointCloud& c) {
  Eigen::AlignedBox3d b;
  for (std::size_t i = 0; i < c.size(); ++i) b.extend(c.world(i));
  return b;
}

/// Points of `a` within `d` of `tree`: their count and sum (frame of the trees).
void touching(std::span<const Vec3f> a, const KdTree& tree, float d, std::size_t& n, Vec3d& sum) {
  for (const Vec3f& p : a) {
    float d2 = 0.0f;
    (void)tree.nearest_within(p, d * d, &d2);
    if (d2 <= d * d) ++n, sum += p.cast<double>();
  }
}

}  // namespace

void SupportConfig::validate() const {
  require_config(contact_distance > 0, "objects", "support.contact_distance", "must be > 0");
  require_config(min_contact_points >= 1, "objects", "support.min_contact_points", "must be >= 1");
  require_config(min_elevation_deg > -90 && min_elevation_deg < 90, "objects", "support.min_elevation_deg",
                 "must lie in (-90, 90)");
}

std::vector<Contact> contacts(std::span<const ObjectRecord> objects, const SupportConfig& c) {
  c.validate();
  const Vec3d origin = objects.empty() ? Vec3d::Zero() : objects.front().centroid;
  std::vector<std::vector<Vec3f>> pts;
  std::vector<KdTree> trees;
  std::vector<Eigen::AlignedBox3d> boxes;
  for (const ObjectRecord& o : objects) {
    pts.push_back(points_in(o.cloud, origin));
    trees.emplace_back(pts.back());
    boxes.push_back(bounds(o.cloud));
  }
  std::vector<Contact> out;
  const auto d = float(c.contact_distance);
  for (std::size_t i = 0; i < objects.size(); ++i)
    for (std::size_t j = i + 1; j < objects.size(); ++j) {
      if (pts[i].empty() || pts[j].empty() || boxes[i].exteriorDistance(boxes[j]) > c.contact_distance) continue;
      Contact k;
      Vec3d sum = Vec3d::Zero();
      touching(pts[i], trees[j], d, k.points, sum);
      touching(pts[j], trees[i], d, k.points, sum);
      if (k.points < std::size_t(c.min_contact_points)) continue;
      const bool i_lower = objects[i].centroid.z() <= objects[j].centroid.z();
      k.lower = i_lower ? i : j;
      k.upper = i_lower ? j : i;
      k.at = origin + sum / double(k.points);
      const Vec3d v = k.at - objects[k.lower].centroid;
      k.elevation_deg = std::atan2(v.z(), v.head<2>().norm()) * kDegPerRad;
      k.rests = k.elevation_deg >= c.min_elevation_deg;
      out.push_back(k);
    }
  return out;
}

std::vector<int> loads(std::size_t n, std::span<const Contact> contacts) {
  std::vector<int> l(n, 0);
  for (const Contact& k : contacts) l[k.lower] += k.rests;
  return l;
}

std::size_t next_to_pick(std::span<const ObjectRecord> objects, std::span<const std::size_t> candidates,
                         const SupportConfig& c) {
  if (candidates.empty()) throw InputError("next_to_pick: no candidate");
  const std::vector<int> load = loads(objects.size(), contacts(objects, c));
  const auto free_first = [&](std::size_t a, std::size_t b) {
    if ((load[a] == 0) != (load[b] == 0)) return load[a] == 0;
    if (load[a] == 0) return objects[a].num_points > objects[b].num_points;  // Sec. 5.1: largest first
    return objects[a].centroid.z() > objects[b].centroid.z();                // all carry: the highest
  };
  return *std::min_element(candidates.begin(), candidates.end(), free_first);
}

}  // namespace cairn
