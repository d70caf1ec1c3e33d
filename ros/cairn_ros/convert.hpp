#pragma once
// The plain data of bag_file.hpp <-> cairn's types (C++20 side of the ROS layer).
#include <Eigen/Geometry>
#include <cmath>
#include <string>

#include "cairn/core/error.hpp"
#include "cairn/core/point_cloud.hpp"
#include "cairn/mapping/mapper.hpp"
#include "cairn_ros/bag_file.hpp"

namespace cairn::bag {

inline file::Transform to_file(const Eigen::Isometry3d& T) {
  const Eigen::Quaterniond q(T.linear());
  return {{T.translation().x(), T.translation().y(), T.translation().z()}, {q.x(), q.y(), q.z(), q.w()}};
}

/// Throws InputError unless the quaternion is (close to) a unit one — a default-constructed ROS
/// pose has all zeros — or a value is not finite.
inline Eigen::Isometry3d from_file(const file::Transform& T) {
  constexpr double kUnitTolerance = 1e-3;  // |q| may differ from 1 by this (float round trips)
  const Eigen::Quaterniond q(T.q[3], T.q[0], T.q[1], T.q[2]);
  if (!q.coeffs().allFinite() || !Eigen::Vector3d(T.t[0], T.t[1], T.t[2]).allFinite() ||
      std::abs(q.norm() - 1.0) > kUnitTolerance)
    throw InputError("a pose needs finite values and a unit quaternion (|q| = " + std::to_string(q.norm()) + ")");
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.linear() = q.normalized().toRotationMatrix();
  out.translation() = Eigen::Vector3d(T.t[0], T.t[1], T.t[2]);
  return out;
}

/// x y z (and colours) of a decoded cloud.
inline PointCloud points_of(const file::Cloud& c) {
  PointCloud out;
  out.points.reserve(c.xyz.size() / 3);
  for (std::size_t i = 0; i + 2 < c.xyz.size(); i += 3) out.points.emplace_back(c.xyz[i], c.xyz[i + 1], c.xyz[i + 2]);
  if (!c.rgb.empty())
    for (std::size_t i = 0; i + 2 < c.rgb.size(); i += 3) out.colors.push_back({c.rgb[i], c.rgb[i + 1], c.rgb[i + 2]});
  return out;
}

/// A cloud as plain data (world coordinates in float32, colours when it has them).
inline file::Cloud cloud_of(const PointCloud& c, double stamp, const std::string& frame) {
  file::Cloud s;
  s.stamp = stamp;
  s.frame = frame;
  s.xyz.reserve(3 * c.size());
  for (std::size_t i = 0; i < c.size(); ++i) {
    const Vec3f p = c.world(i).cast<float>();
    s.xyz.insert(s.xyz.end(), {p.x(), p.y(), p.z()});
    if (c.has_colors()) s.rgb.insert(s.rgb.end(), {c.colors[i].r, c.colors[i].g, c.colors[i].b});
  }
  return s;
}

/// Map edits as plain data and back (the objects node publishes them, the mapper applies them).
inline file::MapEdit to_file(const MapEdit& e, const std::string& frame) {
  file::MapEdit out{.kind = to_string(e.kind), .center = {e.center.x(), e.center.y(), e.center.z()},
                    .radius = e.radius, .distance = e.distance, .points = cloud_of(e.points, 0.0, frame)};
  out.points.rgb.clear();
  return out;
}
inline MapEdit from_file(const file::MapEdit& e) {
  MapEdit out;
  out.kind = map_edit_kind_from_string(e.kind);
  out.center = Vec3d(e.center[0], e.center[1], e.center[2]);
  out.radius = e.radius;
  out.distance = e.distance;
  out.points = points_of(e.points);
  out.validate();
  return out;
}

/// A decoded Velodyne-style sweep as the Mapper takes it: absolute per-point times, the ring
/// field, t_end = stamp + `period`. Throws InputError (naming `what`) without time and ring.
inline RecordedSweep sweep_from(const file::Cloud& c, const std::string& sensor, double period, const std::string& what) {
  if (c.time.size() * 3 != c.xyz.size() || c.ring.size() * 3 != c.xyz.size())
    throw InputError(what + ": a sweep needs per-point 'time' (float32) and 'ring' (uint16) fields");
  RecordedSweep out;
  out.sensor = sensor;
  out.cloud = points_of(c);
  out.cloud.times.resize(c.time.size());
  for (std::size_t i = 0; i < c.time.size(); ++i) out.cloud.times[i] = c.stamp + double(c.time[i]);
  out.cloud.fields.push_back({"ring", std::vector<float>(c.ring.begin(), c.ring.end())});
  out.t_start = c.stamp;
  out.t_end = c.stamp + period;
  return out;
}

}  // namespace cairn::bag
