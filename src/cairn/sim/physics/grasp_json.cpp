#include "cairn/sim/physics/grasp_json.hpp"

#include <algorithm>
#include <cmath>

#include "cairn/core/error.hpp"

namespace cairn::sim {
namespace {

using Eigen::Isometry3d;

constexpr double kRigidTolerance = 1e-6;  // |R^T R - I| of a matrix pose

double number(const nlohmann::json& j, const std::string& what) {
  if (!j.is_number()) throw InputError(what + ": expected a number");
  const double v = j.get<double>();
  if (!std::isfinite(v)) throw InputError(what + ": not finite");
  return v;
}

template <int N>
Eigen::Matrix<double, N, 1> vector(const nlohmann::json& j, const std::string& what) {
  if (!j.is_array() || j.size() != N) throw InputError(what + ": expected an array of " + std::to_string(N) + " numbers");
  Eigen::Matrix<double, N, 1> v;
  for (int i = 0; i < N; ++i) v[i] = number(j[static_cast<std::size_t>(i)], what);
  return v;
}

nlohmann::json rounded(double v) { return std::round(v * 1e9) / 1e9; }

}  // namespace

nlohmann::json pose_to_json(const Isometry3d& T) {
  nlohmann::json rows = nlohmann::json::array();
  for (int r = 0; r < 4; ++r) {
    nlohmann::json row = nlohmann::json::array();
    for (int c = 0; c < 4; ++c) row.push_back(rounded(T.matrix()(r, c)));
    rows.push_back(row);
  }
  return rows;
}

Isometry3d pose_from_json(const nlohmann::json& j, const std::string& what) {
  Isometry3d T = Isometry3d::Identity();
  if (j.is_array()) {
    if (j.size() != 4) throw InputError(what + ": a matrix pose needs 4 rows");
    for (int r = 0; r < 4; ++r) {
      const auto row = vector<4>(j[static_cast<std::size_t>(r)], what + " row " + std::to_string(r));
      T.matrix().row(r) = row.transpose();
    }
    if ((T.matrix().row(3) - Eigen::RowVector4d(0, 0, 0, 1)).norm() > kRigidTolerance) {
      throw InputError(what + ": last row must be [0, 0, 0, 1]");
    }
    const Eigen::Matrix3d R = T.linear();
    if ((R.transpose() * R - Eigen::Matrix3d::Identity()).norm() > kRigidTolerance || R.determinant() < 0) {
      throw InputError(what + ": rotation is not orthonormal");
    }
    return T;
  }
  if (j.is_object() && j.contains("position") && j.contains("quaternion_wxyz")) {
    const auto q = vector<4>(j["quaternion_wxyz"], what + ".quaternion_wxyz");
    if (q.norm() < kRigidTolerance) throw InputError(what + ".quaternion_wxyz: zero quaternion");
    T.linear() = Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized().toRotationMatrix();
    T.translation() = vector<3>(j["position"], what + ".position");
    return T;
  }
  throw InputError(what + ": expected a 4x4 matrix or {\"position\", \"quaternion_wxyz\"}");
}

nlohmann::json to_json(const GraspPlan& p) {
  nlohmann::json j{{"T_world_gripper", pose_to_json(p.T_world_gripper)},
                   {"opening", p.opening},
                   {"approach_distance", p.approach_distance},
                   {"lift_height", p.lift_height},
                   {"T_world_place", pose_to_json(p.T_world_place)},
                   {"target_stone", p.target_stone}};
  if (p.swing_pivot) j["swing_pivot"] = {p.swing_pivot->x(), p.swing_pivot->y()};
  return j;
}

GraspPlan grasp_plan_from_json(const nlohmann::json& j, const std::string& source) {
  if (!j.is_object()) throw InputError(source + ": a grasp plan must be a JSON object");
  static const char* kKnown[] = {"T_world_gripper", "opening",     "approach_distance", "lift_height",
                                 "T_world_place",   "swing_pivot", "target_stone"};
  for (const auto& [key, value] : j.items()) {
    if (std::find(std::begin(kKnown), std::end(kKnown), key) == std::end(kKnown)) {
      throw InputError(source + ": unknown key '" + key +
                       "' (known: T_world_gripper, opening, approach_distance, lift_height, "
                       "T_world_place, swing_pivot, target_stone)");
    }
  }
  if (!j.contains("T_world_gripper")) throw InputError(source + ": T_world_gripper is required");
  GraspPlan p;
  p.T_world_gripper = pose_from_json(j["T_world_gripper"], source + ": T_world_gripper");
  p.T_world_place = j.contains("T_world_place") ? pose_from_json(j["T_world_place"], source + ": T_world_place")
                                                : p.T_world_gripper;
  if (j.contains("opening")) p.opening = number(j["opening"], source + ": opening");
  if (j.contains("approach_distance")) p.approach_distance = number(j["approach_distance"], source + ": approach_distance");
  if (j.contains("lift_height")) p.lift_height = number(j["lift_height"], source + ": lift_height");
  if (j.contains("swing_pivot")) p.swing_pivot = vector<2>(j["swing_pivot"], source + ": swing_pivot");
  if (j.contains("target_stone")) {
    if (!j["target_stone"].is_number_integer()) throw InputError(source + ": target_stone must be an integer");
    p.target_stone = j["target_stone"].get<int>();
  }
  return p;
}

nlohmann::json to_json(const GraspTrialResult& r) {
  nlohmann::json poses = nlohmann::json::array();
  for (std::size_t k = 0; k < r.stone_poses.size(); ++k) {
    const Isometry3d& T = r.stone_poses[k];
    poses.push_back({{"stone", k},
                     {"T_world_stone", pose_to_json(T)},
                     {"translation", rounded(T.translation().norm())},
                     {"rotation", rounded(Eigen::AngleAxisd(T.linear()).angle())}});
  }
  nlohmann::json phases = nlohmann::json::array();
  for (const PhaseTiming& p : r.phases) phases.push_back({{"name", p.name}, {"start", rounded(p.start)}, {"end", rounded(p.end)}, {"wall", p.wall}});
  nlohmann::json initial = nlohmann::json::array();
  for (const Isometry3d& T : r.initial_stone_poses) initial.push_back(pose_to_json(T));
  nlohmann::json trace = {{"time", nlohmann::json::array()}, {"opening", nlohmann::json::array()},
                          {"arm_load", nlohmann::json::array()}};
  for (const TraceSample& t : r.trace) {
    trace["time"].push_back(rounded(t.time));
    trace["opening"].push_back(rounded(t.opening));
    trace["arm_load"].push_back(std::round(t.arm_load));
  }
  return {{"success", r.success},
          {"failure_reasons", r.failure_reasons},
          {"message", r.message},
          {"grasped_stone", r.grasped_stone},
          {"grasp_opening", rounded(r.grasp_opening)},
          {"slip_distance", rounded(r.slip_distance)},
          {"slip_angle", rounded(r.slip_angle)},
          {"swing_in", rounded(r.swing_in)},
          {"jaw_travel", rounded(r.jaw_travel)},
          {"place_error", rounded(r.place_error)},
          {"settled", r.settled},
          {"stone_poses", poses},
          {"initial_settle", {{"stone_poses", initial}, {"max_speed", rounded(r.initial_max_speed)}}},
          {"free_stones", r.free_stones},
          {"trace", trace},
          {"phases", phases},
          {"sim_time", rounded(r.sim_time)},
          {"wall_time", r.wall_time}};
}

nlohmann::json to_json(const SiteSettleResult& r) {
  nlohmann::json poses = nlohmann::json::array();
  for (const Isometry3d& T : r.stone_poses) poses.push_back(pose_to_json(T));
  return {{"settled", r.settled},
          {"islands", r.islands},
          {"rounds", r.rounds},
          {"max_displacement", rounded(r.max_displacement)},
          {"max_rotation", rounded(r.max_rotation)},
          {"stone_poses", poses},
          {"sim_time", rounded(r.sim_time)},
          {"wall_time", r.wall_time}};
}

nlohmann::json to_json(const SettleResult& r) {
  nlohmann::json poses = nlohmann::json::array();
  for (const Isometry3d& T : r.stone_poses) poses.push_back(pose_to_json(T));
  return {{"settled", r.settled},
          {"max_speed", rounded(r.max_speed)},
          {"stone_poses", poses},
          {"sim_time", rounded(r.sim_time)},
          {"wall_time", r.wall_time}};
}

}  // namespace cairn::sim
