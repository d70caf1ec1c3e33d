#include "cairn_ros/grasp_core.hpp"

#include <optional>

#include "cairn/core/error.hpp"
#include "cairn/eval/app_config.hpp"
#include "cairn/grasp/planner.hpp"
#include "cairn/objects/pipeline.hpp"
#include "cairn/robot/gripper.hpp"
#include "cairn_ros/convert.hpp"
#include "cairn_ros/latest_cloud.hpp"

namespace cairn::bag {

struct GraspCore::Impl {
  AppConfig config;
  std::string database;
  LatestCloud map, drone;
};

GraspCore::GraspCore(const std::string& config_file, const std::vector<std::string>& overrides, std::string database)
    : impl_(std::make_unique<Impl>()) {
  impl_->config = load_app_config(AppConfig{}, config_file, overrides);
  if (database.empty()) throw InputError("cairn_grasp: ~database (the objects node's SQLite file) is required");
  impl_->database = std::move(database);
}

GraspCore::~GraspCore() = default;

void GraspCore::set_map(const file::Cloud& map) { impl_->map.set(map); }

void GraspCore::set_drone_cloud(const file::Cloud& aligned) { impl_->drone.set(aligned); }

namespace {

/// The gripper's convex parts at the grasp's opening, in the map frame.
std::vector<GripperBox> parts_in_map(const grasp::Grasp& g, const GripperConfig& gripper) {
  std::vector<GripperBox> out;
  for (const ConvexPart& p : gripper_parts(gripper, g.opening)) {
    const Eigen::Vector3d c = g.T_map_gripper * p.center;
    const Eigen::Quaterniond q(Eigen::Matrix3d(g.T_map_gripper.linear() * p.axes));
    out.push_back({.name = p.name,
                   .center = {c.x(), c.y(), c.z()},
                   .size = {2 * p.half_extents.x(), 2 * p.half_extents.y(), 2 * p.half_extents.z()},
                   .q = {q.x(), q.y(), q.z(), q.w()}});
  }
  return out;
}

}  // namespace

GraspAnswer GraspCore::plan(std::int64_t id) const {
  const std::shared_ptr<const PointCloud> map = impl_->map.get();
  if (!map) throw InputError("cairn_grasp: no map received yet");
  const ObjectDatabase db(impl_->database, ObjectDatabase::Mode::read_only);
  // The drone's survey completes the planning cloud until something was grasped (Sec. 5.2; the
  // experiments use it for a stone's first move only): then it shows stones where they no longer are.
  const std::shared_ptr<const PointCloud> drone = any_grasp_stored(db) ? nullptr : impl_->drone.get();
  const ObjectRecord object = object_to_grasp(db, id > 0 ? std::optional<std::int64_t>(id) : std::nullopt);
  const GripperConfig& gripper = impl_->config.simulation.gripper;
  const grasp::GraspPlanning p =
      grasp::plan_grasps(*map, object.cloud, drone.get(), gripper, impl_->config.grasp);
  GraspAnswer out{.object = object.id, .grasps = {}, .json = grasp::to_json(p, gripper).dump()};
  for (const grasp::Grasp& g : p.grasps)
    out.grasps.push_back({.T_map_gripper = to_file(g.T_map_gripper), .opening = g.opening, .parts = parts_in_map(g, gripper)});
  return out;
}

}  // namespace cairn::bag
