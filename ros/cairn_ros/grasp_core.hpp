#pragma once
// What the cairn_grasp node does, without ROS: grasp planning for the two-jaw gripper (Sec. 5) on
// the newest map, the registered drone cloud when there is one, and the object database's model
// of the object — the library call and JSON contract of `cairn grasp`. C++17-clean header.
#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "cairn_ros/bag_file.hpp"

namespace cairn::bag {

/// One convex part of the gripper (robot/gripper.hpp) as a box in the map frame.
struct GripperBox {
  std::string name;  // palm, jaw_left, jaw_right
  std::array<double, 3> center{0.0, 0.0, 0.0}, size{0.0, 0.0, 0.0};
  std::array<double, 4> q{0.0, 0.0, 0.0, 1.0};  // x y z w
};

struct PlannedGrasp {
  file::Transform T_map_gripper;  // at closing, jaws at the pre-grasp opening
  double opening = 0.0;           // [m]
  std::vector<GripperBox> parts;
};

struct GraspAnswer {
  std::int64_t object = 0;
  std::vector<PlannedGrasp> grasps;  // best first
  std::string json;                  // the `cairn grasp` contract
};

class GraspCore {
 public:
  /// The CLI's configuration; `database`: the object database (opened read-only per request, so
  /// the objects node's newest commits count). Throws ConfigError / InputError.
  GraspCore(const std::string& config_file, const std::vector<std::string>& overrides, std::string database);
  ~GraspCore();
  GraspCore(const GraspCore&) = delete;
  GraspCore& operator=(const GraspCore&) = delete;

  void set_map(const file::Cloud& map);
  void set_drone_cloud(const file::Cloud& aligned);
  /// Grasps of object `id` (0: the largest that is not lost, Sec. 5.1), with the drone cloud until
  /// the database holds a grasp (any_grasp_stored). Throws InputError on bad
  /// input (no map yet, unknown object); an answer without grasps when none passes.
  [[nodiscard]] GraspAnswer plan(std::int64_t id) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace cairn::bag
