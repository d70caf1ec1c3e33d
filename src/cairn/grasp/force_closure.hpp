#pragma once
// Force closure of a two-jaw grasp (paper Sec. 5.4), decided analytically where the paper uses
// GPD's CNN: two soft contacts are in force closure when the line between them lies inside both
// friction cones (Nguyen 1988); a grasp is robust when most small perturbations of its pose and of
// the friction coefficient keep it in force closure (Dex-Net 2.0's robust force closure).
#include <cstdint>

#include "cairn/core/kdtree.hpp"
#include "cairn/grasp/candidates.hpp"

namespace cairn::grasp {

/// Angle [rad] by which the contact line stays inside the tighter of the two friction cones of
/// half-angle atan(mu) (negative: outside, no force closure).
[[nodiscard]] double cone_margin(const Closing& closing, double mu);
/// cone_margin(...) >= 0 for a closed grasp.
[[nodiscard]] bool force_closure(const Closing& closing, double mu);

/// Share of `config.perturbations` perturbed copies of the candidate (pose noise in G, relative
/// noise of mu) whose jaws still close on the object in force closure. `tree` indexes
/// pc.cloud.points. Deterministic for (config.seed, salt).
[[nodiscard]] double robustness(const PlanningCloud& pc, const KdTree& tree, const Candidate& candidate,
                                const GripperConfig& gripper, const ForceClosureConfig& config, double voxel,
                                std::uint64_t salt);

}  // namespace cairn::grasp
