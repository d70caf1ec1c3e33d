#pragma once
// What the cairn_registration node does, without ROS: a drone cloud registered into the newest
// map (Sec. 4.1 scale recovery, Sec. 4.4), by the same library call and JSON contract as
// `cairn register` (registration/drone_registration.hpp). C++17-clean header.
#include <array>
#include <memory>
#include <string>
#include <vector>

#include "cairn/core/io/bag_topics.hpp"
#include "cairn_ros/bag_file.hpp"

namespace cairn::bag {

struct RegistrationAnswer {
  bool success = false;
  std::string message;  // the reason when no transform passes the acceptance test
  std::array<double, 16> T_map_drone{};  // row-major; a similarity with scale recovery
  std::string json;                      // the `cairn register` contract
  file::Cloud aligned;                   // the drone cloud in the map frame (voxelised), on success
  file::Cloud merged;                    // the map and the aligned drone cloud, voxelised (Sec. 4.4), on success
};

class RegistrationCore {
 public:
  /// The CLI's configuration (cairn/eval/app_config.hpp). Throws ConfigError / InputError.
  RegistrationCore(const std::string& config_file, const std::vector<std::string>& overrides);
  ~RegistrationCore();
  RegistrationCore(const RegistrationCore&) = delete;
  RegistrationCore& operator=(const RegistrationCore&) = delete;

  [[nodiscard]] const io::BagTopics& topics() const;
  void set_map(const file::Cloud& map);
  void set_drone_cloud(const file::Cloud& cloud);
  /// Registers the cloud of `cloud_file` (empty: the newest drone cloud received) into the newest
  /// map; `sfm` + `metric` (files, both or none) recover its scale first; `estimate_scale`: 7-DoF
  /// (registration.scale_check.estimate). Throws InputError on
  /// bad input (no map yet, no drone cloud, unreadable files).
  [[nodiscard]] RegistrationAnswer register_drone(const std::string& cloud_file, const std::string& sfm,
                                                  const std::string& metric, bool gravity_aligned,
                                                  bool estimate_scale = false);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace cairn::bag
