// cairn_grasp: grasp planning for the two-jaw gripper (paper Sec. 5) as a ROS 1 node
// (docs/ros.md). A thin adapter over GraspCore: the library call and JSON contract of
// `cairn grasp`. C++17 (roscpp).
//
// Subscribes: ~map_topic (PointCloud2, default /cairn_mapper/map), ~drone_topic (PointCloud2,
// default /cairn_registration/aligned: the registered drone cloud, used until the database holds a grasp).
// Service ~plan (cairn_ros/PlanGrasps: object id -> ranked grasps; 0 = the largest object).
// Publishes ~grasps (geometry_msgs/PoseArray, latched) and ~markers (MarkerArray, latched: the
// gripper's palm and jaws at each grasp, the best opaque). Parameters: ~database (the objects
// node's SQLite file, read per request), ~config, ~set, ~map_topic, ~drone_topic, ~map_frame,
// ~markers (how many grasps get gripper markers).
#include <cairn_ros/PlanGrasps.h>
#include <geometry_msgs/PoseArray.h>
#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>
#include <visualization_msgs/MarkerArray.h>

#include <string>

#include "cairn_ros/grasp_core.hpp"
#include "node_support.hpp"

namespace {

using cairn::bag::GraspCore;
namespace file = cairn::bag::file;

constexpr float kOtherAlpha = 0.25f;  // grasps after the best

class GraspNode {
 public:
  GraspNode(ros::NodeHandle& nh, ros::NodeHandle& pnh, GraspCore& core, const std::string& map_topic,
            const std::string& drone_topic, std::string map_frame, int marker_grasps)
      : core_(core), map_frame_(std::move(map_frame)), marker_grasps_(marker_grasps) {
    subs_.push_back(cairn::node::subscribe_cloud(nh, map_topic, "cairn_grasp", errors_, "map",
                                                 [this](const file::Cloud& c, double) { core_.set_map(c); }));
    subs_.push_back(cairn::node::subscribe_cloud(nh, drone_topic, "cairn_grasp", errors_, "drone cloud",
                                                 [this](const file::Cloud& c, double) { core_.set_drone_cloud(c); }));
    grasps_pub_ = pnh.advertise<geometry_msgs::PoseArray>("grasps", 1, /*latch=*/true);
    markers_pub_ = pnh.advertise<visualization_msgs::MarkerArray>("markers", 1, /*latch=*/true);
    service_ = pnh.advertiseService("plan", &GraspNode::plan, this);
  }

 private:
  template <class F>
  std::string guarded(F&& f) {
    return cairn::node::guarded("cairn_grasp", errors_, std::forward<F>(f));
  }

  bool plan(cairn_ros::PlanGrasps::Request& req, cairn_ros::PlanGrasps::Response& res) {
    const std::string error = guarded([&] {
      const cairn::bag::GraspAnswer a = core_.plan(req.object_id);
      res.object_id = a.object;
      res.json = a.json;
      res.grasps.header.frame_id = map_frame_;
      res.grasps.header.stamp = ros::Time::now();
      for (const cairn::bag::PlannedGrasp& g : a.grasps) res.grasps.poses.push_back(file::to_pose(g.T_map_gripper));
      res.success = !a.grasps.empty();
      res.message = res.success ? std::to_string(a.grasps.size()) + " grasps of object " + std::to_string(a.object)
                                : "no grasp passes (collision, force closure, robustness) for object " +
                                      std::to_string(a.object);
      grasps_pub_.publish(res.grasps);
      markers_pub_.publish(markers(a));
      ROS_INFO("cairn_grasp: %s", res.message.c_str());
    });
    if (!error.empty()) {
      res.success = false;
      res.message = error;
    }
    return true;
  }

  [[nodiscard]] visualization_msgs::MarkerArray markers(const cairn::bag::GraspAnswer& a) const {
    visualization_msgs::MarkerArray out;
    visualization_msgs::Marker clear;
    clear.action = visualization_msgs::Marker::DELETEALL;
    out.markers.push_back(clear);
    int id = 0;
    for (std::size_t k = 0; k < a.grasps.size() && int(k) < marker_grasps_; ++k)
      for (const cairn::bag::GripperBox& b : a.grasps[k].parts) {
        visualization_msgs::Marker m;
        m.header.frame_id = map_frame_;
        m.header.stamp = ros::Time::now();
        m.ns = "gripper";
        m.id = id++;
        m.type = visualization_msgs::Marker::CUBE;
        m.action = visualization_msgs::Marker::ADD;
        m.pose.position.x = b.center[0];
        m.pose.position.y = b.center[1];
        m.pose.position.z = b.center[2];
        m.pose.orientation.x = b.q[0];
        m.pose.orientation.y = b.q[1];
        m.pose.orientation.z = b.q[2];
        m.pose.orientation.w = b.q[3];
        m.scale.x = b.size[0];
        m.scale.y = b.size[1];
        m.scale.z = b.size[2];
        m.color.r = k == 0 ? 0.1f : 0.9f;  // the best green, the others orange
        m.color.g = k == 0 ? 0.8f : 0.5f;
        m.color.b = 0.1f;
        m.color.a = k == 0 ? 1.0f : kOtherAlpha;
        out.markers.push_back(m);
      }
    return out;
  }

  GraspCore& core_;
  std::string map_frame_;
  int marker_grasps_;
  std::vector<ros::Subscriber> subs_;
  ros::Publisher grasps_pub_, markers_pub_;
  ros::ServiceServer service_;
  std::size_t errors_ = 0;
};

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "cairn_grasp");
  ros::NodeHandle nh, pnh("~");
  const cairn::node::ConfigParams config = cairn::node::config_params(pnh);
  std::string database, map_topic, drone_topic, map_frame;
  int marker_grasps = 5;
  pnh.param<std::string>("database", database, "");
  pnh.param<std::string>("map_topic", map_topic, "/cairn_mapper/map");
  pnh.param<std::string>("drone_topic", drone_topic, "/cairn_registration/aligned");
  pnh.param<std::string>("map_frame", map_frame, "map");
  pnh.param("markers", marker_grasps, 5);
  return cairn::node::run_node("cairn_grasp", [&] {
    GraspCore core(config.file, config.overrides, database);
    GraspNode node(nh, pnh, core, map_topic, drone_topic, map_frame, marker_grasps);
    ros::spin();
  });
}
