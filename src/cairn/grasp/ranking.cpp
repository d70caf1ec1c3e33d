#include "cairn/grasp/ranking.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace cairn::grasp {
namespace {

/// The `keep` best of `order` by `key` (stable).
template <class Key>
void keep_best(std::vector<std::size_t>& order, std::size_t keep, Key key) {
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return key(a) < key(b); });
  if (order.size() > keep) order.resize(keep);
}

}  // namespace

Costs grasp_costs(const Eigen::Isometry3d& T, const Eigen::Vector3d& centroid, const Eigen::Vector3d& ground_normal) {
  const Eigen::Vector3d n = T.linear().col(0);
  const Eigen::Vector3d r = centroid - T.translation();
  return {.align = std::acos(std::clamp(-ground_normal.normalized().dot(n), -1.0, 1.0)),  // Eq. 5
          .enclose = r.dot(n),                                                          // Eq. 6
          .dist = r.cross(n).norm() / n.norm()};                                        // Eq. 7
}

std::vector<std::size_t> rank_hierarchically(std::span<const Costs> costs, const RankingConfig& c) {
  std::vector<std::size_t> order(costs.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  keep_best(order, std::size_t(c.keep_align), [&](std::size_t i) { return costs[i].align; });
  keep_best(order, std::size_t(c.keep_enclose), [&](std::size_t i) { return costs[i].enclose; });
  keep_best(order, order.size(), [&](std::size_t i) { return costs[i].dist; });
  return order;
}

std::vector<std::size_t> rank_closest(std::span<const Costs> costs) {
  std::vector<std::size_t> order(costs.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  keep_best(order, order.size(), [&](std::size_t i) { return costs[i].enclose + costs[i].dist; });
  return order;
}

std::vector<std::size_t> rank_grasps(std::span<const Costs> costs, const RankingConfig& c) {
  return c.method == "closest" ? rank_closest(costs) : rank_hierarchically(costs, c);
}

double search_key(const Costs& costs, const RankingConfig& c) {
  return c.method == "closest" ? costs.enclose + costs.dist : costs.align;
}

}  // namespace cairn::grasp
