#pragma once
// Hierarchical ranking of force-closure grasps (paper Sec. 5.4, Eq. 5-7).
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <span>
#include <vector>

#include "cairn/grasp/config.hpp"

namespace cairn::grasp {

struct Costs {
  double align = 0.0;    // [rad] Eq. 5: acos(-n_ground . n_approach)
  double enclose = 0.0;  // [m] Eq. 6: r_CoM . n_approach (palm centre to centroid along the approach)
  double dist = 0.0;     // [m] Eq. 7: |r_CoM x n_approach| (centroid to the approach line through the TCP)
};

/// Costs of gripper pose T (G: x = n_approach, origin = the palm's centre) for an object centroid
/// and the upward ground normal, all in one frame.
[[nodiscard]] Costs grasp_costs(const Eigen::Isometry3d& T, const Eigen::Vector3d& centroid,
                                const Eigen::Vector3d& ground_normal);

/// Sec. 5.4: the best keep_align by c_align, of those the best keep_enclose by c_enc, ordered by
/// c_dist. Returns indices into `costs`, best first (ties keep the input order).
[[nodiscard]] std::vector<std::size_t> rank_hierarchically(std::span<const Costs> costs, const RankingConfig& config);

/// Beyond the paper: ordered by c_enc + c_dist (ties keep the input order).
[[nodiscard]] std::vector<std::size_t> rank_closest(std::span<const Costs> costs);

/// The configured ranking (RankingConfig::method) and the key its robustness search follows
/// (c_align for the hierarchical ranking, c_enc + c_dist for the closest).
[[nodiscard]] std::vector<std::size_t> rank_grasps(std::span<const Costs> costs, const RankingConfig& config);
[[nodiscard]] double search_key(const Costs& costs, const RankingConfig& config);

}  // namespace cairn::grasp
