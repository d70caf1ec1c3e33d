#pragma once
// What every cairn node shares (C++17, roscpp): the CLI's configuration from ~config and ~set,
// callbacks that report bad input instead of ending the node, the map-edit message.
#include <cairn_ros/MapEdit.h>
#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>

#include <exception>
#include <string>
#include <vector>

#include "cairn_ros/bag_file.hpp"
#include "cairn_ros/messages.hpp"

namespace cairn::node {

namespace file = ::cairn::bag::file;

/// ~config (the CLI's YAML file, empty: defaults) and ~set (key.path=value overrides).
struct ConfigParams {
  std::string file;
  std::vector<std::string> overrides;
};
inline ConfigParams config_params(const ros::NodeHandle& pnh) {
  ConfigParams c;
  pnh.param<std::string>("config", c.file, "");
  pnh.param<std::vector<std::string>>("set", c.overrides, {});
  return c;
}

/// Runs `f`; an exception (bad input) is logged, counted and returned as its message (empty when
/// `f` completed): it never ends the node.
template <class F>
std::string guarded(const char* node, std::size_t& errors, F&& f) {
  try {
    f();
    return {};
  } catch (const std::exception& e) {
    ROS_ERROR_THROTTLE(1.0, "%s: %s", node, e.what());
    ++errors;
    return e.what()[0] ? e.what() : "error";
  }
}

/// Subscribes to the newest cloud on `topic` (queue 1, a latched map or drone cloud): each message
/// decoded and handed to `take(cloud, stamp)`; a bad one logged and counted (guarded), never fatal.
template <class F>
ros::Subscriber subscribe_cloud(ros::NodeHandle& nh, const std::string& topic, const char* node, std::size_t& errors,
                                const char* what, F take) {
  return nh.subscribe<sensor_msgs::PointCloud2>(
      topic, 1, [node, &errors, what, take](const sensor_msgs::PointCloud2ConstPtr& m) {
        (void)guarded(node, errors, [&] { take(file::from_msg(*m, true, what), m->header.stamp.toSec()); });
      });
}

/// Runs a node's `body` (build the core and the node, spin): a bad configuration or database is
/// fatal at start, with exit 2.
template <class F>
int run_node(const char* node, F&& body) {
  try {
    body();
  } catch (const std::exception& e) {
    ROS_FATAL("%s: %s", node, e.what());
    return 2;
  }
  return 0;
}

inline cairn_ros::MapEdit to_msg(const file::MapEdit& e, const std::string& frame) {
  cairn_ros::MapEdit m;
  m.kind = e.kind;
  m.center.x = e.center[0];
  m.center.y = e.center[1];
  m.center.z = e.center[2];
  m.radius = e.radius;
  m.distance = e.distance;
  file::Cloud points = e.points;
  points.frame = frame;
  m.points = file::to_msg(points);
  return m;
}

inline file::MapEdit from_msg(const cairn_ros::MapEdit& m) {
  return {m.kind, {m.center.x, m.center.y, m.center.z}, m.radius, m.distance,
          file::from_msg(m.points, true, "map edit")};
}

}  // namespace cairn::node
