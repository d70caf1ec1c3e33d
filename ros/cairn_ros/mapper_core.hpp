#pragma once
// What the cairn_mapper node does, without ROS: the online Mapper (Sec. 4.2) fed message by
// message. The node (C++17, roscpp) converts messages to the plain data of bag_file.hpp and calls
// this; the implementation is C++20 (cairn's Mapper), so this header stays C++17.
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "cairn/core/io/bag_topics.hpp"
#include "cairn_ros/bag_file.hpp"

namespace cairn::bag {

struct MapperStatus {
  std::size_t sweeps_received = 0, sweeps_mapped = 0, sweeps_waiting = 0, nodes = 0, map_points = 0;
  std::size_t edits = 0;  // map edits applied (apply_edit)
  bool started = false;   // robot model and extrinsics known, Mapper built
  bool finished = false;  // finish() ran
};

class MapperCore {
 public:
  /// The CLI's configuration (cairn/eval/app_config.hpp): `config_file` (empty: defaults), then
  /// the `key.path=value` overrides. `sweep_period` [s]: a Velodyne message carries no end time.
  /// Throws ConfigError / InputError.
  MapperCore(const std::string& config_file, const std::vector<std::string>& overrides, double sweep_period);
  ~MapperCore();
  MapperCore(const MapperCore&) = delete;
  MapperCore& operator=(const MapperCore&) = delete;

  /// Topic and frame names (the `bag.*` settings).
  [[nodiscard]] const io::BagTopics& topics() const;

  void set_robot_model(const std::string& robot_json);
  /// tf cabin -> child; the LiDARs' frames (bag.lidar_h_frame / lidar_v_frame) are kept. Mapping
  /// starts with the extrinsics known then (a sweep of a LiDAR without one is an error).
  void set_transform(const std::string& parent, const std::string& child, const file::Transform& T);
  void add_state(double t, const file::Transform& T_world_cabin);
  void add_joints(double t, const std::vector<std::string>& names, const std::vector<double>& positions);
  /// A sweep of the LiDAR on `topic`: queued until the state estimate and joint states cover it
  /// (the Mapper needs them first), then mapped. Throws InputError on a malformed sweep or one
  /// after finish(); a sweep that fails is dropped, the queue goes on.
  void add_sweep(const std::string& topic, const file::Cloud& sweep);
  /// An edit of the map by another stage (e.g. cairn_objects: a grasped object's points removed,
  /// Sec. 4.5), recorded by the Mapper so that later rebuilds replay it; the voxels removed.
  /// Throws InputError before mapping started or on an invalid edit.
  std::size_t apply_edit(const file::MapEdit& edit);
  /// Maps what is still queued, full optimisation, the map rebuilt from the final poses.
  void finish();

  [[nodiscard]] MapperStatus status() const;
  /// The map in the optimised (map) frame, stamped with the newest node's time; empty before the
  /// first mapped sweep. The frame name is the node's (~map_frame).
  [[nodiscard]] file::Cloud map() const;
  /// Optimised T_world_cabin per node: (time, pose).
  [[nodiscard]] std::vector<std::pair<double, file::Transform>> trajectory() const;
  /// The correction at the newest node, T_map_world = T_opt · T_estimate⁻¹ (the `map -> odom`
  /// convention with odom = the state estimate's world frame); identity before the first node.
  [[nodiscard]] file::Transform map_correction() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace cairn::bag
