#pragma once
// Topic and frame names of a machine's rosbag (docs/ros.md): what `cairn simulate --bag` writes and
// `cairn map --bag` reads. Plain strings, so the configuration (YAML, --set bag.*) needs no ROS.
#include <string>

namespace cairn::io {

struct BagTopics {
  std::string lidar_h = "/lidar_h/velodyne_points";  // sensor_msgs/PointCloud2, sensor frame, x y z time ring
  std::string lidar_v = "/lidar_v/velodyne_points";
  std::string odometry = "/state_estimate/odometry";  // nav_msgs/Odometry, T_world_cabin
  std::string joint_states = "/joint_states";         // sensor_msgs/JointState (encoders)
  std::string drone_cloud = "/drone/cloud";           // sensor_msgs/PointCloud2, SfM frame
  std::string robot_model = "/cairn/robot_model";     // std_msgs/String, robot.json (latched)
  std::string world_frame = "world";
  std::string cabin_frame = "cabin";
  std::string lidar_h_frame = "lidar_h";
  std::string lidar_v_frame = "lidar_v";
  std::string drone_frame = "drone_sfm";

  /// The LiDAR topic and frame of a run directory's sensor name ("H", "V").
  [[nodiscard]] const std::string& lidar_topic(const std::string& sensor) const { return sensor == "H" ? lidar_h : lidar_v; }
  [[nodiscard]] const std::string& lidar_frame(const std::string& sensor) const {
    return sensor == "H" ? lidar_h_frame : lidar_v_frame;
  }

  template <class V>
  void visit(V& v) {
    v("lidar_h", lidar_h, "topic of the horizontal LiDAR's sweeps (PointCloud2)");
    v("lidar_v", lidar_v, "topic of the vertical LiDAR's sweeps (PointCloud2)");
    v("odometry", odometry, "topic of the state estimate T_world_cabin (nav_msgs/Odometry)");
    v("joint_states", joint_states, "topic of the joint encoders (sensor_msgs/JointState)");
    v("drone_cloud", drone_cloud, "topic of the drone's photogrammetry cloud (PointCloud2)");
    v("robot_model", robot_model, "topic of the machine's robot.json (std_msgs/String)");
    v("world_frame", world_frame, "tf frame of the georeferenced world");
    v("cabin_frame", cabin_frame, "tf frame of the cabin");
    v("lidar_h_frame", lidar_h_frame, "tf frame of the horizontal LiDAR");
    v("lidar_v_frame", lidar_v_frame, "tf frame of the vertical LiDAR");
    v("drone_frame", drone_frame, "frame of the drone cloud (SfM)");
  }
};

}  // namespace cairn::io
