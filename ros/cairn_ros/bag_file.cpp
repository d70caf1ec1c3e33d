// Compiled as C++17 (ros/CMakeLists.txt): Debian's ROS 1 message headers.
#include "cairn_ros/bag_file.hpp"

#include <geometry_msgs/TransformStamped.h>
#include <nav_msgs/Odometry.h>
#include <ros/exception.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/JointState.h>
#include <sensor_msgs/PointCloud2.h>
#include <std_msgs/String.h>
#include <tf2_msgs/TFMessage.h>

#include <algorithm>
#include <cstring>

#include "cairn/core/error.hpp"

namespace cairn::bag::file {
namespace {

// A bag's record time must be at least ros::TIME_MIN; run directories start at t = 0.
::ros::Time stamp_of(double t) { return ::ros::Time(std::max(t, 0.0)); }
::ros::Time record_time(double t) { return std::max(stamp_of(t), ::ros::TIME_MIN); }

/// Runs `f`, turning ROS's exceptions (rosbag's BagIOException and BagFormatException, a stream
/// overrun of a truncated message, ros::Time out of range) into InputErrors naming the bag.
template <class F>
auto input_errors(const std::string& path, F&& f) {
  try {
    return f();
  } catch (const InputError&) {
    throw;
  } catch (const std::runtime_error& e) {  // ros::Exception derives from it
    throw InputError(path + ": " + e.what());
  }
}

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

sensor_msgs::PointField field(const std::string& name, std::uint32_t offset, std::uint8_t type) {
  sensor_msgs::PointField f;
  f.name = name;
  f.offset = offset;
  f.datatype = type;
  f.count = 1;
  return f;
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
    for (const long o : {ox, oy, oz}) c.xyz.push_back(read_at<float>(p + o));
    if (ot >= 0) c.time.push_back(read_at<float>(p + ot));
    if (oring >= 0) c.ring.push_back(read_at<std::uint16_t>(p + oring));
    if (orgb >= 0) {
      const std::uint32_t rgb = read_at<std::uint32_t>(p + orgb);
      c.rgb.insert(c.rgb.end(), {std::uint8_t(rgb >> 16), std::uint8_t(rgb >> 8), std::uint8_t(rgb)});
    }
  }
  return c;
}

}  // namespace

struct Writer::Impl {
  std::string path;
  ::rosbag::Bag bag;
  template <class M>
  void write(const std::string& topic, double t, const M& msg) {
    input_errors(path, [&] {
      bag.write(topic, record_time(t), msg);
      return 0;
    });
  }
};

Writer::Writer(const std::string& path) : impl_(std::make_unique<Impl>()) {
  impl_->path = path;
  input_errors(path, [&] {
    impl_->bag.open(path, ::rosbag::bagmode::Write);
    impl_->bag.setCompression(::rosbag::compression::LZ4);
    return 0;
  });
}

Writer::~Writer() = default;

void Writer::text(const std::string& topic, double t, const std::string& text) {
  std_msgs::String m;
  m.data = text;
  impl_->write(topic, t, m);
  ++messages_[topic];
}

void Writer::transforms(const std::string& topic, double t, const std::vector<FrameTransform>& transforms) {
  tf2_msgs::TFMessage m;
  for (const FrameTransform& f : transforms) {
    geometry_msgs::TransformStamped ts;
    ts.header.stamp = stamp_of(t);
    ts.header.frame_id = f.parent;
    ts.child_frame_id = f.child;
    ts.transform = to_msg(f.T);
    m.transforms.push_back(ts);
  }
  impl_->write(topic, t, m);
  ++messages_[topic];
}

void Writer::odometry(const std::string& topic, double t, const std::string& frame, const std::string& child,
                      const Transform& pose) {
  nav_msgs::Odometry o;
  o.header.stamp = stamp_of(t);
  o.header.frame_id = frame;
  o.child_frame_id = child;
  o.pose.pose.position.x = pose.t[0];
  o.pose.pose.position.y = pose.t[1];
  o.pose.pose.position.z = pose.t[2];
  o.pose.pose.orientation = to_msg(pose).rotation;
  impl_->write(topic, t, o);
  ++messages_[topic];
}

void Writer::joints(const std::string& topic, double t, const std::vector<std::string>& names,
                    const std::vector<double>& positions) {
  sensor_msgs::JointState m;
  m.header.stamp = stamp_of(t);
  m.name = names;
  m.position = positions;
  impl_->write(topic, t, m);
  ++messages_[topic];
}

void Writer::cloud(const std::string& topic, const Cloud& cloud) {
  impl_->write(topic, cloud.stamp, to_msg(cloud));
  ++messages_[topic];
}

void Writer::close() {
  input_errors(impl_->path, [&] {
    impl_->bag.close();
    return 0;
  });
}

struct Reader::Impl {
  std::string path;
  bool decode = false;
  ::rosbag::Bag bag;
  std::unique_ptr<::rosbag::View> view;  // neither copyable nor movable; the iterator points into it
  ::rosbag::View::iterator it;
};

Reader::Reader(const std::string& path, const std::vector<std::string>& topics, bool decode_clouds)
    : impl_(std::make_unique<Impl>()) {
  impl_->path = path;
  impl_->decode = decode_clouds;
  input_errors(path, [&] {
    impl_->bag.open(path, ::rosbag::bagmode::Read);
    impl_->view = std::make_unique<::rosbag::View>(impl_->bag, ::rosbag::TopicQuery(topics));
    impl_->it = impl_->view->begin();
    return 0;
  });
}

Reader::~Reader() = default;

bool Reader::next(Message& out) {
  Impl& s = *impl_;
  return input_errors(s.path, [&] {
    if (s.it == s.view->end()) return false;
    const ::rosbag::MessageInstance& m = *s.it;
    out = Message{};
    out.topic = m.getTopic();
    out.type = m.getDataType();
    const std::string what = s.path + ": " + out.topic;
    if (const auto str = m.instantiate<std_msgs::String>()) {
      out.kind = Message::Kind::text;
      out.stamp = m.getTime().toSec();
      out.text = str->data;
    } else if (const auto tf = m.instantiate<tf2_msgs::TFMessage>()) {
      out.kind = Message::Kind::transforms;
      for (const auto& ts : tf->transforms) {
        out.stamp = ts.header.stamp.toSec();
        out.transforms.push_back({ts.header.frame_id, ts.child_frame_id, from_msg(ts.transform)});
      }
    } else if (const auto o = m.instantiate<nav_msgs::Odometry>()) {
      out.kind = Message::Kind::odometry;
      out.stamp = o->header.stamp.toSec();
      out.frame = o->header.frame_id;
      out.child = o->child_frame_id;
      const auto& p = o->pose.pose;
      out.pose = {{p.position.x, p.position.y, p.position.z}, {p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w}};
    } else if (const auto j = m.instantiate<sensor_msgs::JointState>()) {
      if (j->position.size() != j->name.size()) throw InputError(what + ": as many joint positions as names expected");
      out.kind = Message::Kind::joints;
      out.stamp = j->header.stamp.toSec();
      out.names = j->name;
      out.positions = j->position;
    } else if (const auto c = m.instantiate<sensor_msgs::PointCloud2>()) {
      out.kind = Message::Kind::cloud;
      out.cloud = from_msg(*c, s.decode, what);
      out.stamp = out.cloud.stamp;
    } else {
      throw InputError(what + ": unexpected message type " + out.type);
    }
    ++s.it;
    return true;
  });
}

}  // namespace cairn::bag::file
