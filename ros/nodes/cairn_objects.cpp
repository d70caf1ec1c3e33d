// cairn_objects: the object database of paper Sec. 4.5 as a ROS 1 node (docs/ros.md). A thin adapter
// over ObjectsCore: the same SQLite file, library calls and JSON as `cairn objects`. C++17 (roscpp).
//
// Subscribes: ~map_topic (PointCloud2, default /cairn_mapper/map), ~merged_topic (default
// /cairn_registration/merged: the map merged with the registered drone cloud, segmented instead of
// the map until the first grasp). Services: ~segment (std_srvs/Trigger: segment, associate and
// store at the newest map's stamp; the association JSON in the answer's message), ~grasp and
// ~release (cairn_ros/ObjectEvent), ~realign (std_srvs/Trigger: every placed object re-aligned to
// the newest map). Publishes ~markers (MarkerArray, latched: each object's points in its colour —
// the HTML report's, the same across updates — and a label "id status"), ~objects
// (std_msgs/String, latched: `cairn objects list` JSON), ~map_edits (cairn_ros/MapEdit: a grasped
// object's points to remove from the map, for cairn_mapper).
// Parameters: ~database (the SQLite file, created when missing, kept across runs), ~config, ~set,
// ~map_topic, ~merged_topic, ~map_frame, ~view_voxel [m] (the markers' thinning).
#include <cairn_ros/MapEdit.h>
#include <cairn_ros/ObjectEvent.h>
#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>
#include <std_msgs/String.h>
#include <std_srvs/Trigger.h>
#include <visualization_msgs/MarkerArray.h>

#include <algorithm>
#include <string>

#include "cairn_ros/objects_core.hpp"
#include "node_support.hpp"

namespace {

using cairn::bag::ObjectsCore;
namespace file = cairn::bag::file;

constexpr double kPointSize = 0.04;   // [m] marker points
constexpr double kLabelHeight = 0.3;  // [m] text, and its lift above the centroid

class ObjectsNode {
 public:
  ObjectsNode(ros::NodeHandle& nh, ros::NodeHandle& pnh, ObjectsCore& core, const std::string& map_topic,
              const std::string& merged_topic, std::string map_frame, double view_voxel)
      : core_(core), map_frame_(std::move(map_frame)), view_voxel_(view_voxel) {
    map_sub_ = cairn::node::subscribe_cloud(nh, map_topic, "cairn_objects", errors_, "map",
                                            [this](const file::Cloud& c, double stamp) {
                                              core_.set_map(c);
                                              map_time_ = std::max(map_time_, stamp);
                                            });
    merged_sub_ = cairn::node::subscribe_cloud(nh, merged_topic, "cairn_objects", errors_, "merged map",
                                               [this](const file::Cloud& c, double stamp) {
                                                 core_.set_merged_map(c);
                                                 map_time_ = std::max(map_time_, stamp);  // segmented before a LiDAR map came
                                               });
    markers_pub_ = pnh.advertise<visualization_msgs::MarkerArray>("markers", 1, /*latch=*/true);
    objects_pub_ = pnh.advertise<std_msgs::String>("objects", 1, /*latch=*/true);
    edits_pub_ = pnh.advertise<cairn_ros::MapEdit>("map_edits", 10);
    services_.push_back(pnh.advertiseService("segment", &ObjectsNode::segment, this));
    services_.push_back(pnh.advertiseService("realign", &ObjectsNode::realign, this));
    services_.push_back(pnh.advertiseService("grasp", &ObjectsNode::grasp, this));
    services_.push_back(pnh.advertiseService("release", &ObjectsNode::release, this));
    guarded([&] { publish(); });  // what the database holds from earlier runs
  }

 private:
  template <class F>
  std::string guarded(F&& f) {
    return cairn::node::guarded("cairn_objects", errors_, std::forward<F>(f));
  }

  bool segment(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
    return trigger(res, [&] { return core_.segment(map_time_); });
  }
  bool realign(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
    return trigger(res, [&] { return core_.realign(map_time_); });
  }
  template <class F>
  bool trigger(std_srvs::Trigger::Response& res, F&& f) {
    const std::string error = guarded([&] { res.message = f(); });
    res.success = error.empty();
    if (!res.success) res.message = error;
    guarded([&] { publish(); });  // what is stored is answered as stored, whatever publishing does
    return true;
  }

  bool grasp(cairn_ros::ObjectEvent::Request& req, cairn_ros::ObjectEvent::Response& res) {
    return event(req, res, &ObjectsCore::grasp);
  }
  bool release(cairn_ros::ObjectEvent::Request& req, cairn_ros::ObjectEvent::Response& res) {
    return event(req, res, &ObjectsCore::release);
  }
  template <class Event>
  bool event(const cairn_ros::ObjectEvent::Request& req, cairn_ros::ObjectEvent::Response& res, Event e) {
    cairn::bag::ObjectEventAnswer a;
    const std::string error =
        guarded([&] { a = (core_.*e)(req.object_id, file::from_pose(req.gripper), req.time); });
    res.success = error.empty();
    res.message = error;
    res.json = a.json;
    // Stored: answered as stored, whatever publishing does.
    guarded([&] {
      for (const file::MapEdit& edit : a.edits) edits_pub_.publish(cairn::node::to_msg(edit, map_frame_));
      publish();
    });
    return true;
  }

  void publish() {
    visualization_msgs::MarkerArray markers;
    visualization_msgs::Marker clear;
    clear.action = visualization_msgs::Marker::DELETEALL;
    markers.markers.push_back(clear);
    for (const cairn::bag::ObjectView& o : core_.objects(view_voxel_)) {
      visualization_msgs::Marker points = marker(o, "objects", visualization_msgs::Marker::POINTS);
      points.scale.x = points.scale.y = kPointSize;
      for (std::size_t i = 0; i + 2 < o.cloud.xyz.size(); i += 3) {
        geometry_msgs::Point p;
        p.x = o.cloud.xyz[i];
        p.y = o.cloud.xyz[i + 1];
        p.z = o.cloud.xyz[i + 2];
        points.points.push_back(p);
      }
      markers.markers.push_back(points);
      visualization_msgs::Marker label = marker(o, "labels", visualization_msgs::Marker::TEXT_VIEW_FACING);
      label.pose.position.x = o.centroid[0];
      label.pose.position.y = o.centroid[1];
      label.pose.position.z = o.centroid[2] + 3 * kLabelHeight;
      label.scale.z = kLabelHeight;
      label.color.r = label.color.g = label.color.b = 1.0f;
      label.text = std::to_string(o.id) + " " + o.status;
      markers.markers.push_back(label);
    }
    markers_pub_.publish(markers);
    std_msgs::String objects;
    objects.data = core_.list_json();
    objects_pub_.publish(objects);
  }

  [[nodiscard]] visualization_msgs::Marker marker(const cairn::bag::ObjectView& o, const char* ns, int type) const {
    visualization_msgs::Marker m;
    m.header.frame_id = map_frame_;
    m.header.stamp = ros::Time::now();
    m.ns = ns;
    m.id = int(o.id);
    m.type = type;
    m.action = visualization_msgs::Marker::ADD;
    m.pose.orientation.w = 1.0;
    m.color.r = float(o.color[0]) / 255.0f;
    m.color.g = float(o.color[1]) / 255.0f;
    m.color.b = float(o.color[2]) / 255.0f;
    m.color.a = o.status == "lost" ? 0.3f : 1.0f;
    return m;
  }

  ObjectsCore& core_;
  std::string map_frame_;
  double view_voxel_;
  double map_time_ = 0.0;  // the newest map's stamp (the run's clock): the time of segmentations and re-alignments
  ros::Subscriber map_sub_, merged_sub_;
  ros::Publisher markers_pub_, objects_pub_, edits_pub_;
  std::vector<ros::ServiceServer> services_;
  std::size_t errors_ = 0;
};

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "cairn_objects");
  ros::NodeHandle nh, pnh("~");
  const cairn::node::ConfigParams config = cairn::node::config_params(pnh);
  std::string database, map_topic, merged_topic, map_frame;
  double view_voxel = 0.05;
  pnh.param<std::string>("database", database, "");
  pnh.param<std::string>("map_topic", map_topic, "/cairn_mapper/map");
  pnh.param<std::string>("merged_topic", merged_topic, "/cairn_registration/merged");
  pnh.param<std::string>("map_frame", map_frame, "map");
  pnh.param("view_voxel", view_voxel, 0.05);
  return cairn::node::run_node("cairn_objects", [&] {
    ObjectsCore core(config.file, config.overrides, database);
    ObjectsNode node(nh, pnh, core, map_topic, merged_topic, map_frame, view_voxel);
    ros::spin();
  });
}
