#pragma once
// A machine's rosbag <-> cairn's run data (docs/ros.md). Writing: a run directory as a real machine
// would record it — both LiDARs' sweeps (sensor_msgs/PointCloud2 with per-point `time` relative to
// the header stamp and `ring`, as the Velodyne driver publishes them), the state estimate
// (nav_msgs/Odometry and /tf world -> cabin), the joint encoders (sensor_msgs/JointState), the
// extrinsics (/tf_static cabin -> lidar_*), the robot model (std_msgs/String with robot.json) and
// the drone's cloud. Reading needs no roscore: everything but the sweeps in one pass, then the
// sweeps streamed in time order.
#include <filesystem>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "cairn/core/io/bag_topics.hpp"
#include "cairn/core/io/run_dir.hpp"
#include "cairn/mapping/mapper.hpp"

namespace cairn::bag {

struct BagWriteSummary {
  std::map<std::string, std::size_t> messages;  // per topic
};

/// Writes `run` as a rosbag (LZ4-compressed chunks), replacing `bag`. Throws InputError when a
/// file of the run cannot be read or the bag cannot be written.
BagWriteSummary write_run_bag(const io::RunDirectory& run, const std::filesystem::path& bag,
                              const io::BagTopics& topics = {});

/// What a bag holds besides the sweeps, and where the sweeps are.
struct BagRun {
  std::filesystem::path file;
  RobotModel robot;
  std::map<std::string, Eigen::Isometry3d> T_cabin_sensor;  // "H", "V" (from /tf_static)
  std::vector<StampedPose> state_estimate;                  // T_world_cabin
  std::vector<JointState> joint_states;
  std::map<std::string, std::size_t> sweeps;  // per sensor
  std::map<std::string, double> sweep_period;  // per sensor: median spacing of the sweep stamps [s]
  bool has_drone_cloud = false;
};

/// Reads everything but the sweeps. Throws InputError naming the bag and what is missing (no
/// odometry, no extrinsics for a LiDAR topic, no robot model, not a bag, ...).
BagRun open_run_bag(const std::filesystem::path& bag, const io::BagTopics& topics = {});

/// The sweeps in time order, one at a time: points in the sensor frame, absolute per-point times,
/// the "ring" field; t_start = header stamp, t_end = t_start + the sensor's sweep period (a
/// Velodyne message carries no end time).
SweepSource bag_sweeps(const BagRun& run, const io::BagTopics& topics = {});

/// The drone cloud of the bag (SfM frame); throws InputError when the bag has none.
PointCloud bag_drone_cloud(const BagRun& run, const io::BagTopics& topics = {});

/// `map_run` on a bag: the same mapper, the sweeps streamed from the bag.
MapRunResult map_bag(const BagRun& run, const MappingConfig& config = {}, const MappingProgress& progress = {},
                     const io::BagTopics& topics = {});

}  // namespace cairn::bag
