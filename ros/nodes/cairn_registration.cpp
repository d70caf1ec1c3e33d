// cairn_registration: a drone cloud registered into the current map (paper Sec. 4.1 scale
// recovery, Sec. 4.4 segment-based registration) as a ROS 1 node (docs/ros.md). A thin adapter over
// RegistrationCore: the same library call and JSON contract as `cairn register`. C++17 (roscpp).
//
// Subscribes: ~map_topic (PointCloud2, default /cairn_mapper/map), the drone cloud (bag.drone_cloud,
// SfM frame; used when a request names no file). Service ~register (cairn_ros/RegisterDrone).
// Publishes ~aligned (PointCloud2 in ~map_frame, latched: the registered drone cloud), ~merged
// (PointCloud2, latched: the map and the drone cloud merged, voxelised; what cairn_objects segments
// first) and ~result (std_msgs/String, latched: the JSON of the newest answer). Parameters: ~config, ~set, ~map_frame.
#include <cairn_ros/RegisterDrone.h>
#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>
#include <std_msgs/String.h>

#include <string>

#include "cairn_ros/registration_core.hpp"
#include "node_support.hpp"

namespace {

using cairn::bag::RegistrationCore;
namespace file = cairn::bag::file;

class RegistrationNode {
 public:
  RegistrationNode(ros::NodeHandle& nh, ros::NodeHandle& pnh, RegistrationCore& core, const std::string& map_topic,
                   std::string map_frame)
      : core_(core), map_frame_(std::move(map_frame)) {
    subs_.push_back(cairn::node::subscribe_cloud(nh, map_topic, "cairn_registration", errors_, "map",
                                                 [this](const file::Cloud& c, double) { core_.set_map(c); }));
    subs_.push_back(cairn::node::subscribe_cloud(nh, core.topics().drone_cloud, "cairn_registration", errors_,
                                                 "drone cloud",
                                                 [this](const file::Cloud& c, double) { core_.set_drone_cloud(c); }));
    aligned_pub_ = pnh.advertise<sensor_msgs::PointCloud2>("aligned", 1, /*latch=*/true);
    merged_pub_ = pnh.advertise<sensor_msgs::PointCloud2>("merged", 1, /*latch=*/true);
    result_pub_ = pnh.advertise<std_msgs::String>("result", 1, /*latch=*/true);
    service_ = pnh.advertiseService("register", &RegistrationNode::answer, this);
  }

 private:
  bool answer(cairn_ros::RegisterDrone::Request& req, cairn_ros::RegisterDrone::Response& res) {
    const std::string error = cairn::node::guarded("cairn_registration", errors_, [&] {
      cairn::bag::RegistrationAnswer a = core_.register_drone(req.cloud_file, req.sfm, req.metric, req.gravity_aligned,
                                                                 req.estimate_scale);
      res.success = a.success;
      res.message = a.message;
      for (std::size_t i = 0; i < 16; ++i) res.T_map_drone[i] = a.T_map_drone[i];
      res.json = a.json;
      std_msgs::String result;
      result.data = a.json;
      result_pub_.publish(result);
      if (a.success) {
        for (file::Cloud* c : {&a.aligned, &a.merged}) {
          c->frame = map_frame_;
          c->stamp = ros::Time::now().toSec();
        }
        aligned_pub_.publish(file::to_msg(a.aligned));
        merged_pub_.publish(file::to_msg(a.merged));
      }
      ROS_INFO("cairn_registration: %s", a.success ? "registered" : ("no acceptable transform: " + a.message).c_str());
    });
    if (!error.empty()) {  // bad input: said in the answer, the node goes on
      res.success = false;
      res.message = error;
    }
    return true;
  }

  RegistrationCore& core_;
  std::string map_frame_;
  std::vector<ros::Subscriber> subs_;
  ros::Publisher aligned_pub_, merged_pub_, result_pub_;
  ros::ServiceServer service_;
  std::size_t errors_ = 0;
};

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "cairn_registration");
  ros::NodeHandle nh, pnh("~");
  const cairn::node::ConfigParams config = cairn::node::config_params(pnh);
  std::string map_topic, map_frame;
  pnh.param<std::string>("map_topic", map_topic, "/cairn_mapper/map");
  pnh.param<std::string>("map_frame", map_frame, "map");
  return cairn::node::run_node("cairn_registration", [&] {
    RegistrationCore core(config.file, config.overrides);
    RegistrationNode node(nh, pnh, core, map_topic, map_frame);
    ros::spin();
  });
}
