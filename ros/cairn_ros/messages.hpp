#pragma once
// ROS 1 messages <-> the plain data of bag_file.hpp, shared by the bag layer and the nodes.
// C++17 only (Debian's ROS 1 message headers): include from ROS translation units.
#include <geometry_msgs/Pose.h>
#include <geometry_msgs/Transform.h>
#include <sensor_msgs/PointCloud2.h>

#include <string>

#include "cairn_ros/bag_file.hpp"

namespace cairn::bag::file {

/// A stamp of the run's clock (negative times clamp to 0).
::ros::Time stamp_of(double t);
geometry_msgs::Transform to_msg(const Transform& T);
Transform from_msg(const geometry_msgs::Transform& m);
geometry_msgs::Pose to_pose(const Transform& T);
Transform from_pose(const geometry_msgs::Pose& m);
/// x y z float32, then `time` float32, `ring` uint16 (padded to 4 bytes) and packed `rgb` when
/// the cloud has them; little endian, height 1.
sensor_msgs::PointCloud2 to_msg(const Cloud& c);
/// The fields above back from any PointCloud2 that has float32 x y z (offsets from its fields;
/// `decode` false: stamp and frame only). Throws InputError naming `what`.
/// Points with a NaN or infinite coordinate (an organised cloud's "no return") are left out.
Cloud from_msg(const sensor_msgs::PointCloud2& m, bool decode, const std::string& what);

}  // namespace cairn::bag::file
