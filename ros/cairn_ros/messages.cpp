// Compiled as C++17 (ros/CMakeLists.txt): Debian's ROS 1 message headers.
#include "cairn_ros/messages.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "cairn/core/error.hpp"

namespace cairn::bag::file {
namespace {

sensor_msgs::PointField field(const std::string& name, std::uint32_t offset, std::uint8_t type) {
  sensor_msgs::PointField f;
  f.name = name;
  f.offset = offset;
  f.datatype = type;
  f.count = 1;
  return f;
}

/// Offset of a field with the expected datatype inside a point, or -1 when absent; throws when
/// it has another datatype or does not fit the point.
long offset_of(const sensor_msgs::PointCloud2& m, const std::string& name, std::uint8_t type, std::uint32_t size,
               const std::string& what) {
  for (const auto& f : m.fields)
    if (f.name == name) {
      if (f.datatype != type) throw InputError(what + ": field '" + name + "' has an unexpected datatype");
      if (std::size_t(f.offset) + size > m.point_step) throw InputError(what + ": field '" + name + "' beyond point_step");
      return long(f.offset);
    }
  return -1;
}

template <class T>
T read_at(const std::uint8_t* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  return v;
}

}  // namespace

::ros::Time stamp_of(double t) { return ::ros::Time(std::max(t, 0.0)); }

geometry_msgs::Transform to_msg(const Transform& T) {
  geometry_msgs::Transform m;
  m.translation.x = T.t[0];
  m.translation.y = T.t[1];
  m.translation.z = T.t[2];
  m.rotation.x = T.q[0];
  m.rotation.y = T.q[1];
  m.rotation.z = T.q[2];
  m.rotation.w = T.q[3];
  return m;
}

Transform from_msg(const geometry_msgs::Transform& m) {
  return {{m.translation.x, m.translation.y, m.translation.z}, {m.rotation.x, m.rotation.y, m.rotation.z, m.rotation.w}};
}

geometry_msgs::Pose to_pose(const Transform& T) {
  const geometry_msgs::Transform m = to_msg(T);
  geometry_msgs::Pose p;
  p.position.x = m.translation.x;
  p.position.y = m.translation.y;
  p.position.z = m.translation.z;
  p.orientation = m.rotation;
  return p;
}

Transform from_pose(const geometry_msgs::Pose& m) {
  geometry_msgs::Transform t;
  t.translation.x = m.position.x;
  t.translation.y = m.position.y;
  t.translation.z = m.position.z;
  t.rotation = m.orientation;
  return from_msg(t);
}

sensor_msgs::PointCloud2 to_msg(const Cloud& c) {
  sensor_msgs::PointCloud2 m;
  m.header.stamp = stamp_of(c.stamp);
  m.header.frame_id = c.frame;
  const std::size_t n = c.xyz.size() / 3;
  m.height = 1;
  m.width = std::uint32_t(n);
  m.fields = {field("x", 0, sensor_msgs::PointField::FLOAT32), field("y", 4, sensor_msgs::PointField::FLOAT32),
              field("z", 8, sensor_msgs::PointField::FLOAT32)};
  std::uint32_t step = 12;
  const bool timed = !c.time.empty(), ringed = !c.ring.empty(), coloured = !c.rgb.empty();
  if (timed) m.fields.push_back(field("time", step, sensor_msgs::PointField::FLOAT32)), step += 4;
  if (ringed) m.fields.push_back(field("ring", step, sensor_msgs::PointField::UINT16)), step += 4;  // 2 + padding
  if (coloured) m.fields.push_back(field("rgb", step, sensor_msgs::PointField::FLOAT32)), step += 4;
  m.is_bigendian = false;
  m.point_step = step;
  m.row_step = step * m.width;
  m.is_dense = true;
  m.data.assign(std::size_t(m.row_step), 0);
  for (std::size_t i = 0; i < n; ++i) {
    std::uint8_t* p = m.data.data() + i * step;
    std::memcpy(p, &c.xyz[3 * i], 12);
    std::uint32_t o = 12;
    if (timed) std::memcpy(p + o, &c.time[i], 4), o += 4;
    if (ringed) std::memcpy(p + o, &c.ring[i], 2), o += 4;
    if (coloured) {  // PCL's packed rgb: 0x00RRGGBB in a float's bytes
      const std::uint32_t rgb = (std::uint32_t(c.rgb[3 * i]) << 16) | (std::uint32_t(c.rgb[3 * i + 1]) << 8) |
                                std::uint32_t(c.rgb[3 * i + 2]);
      std::memcpy(p + o, &rgb, 4);
    }
  }
  return m;
}

Cloud from_msg(const sensor_msgs::PointCloud2& m, bool decode, const std::string& what) {
  Cloud c;
  c.stamp = m.header.stamp.toSec();
  c.frame = m.header.frame_id;
  if (!decode) return c;
  if (m.is_bigendian) throw InputError(what + ": big-endian PointCloud2 is not supported");
  if (std::size_t(m.row_step) < std::size_t(m.width) * m.point_step || m.data.size() < std::size_t(m.height) * m.row_step)
    throw InputError(what + ": PointCloud2 data shorter than its width, height and steps say");
  using F = sensor_msgs::PointField;
  const long ox = offset_of(m, "x", F::FLOAT32, 4, what), oy = offset_of(m, "y", F::FLOAT32, 4, what),
             oz = offset_of(m, "z", F::FLOAT32, 4, what);
  if (ox < 0 || oy < 0 || oz < 0) throw InputError(what + ": PointCloud2 without float32 x, y and z");
  const long ot = offset_of(m, "time", F::FLOAT32, 4, what), oring = offset_of(m, "ring", F::UINT16, 2, what),
             orgb = offset_of(m, "rgb", F::FLOAT32, 4, what);
  const std::size_t n = std::size_t(m.width) * m.height;
  c.xyz.reserve(3 * n);
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint8_t* p = m.data.data() + (i / m.width) * m.row_step + (i % m.width) * m.point_step;
    const float x = read_at<float>(p + ox), y = read_at<float>(p + oy), z = read_at<float>(p + oz);
    // No return (organised LiDAR clouds mark it with NaN): no point, as PCL's removeNaNFromPointCloud.
    if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z)) continue;
    c.xyz.insert(c.xyz.end(), {x, y, z});
    if (ot >= 0) c.time.push_back(read_at<float>(p + ot));
    if (oring >= 0) c.ring.push_back(read_at<std::uint16_t>(p + oring));
    if (orgb >= 0) {
      const std::uint32_t rgb = read_at<std::uint32_t>(p + orgb);
      c.rgb.insert(c.rgb.end(), {std::uint8_t(rgb >> 16), std::uint8_t(rgb >> 8), std::uint8_t(rgb)});
    }
  }
  return c;
}

}  // namespace cairn::bag::file
