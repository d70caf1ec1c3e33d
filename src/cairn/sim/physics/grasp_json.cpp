#include "cairn/sim/physics/grasp_json.hpp"

#include <cmath>

namespace cairn::sim {
namespace {

using Eigen::Isometry3d;

nlohmann::json point_or_null(const Eigen::Vector3d& p) {
  if (!p.allFinite()) return nullptr;
  return {rounded_json(p.x()), rounded_json(p.y()), rounded_json(p.z())};
}

/// A diagnostic that is -1 when it was not measured.
nlohmann::json rounded_or_null(double v) { return v >= 0 ? rounded_json(v) : nlohmann::json(nullptr); }

/// A diagnostic that is NaN when it was not measured.
nlohmann::json finite_or_null(double v) { return std::isfinite(v) ? rounded_json(v) : nlohmann::json(nullptr); }

}  // namespace

nlohmann::json to_json(const GraspTrialResult& r) {
  nlohmann::json poses = nlohmann::json::array();
  for (std::size_t k = 0; k < r.stone_poses.size(); ++k) {
    const Isometry3d& T = r.stone_poses[k];
    poses.push_back({{"stone", k},
                     {"T_world_stone", pose_to_json(T)},
                     {"translation", rounded_json(T.translation().norm())},
                     {"rotation", rounded_json(Eigen::AngleAxisd(T.linear()).angle())}});
  }
  nlohmann::json phases = nlohmann::json::array();
  for (const PhaseTiming& p : r.phases) phases.push_back({{"name", p.name}, {"start", rounded_json(p.start)}, {"end", rounded_json(p.end)}, {"wall", p.wall}});
  nlohmann::json initial = nlohmann::json::array();
  for (const Isometry3d& T : r.initial_stone_poses) initial.push_back(pose_to_json(T));
  nlohmann::json trace = {{"time", nlohmann::json::array()}, {"jaw_angle", nlohmann::json::array()},
                          {"opening", nlohmann::json::array()}, {"arm_load", nlohmann::json::array()}};
  for (const TraceSample& t : r.trace) {
    trace["time"].push_back(rounded_json(t.time));
    trace["jaw_angle"].push_back(rounded_json(t.jaw_angle));
    trace["opening"].push_back(rounded_json(t.opening));
    trace["arm_load"].push_back(std::round(t.arm_load));
    trace["stone_in_gripper"].push_back({rounded_json(t.stone_in_gripper.x()), rounded_json(t.stone_in_gripper.y()),
                                         rounded_json(t.stone_in_gripper.z())});
  }
  return {{"success", r.success},
          {"failure_reasons", r.failure_reasons},
          {"message", r.message},
          {"grasped_stone", r.grasped_stone},
          {"grasp_opening", rounded_json(r.grasp_opening)},
          {"slip_distance", rounded_json(r.slip_distance)},
          {"slip_angle", rounded_json(r.slip_angle)},
          {"swing_in", rounded_json(r.swing_in)},
          {"jaw_travel", rounded_json(r.jaw_travel)},
          {"place_error", rounded_json(r.place_error)},
          {"arm_stalled", r.arm_stalled},
          {"placement",
           {{"released_centroid", point_or_null(r.released_centroid)},
            {"rest_centroid", point_or_null(r.rest_centroid)},
            {"grip_drift", rounded_or_null(r.grip_drift)},
            {"set_down_drift", rounded_or_null(r.set_down_drift)},
            {"released_on_support", r.released_on_support},
            {"release_touches", r.release_touches},
            {"release_opened", finite_or_null(r.release_opened)},
            {"release_backoff", rounded_json(r.release_backoff)},
            {"weighed_com", point_or_null(r.weighed_com)},
            {"place_correction", rounded_or_null(r.place_correction)}}},
          {"release_pose", pose_to_json(r.T_world_release)},
          {"settled", r.settled},
          {"stone_poses", poses},
          {"initial_settle", {{"stone_poses", initial}, {"max_speed", rounded_json(r.initial_max_speed)}}},
          {"free_stones", r.free_stones},
          {"trace", trace},
          {"phases", phases},
          {"sim_time", rounded_json(r.sim_time)},
          {"wall_time", r.wall_time}};
}

nlohmann::json to_json(const SiteSettleResult& r) {
  nlohmann::json poses = nlohmann::json::array();
  for (const Isometry3d& T : r.stone_poses) poses.push_back(pose_to_json(T));
  return {{"settled", r.settled},
          {"islands", r.islands},
          {"rounds", r.rounds},
          {"max_displacement", rounded_json(r.max_displacement)},
          {"max_rotation", rounded_json(r.max_rotation)},
          {"restart_shift", rounded_json(r.restart_shift)},
          {"restart_turn", rounded_json(r.restart_turn)},
          {"stone_poses", poses},
          {"sim_time", rounded_json(r.sim_time)},
          {"wall_time", r.wall_time}};
}

nlohmann::json to_json(const SettleResult& r) {
  nlohmann::json poses = nlohmann::json::array();
  for (const Isometry3d& T : r.stone_poses) poses.push_back(pose_to_json(T));
  return {{"settled", r.settled},
          {"max_speed", rounded_json(r.max_speed)},
          {"stone_poses", poses},
          {"sim_time", rounded_json(r.sim_time)},
          {"wall_time", r.wall_time}};
}

}  // namespace cairn::sim
