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
#include "cairn_ros/messages.hpp"

namespace cairn::bag::file {
namespace {

// A bag's record time must be at least ros::TIME_MIN; run directories start at t = 0.
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

}  // namespace

struct Writer::Impl {
  std::string path;
  ::rosbag::Bag bag;
  /// `latched`: the connection says latching=1, so that `rosbag play` latches the topic (a
  /// late subscriber still gets the robot model and the extrinsics).
  template <class M>
  void write(const std::string& topic, double t, const M& msg, bool latched = false) {
    boost::shared_ptr<::ros::M_string> header;
    if (latched) {  // a given header is stored as is: the type fields too
      header = boost::make_shared<::ros::M_string>();
      (*header)["type"] = ::ros::message_traits::datatype<M>();
      (*header)["md5sum"] = ::ros::message_traits::md5sum<M>();
      (*header)["message_definition"] = ::ros::message_traits::definition<M>();
      (*header)["callerid"] = "/cairn";
      (*header)["latching"] = "1";
    }
    input_errors(path, [&] {
      bag.write(topic, record_time(t), msg, header);
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

void Writer::text(const std::string& topic, double t, const std::string& text, bool latched) {
  std_msgs::String m;
  m.data = text;
  impl_->write(topic, t, m, latched);
  ++messages_[topic];
}

void Writer::transforms(const std::string& topic, double t, const std::vector<FrameTransform>& transforms,
                        bool latched) {
  tf2_msgs::TFMessage m;
  for (const FrameTransform& f : transforms) {
    geometry_msgs::TransformStamped ts;
    ts.header.stamp = stamp_of(t);
    ts.header.frame_id = f.parent;
    ts.child_frame_id = f.child;
    ts.transform = to_msg(f.T);
    m.transforms.push_back(ts);
  }
  impl_->write(topic, t, m, latched);
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
