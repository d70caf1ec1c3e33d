#include "cairn/robot/grasp_plan.hpp"

#include <algorithm>
#include <cmath>

#include "cairn/core/error.hpp"

namespace cairn {
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



}  // namespace

nlohmann::json rounded_json(double v) { return std::round(v * 1e9) / 1e9; }

void require_rigid_pose(const Isometry3d& T, const std::string& what) {
  if (!T.matrix().allFinite()) throw InputError(what + " is not finite");
  const Eigen::Matrix3d R = T.linear();
  if ((R.transpose() * R - Eigen::Matrix3d::Identity()).norm() > kRigidTolerance || R.determinant() < 0) {
    throw InputError(what + " is not a rigid transform (rotation not orthonormal)");
  }
}

nlohmann::json pose_to_json(const Isometry3d& T) {
  nlohmann::json rows = nlohmann::json::array();
  for (int r = 0; r < 4; ++r) {
    nlohmann::json row = nlohmann::json::array();
    for (int c = 0; c < 4; ++c) row.push_back(rounded_json(T.matrix()(r, c)));
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
    require_rigid_pose(T, what);
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
  if (p.place_com_xy) j["place_com_xy"] = {p.place_com_xy->x(), p.place_com_xy->y()};
  return j;
}

GraspPlan grasp_plan_from_json(const nlohmann::json& j, const std::string& source) {
  if (!j.is_object()) throw InputError(source + ": a grasp plan must be a JSON object");
  static const char* kKnown[] = {"T_world_gripper", "opening",     "approach_distance", "lift_height",
                                 "T_world_place",   "swing_pivot", "target_stone",      "place_com_xy"};
  for (const auto& [key, value] : j.items()) {
    if (std::find(std::begin(kKnown), std::end(kKnown), key) == std::end(kKnown)) {
      throw InputError(source + ": unknown key '" + key +
                       "' (known: T_world_gripper, opening, approach_distance, lift_height, "
                       "T_world_place, swing_pivot, target_stone, place_com_xy)");
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
  if (j.contains("place_com_xy")) p.place_com_xy = vector<2>(j["place_com_xy"], source + ": place_com_xy");
  if (j.contains("target_stone")) {
    if (!j["target_stone"].is_number_integer()) throw InputError(source + ": target_stone must be an integer");
    p.target_stone = j["target_stone"].get<int>();
  }
  return p;
}

void validate(const GraspPlan& plan, const GripperConfig& gripper) {
  require_rigid_pose(plan.T_world_gripper, "grasp plan: T_world_gripper");
  require_rigid_pose(plan.T_world_place, "grasp plan: T_world_place");
  if (!(plan.opening > gripper.closed_gap && plan.opening <= max_opening(gripper) + 1e-9)) {
    throw InputError("grasp plan: opening must lie in (closed_gap = " + std::to_string(gripper.closed_gap) +
                     ", max_opening = " + std::to_string(max_opening(gripper)) + "]");
  }
  if (!(std::isfinite(plan.approach_distance) && plan.approach_distance >= 0.0 && std::isfinite(plan.lift_height) &&
        plan.lift_height >= 0.0)) {
    throw InputError("grasp plan: approach_distance and lift_height must be finite and >= 0");
  }
  if (plan.swing_pivot && !plan.swing_pivot->allFinite()) throw InputError("grasp plan: swing_pivot is not finite");
  if (plan.place_com_xy && !plan.place_com_xy->allFinite()) throw InputError("grasp plan: place_com_xy is not finite");
}

}  // namespace cairn
