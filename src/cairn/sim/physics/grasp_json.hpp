#pragma once
// JSON forms of trial and settle results (the `cairn grasp-trial` output). Plans and poses:
// robot/grasp_plan.hpp.
#include <nlohmann/json.hpp>

#include "cairn/robot/grasp_plan.hpp"
#include "cairn/sim/physics/physics.hpp"

namespace cairn::sim {

nlohmann::json to_json(const GraspTrialResult& result);
nlohmann::json to_json(const SettleResult& result);
nlohmann::json to_json(const SiteSettleResult& result);

}  // namespace cairn::sim
