// cairn_mapper: the online LiDAR mapping of Sec. 4.2 as a ROS 1 node (docs/ros.md). A thin adapter:
// messages -> MapperCore (the same Mapper and configuration as `cairn map`) -> the map, the
// trajectory and tf. C++17 (Debian's ROS 1 message headers).
//
// Subscribes (names: the `bag.*` settings): both LiDARs' sensor_msgs/PointCloud2 (per-point time
// and ring), nav_msgs/Odometry (T_world_cabin), sensor_msgs/JointState, /tf_static (cabin ->
// lidar_*), std_msgs/String robot model. Publishes ~map (PointCloud2, latched, every 1/~map_rate
// s while mapping), ~trajectory (nav_msgs/Path, latched), ~status (std_msgs/String, JSON), /tf
// ~map_frame -> world. Service ~finish (std_srvs/Trigger): full optimisation, final map.
// Subscribes to ~map_edits (cairn_ros/MapEdit, default /cairn_objects/map_edits): edits of the map
// by other stages, recorded by the Mapper (replayed on rebuilds).
// Parameters: ~config (the CLI's YAML file), ~set (list of key.path=value), ~map_rate [Hz],
// ~map_frame, ~sweep_period [s].
#include <nav_msgs/Odometry.h>
#include <nav_msgs/Path.h>
#include <ros/ros.h>
#include <sensor_msgs/JointState.h>
#include <sensor_msgs/PointCloud2.h>
#include <std_msgs/String.h>
#include <std_srvs/Trigger.h>
#include <tf2_msgs/TFMessage.h>

#include <exception>
#include <string>
#include <vector>

#include "cairn_ros/mapper_core.hpp"
#include "cairn_ros/messages.hpp"
#include "node_support.hpp"

namespace {

using cairn::bag::MapperCore;
namespace file = cairn::bag::file;

class MapperNode {
 public:
  MapperNode(ros::NodeHandle& nh, ros::NodeHandle& pnh, MapperCore& core, double map_rate, std::string map_frame,
             const std::string& edits_topic)
      : core_(core), map_frame_(std::move(map_frame)) {
    const cairn::io::BagTopics& t = core.topics();
    constexpr std::uint32_t kQueue = 2000;  // never drop a sweep while the mapper catches up
    subs_.push_back(nh.subscribe<sensor_msgs::PointCloud2>(
        t.lidar_h, kQueue, [this, topic = t.lidar_h](const sensor_msgs::PointCloud2ConstPtr& m) { sweep(topic, *m); }));
    subs_.push_back(nh.subscribe<sensor_msgs::PointCloud2>(
        t.lidar_v, kQueue, [this, topic = t.lidar_v](const sensor_msgs::PointCloud2ConstPtr& m) { sweep(topic, *m); }));
    subs_.push_back(nh.subscribe<nav_msgs::Odometry>(t.odometry, 10 * kQueue, [this](const nav_msgs::OdometryConstPtr& o) {
      const auto& p = o->pose.pose;
      guarded([&] {
        core_.add_state(o->header.stamp.toSec(), {{p.position.x, p.position.y, p.position.z},
                                                  {p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w}});
      });
    }));
    subs_.push_back(nh.subscribe<sensor_msgs::JointState>(t.joint_states, 10 * kQueue, [this](const sensor_msgs::JointStateConstPtr& j) {
      guarded([&] { core_.add_joints(j->header.stamp.toSec(), j->name, j->position); });
    }));
    subs_.push_back(nh.subscribe<tf2_msgs::TFMessage>("/tf_static", 10, [this](const tf2_msgs::TFMessageConstPtr& tf) {
      for (const auto& ts : tf->transforms)
        guarded([&] { core_.set_transform(ts.header.frame_id, ts.child_frame_id, file::from_msg(ts.transform)); });
    }));
    // Edits of the map by the objects node (a grasped object's points removed, Sec. 4.5).
    subs_.push_back(nh.subscribe<cairn_ros::MapEdit>(edits_topic, 100, [this](const cairn_ros::MapEditConstPtr& e) {
      guarded([&] {
        const std::size_t removed = core_.apply_edit(cairn::node::from_msg(*e));
        ROS_INFO("cairn_mapper: map edit %s: %zu voxels removed", e->kind.c_str(), removed);
        force_publish_ = true;
      });
    }));
    subs_.push_back(nh.subscribe<std_msgs::String>(t.robot_model, 1, [this](const std_msgs::StringConstPtr& s) {
      guarded([&] { core_.set_robot_model(s->data); });
    }));
    map_pub_ = pnh.advertise<sensor_msgs::PointCloud2>("map", 1, /*latch=*/true);
    path_pub_ = pnh.advertise<nav_msgs::Path>("trajectory", 1, /*latch=*/true);
    status_pub_ = pnh.advertise<std_msgs::String>("status", 10, /*latch=*/true);
    tf_pub_ = nh.advertise<tf2_msgs::TFMessage>("/tf", 100);
    finish_ = pnh.advertiseService("finish", &MapperNode::finish, this);
    timer_ = nh.createWallTimer(ros::WallDuration(1.0 / map_rate),
                                [this](const ros::WallTimerEvent&) { guarded([&] { publish(); }); });
  }

 private:
  template <class F>
  void guarded(F&& f) {  // bad input: said, never a crash
    (void)cairn::node::guarded("cairn_mapper", errors_, std::forward<F>(f));
  }

  void sweep(const std::string& topic, const sensor_msgs::PointCloud2& m) {
    guarded([&] { core_.add_sweep(topic, file::from_msg(m, true, topic)); });
  }

  void publish() {
    const cairn::bag::MapperStatus s = core_.status();
    if (s.sweeps_mapped != published_sweeps_ || s.finished != published_finished_ || force_publish_) {
      force_publish_ = false;
      published_sweeps_ = s.sweeps_mapped;
      published_finished_ = s.finished;
      // The map and the optimised poses are in the map frame, stamped on the run's clock (the
      // newest node); tf map -> world carries the correction of the state estimate.
      file::Cloud cloud = core_.map();
      cloud.frame = map_frame_;
      sensor_msgs::PointCloud2 map = file::to_msg(cloud);
      map_pub_.publish(map);
      nav_msgs::Path path;
      path.header.frame_id = map_frame_;
      path.header.stamp = map.header.stamp;
      for (const auto& [t, T] : core_.trajectory()) {
        geometry_msgs::PoseStamped p;
        p.header.frame_id = path.header.frame_id;
        p.header.stamp = file::stamp_of(t);
        const geometry_msgs::Transform m = file::to_msg(T);
        p.pose.position.x = m.translation.x;
        p.pose.position.y = m.translation.y;
        p.pose.position.z = m.translation.z;
        p.pose.orientation = m.rotation;
        path.poses.push_back(p);
      }
      path_pub_.publish(path);
      tf2_msgs::TFMessage tf;
      geometry_msgs::TransformStamped ts;
      ts.header.stamp = map.header.stamp;
      ts.header.frame_id = map_frame_;
      ts.child_frame_id = core_.topics().world_frame;
      ts.transform = file::to_msg(core_.map_correction());
      tf.transforms.push_back(ts);
      tf_pub_.publish(tf);
    }
    std_msgs::String status;
    status.data = "{\"started\": " + std::string(s.started ? "true" : "false") +
                  ", \"finished\": " + (s.finished ? "true" : "false") +
                  ", \"sweeps_received\": " + std::to_string(s.sweeps_received) +
                  ", \"sweeps_mapped\": " + std::to_string(s.sweeps_mapped) +
                  ", \"sweeps_waiting\": " + std::to_string(s.sweeps_waiting) + ", \"nodes\": " + std::to_string(s.nodes) +
                  ", \"edits\": " + std::to_string(s.edits) + ", \"errors\": " + std::to_string(errors_) + "}";
    status_pub_.publish(status);
  }

  bool finish(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
    try {
      core_.finish();
      publish();
      res.success = true;
      res.message = "finished: " + std::to_string(core_.status().sweeps_mapped) + " sweeps mapped";
    } catch (const std::exception& e) {
      res.success = false;
      res.message = e.what();
    }
    return true;
  }

  MapperCore& core_;
  std::string map_frame_;
  std::vector<ros::Subscriber> subs_;
  ros::Publisher map_pub_, path_pub_, status_pub_, tf_pub_;
  ros::ServiceServer finish_;
  ros::WallTimer timer_;
  std::size_t published_sweeps_ = 0, errors_ = 0;
  bool published_finished_ = false, force_publish_ = false;
};

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "cairn_mapper");
  ros::NodeHandle nh, pnh("~");
  std::string map_frame, edits_topic;
  const cairn::node::ConfigParams config = cairn::node::config_params(pnh);
  double map_rate = 1.0, sweep_period = 0.1;
  pnh.param("map_rate", map_rate, 1.0);
  pnh.param<std::string>("map_frame", map_frame, "map");
  pnh.param("sweep_period", sweep_period, 0.1);  // the VLP-16 at 10 Hz
  pnh.param<std::string>("map_edits", edits_topic, "/cairn_objects/map_edits");
  return cairn::node::run_node("cairn_mapper", [&] {
    if (!(map_rate > 0.0)) throw std::invalid_argument("~map_rate must be positive");
    MapperCore core(config.file, config.overrides, sweep_period);
    MapperNode node(nh, pnh, core, map_rate, map_frame, edits_topic);
    ROS_INFO("cairn_mapper: waiting for %s, %s, %s", core.topics().lidar_h.c_str(), core.topics().lidar_v.c_str(),
             core.topics().odometry.c_str());
    ros::spin();  // one thread: the callbacks and the timer never run at once
  });
}
