#include "cairn/grasp/planner.hpp"

#include <algorithm>
#include <chrono>
#include <numbers>

#include <tbb/parallel_for.h>

#include "cairn/core/kdtree.hpp"
#include "cairn/grasp/force_closure.hpp"

namespace cairn::grasp {
namespace {

using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t) { return std::chrono::duration<double, std::milli>(Clock::now() - t).count(); }

Grasp make_grasp(const Candidate& c, const PlanningCloud& pc, const GripperConfig& g, double mu) {
  const Eigen::Translation3d to_map(pc.cloud.origin);
  Grasp out;
  out.T_map_gripper = to_map * c.T;
  out.opening = c.opening;
  out.closed_opening = opening_at(g, c.closing.angle);
  out.contact_angle = c.closing.angle;
  out.shift = c.closing.shift;
  out.approach = c.T.linear().col(0);
  for (std::size_t k = 0; k < 2; ++k) out.contacts[k] = out.T_map_gripper * c.closing.contacts[k];
  out.costs = grasp_costs(c.T, pc.mass_centroid - pc.cloud.origin, pc.ground_normal);
  out.contact_height = (0.5 * (out.contacts[0] + out.contacts[1]) - pc.mass_centroid).dot(pc.ground_normal);
  const Eigen::Vector3d axis = (out.contacts[1] - out.contacts[0]).normalized();
  out.gravity_lever = std::abs(axis.dot((pc.mass_centroid - out.contacts[0]).cross(pc.ground_normal)));
  out.undercut = -std::max((c.T.linear() * c.closing.normals[0]).dot(pc.ground_normal),
                            (c.T.linear() * c.closing.normals[1]).dot(pc.ground_normal));
  out.cone_margin = cone_margin(c.closing, mu);
  out.force_closure = force_closure(c.closing, mu);
  return out;
}

/// Robustness in the order of the ranking's search key (c_align, or c_enc + c_dist) until as many
/// robust grasps are found as the ranking looks at (keep_align, or output); the rest stay
/// unevaluated (-1).
std::vector<std::size_t> robust_grasps(const PlanningCloud& pc, const KdTree& tree, const std::vector<Candidate>& cands,
                                       std::vector<Grasp>& grasps, const GripperConfig& g, const GraspConfig& c) {
  std::vector<std::size_t> order(grasps.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return search_key(grasps[a].costs, c.ranking) < search_key(grasps[b].costs, c.ranking);
  });
  std::vector<std::size_t> robust;
  const auto keep = std::size_t(c.ranking.method == "closest" ? c.ranking.output : c.ranking.keep_align);
  for (std::size_t from = 0; from < order.size() && robust.size() < keep; from += keep) {  // in parallel batches
    const std::size_t to = std::min(order.size(), from + keep);
    tbb::parallel_for(from, to, [&](std::size_t k) {
      const std::size_t i = order[k];
      grasps[i].robustness = robustness(pc, tree, cands[i], g, c.force_closure, c.cloud.voxel, i);
    });
    for (std::size_t k = from; k < to && robust.size() < keep; ++k)
      if (grasps[order[k]].robustness >= c.force_closure.min_robustness) robust.push_back(order[k]);
  }
  return robust;
}

}  // namespace

GraspPlanning plan_grasps(const PointCloud& map, const PointCloud& object, const PointCloud* drone,
                          const GripperConfig& gripper, const GraspConfig& config) {
  config.validate();
  validate(gripper);
  GraspPlanning out;
  const auto t0 = Clock::now();
  out.cloud = build_planning_cloud(map, object, drone, gripper, config.cloud);
  out.timings_ms["cloud"] = ms_since(t0);
  auto t = Clock::now();
  CandidateCounts cc;
  const KdTree tree(out.cloud.cloud.points);  // one index for the candidates and the robustness
  std::vector<Candidate> all = generate_candidates(out.cloud, tree, gripper, config, cc);
  out.counts = {.samples = cc.samples, .poses = cc.poses, .hypotheses = cc.hypotheses, .collision_free = cc.collision_free};
  out.timings_ms["candidates"] = ms_since(t);
  t = Clock::now();
  std::vector<Candidate> fc;
  std::vector<Grasp> grasps;
  std::vector<std::size_t> fc_index;  // per balanced grasp: its place in force_closure_grasps
  const double max_lever = config.force_closure.max_lever_jaw_heights * gripper.jaw_height;
  const double max_angle = config.force_closure.max_contact_angle_deg * std::numbers::pi / 180.0;
  const double max_shift = config.force_closure.max_shift_voxels * config.cloud.voxel;
  for (Candidate& c : all) {
    Grasp g = make_grasp(c, out.cloud, gripper, config.force_closure.mu / config.force_closure.mu_safety);
    if (!g.force_closure) continue;
    ++out.counts.force_closure;
    out.force_closure_costs.push_back(g.costs);
    out.force_closure_grasps.push_back(g);
    if (g.gravity_lever > max_lever || g.contact_angle > max_angle || std::abs(g.shift) > max_shift) continue;
    fc_index.push_back(out.force_closure_grasps.size() - 1);
    grasps.push_back(g);
    fc.push_back(std::move(c));
  }
  out.counts.balanced = grasps.size();
  const std::vector<std::size_t> robust = robust_grasps(out.cloud, tree, fc, grasps, gripper, config);
  out.counts.robust = robust.size();
  for (std::size_t i = 0; i < grasps.size(); ++i) out.force_closure_grasps[fc_index[i]].robustness = grasps[i].robustness;
  out.timings_ms["force_closure"] = ms_since(t);
  t = Clock::now();
  std::vector<Costs> robust_costs;
  for (const std::size_t i : robust) robust_costs.push_back(grasps[i].costs);
  const std::vector<std::size_t> ranked = rank_grasps(robust_costs, config.ranking);
  std::vector<bool> selected(grasps.size(), false);
  for (std::size_t r = 0; r < ranked.size(); ++r) {
    const std::size_t i = robust[ranked[r]];
    selected[i] = true;
    if (out.grasps.size() >= std::size_t(config.ranking.output)) continue;
    out.grasps.push_back(grasps[i]);
    out.grasps.back().rank = int(r) + 1;
  }
  out.selected_costs.clear();
  for (std::size_t i = 0; i < grasps.size(); ++i)
    if (selected[i]) out.selected_costs.push_back(grasps[i].costs);
  out.timings_ms["ranking"] = ms_since(t);
  out.timings_ms["total"] = ms_since(t0);
  return out;
}

GraspPlan to_grasp_plan(const Grasp& grasp, GraspPlan base) {
  base.T_world_gripper = grasp.T_map_gripper;
  base.opening = grasp.opening;
  return base;
}

namespace {
nlohmann::json vec_json(const Eigen::Vector3d& v) { return {rounded_json(v.x()), rounded_json(v.y()), rounded_json(v.z())}; }
}  // namespace

nlohmann::json to_json(const GraspPlanning& p, const GripperConfig& gripper) {
  nlohmann::json grasps = nlohmann::json::array();
  for (const Grasp& g : p.grasps) {
    nlohmann::json parts = nlohmann::json::array();
    for (const ConvexPart& part : gripper_parts(gripper, g.opening)) {
      nlohmann::json vs = nlohmann::json::array();
      for (const Eigen::Vector3d& v : part.vertices) vs.push_back(vec_json(g.T_map_gripper * v));
      parts.push_back({{"name", part.name}, {"vertices", vs}});
    }
    grasps.push_back({{"rank", g.rank},
                      {"T_map_gripper", pose_to_json(g.T_map_gripper)},
                      {"opening_m", rounded_json(g.opening)},
                      {"closed_opening_m", rounded_json(g.closed_opening)},
                      {"contact_angle_rad", rounded_json(g.contact_angle)},
                      {"shift_m", rounded_json(g.shift)},
                      {"approach", vec_json(g.approach)},
                      {"contacts", {vec_json(g.contacts[0]), vec_json(g.contacts[1])}},
                      {"costs", {{"align_rad", rounded_json(g.costs.align)},
                                 {"enclose_m", rounded_json(g.costs.enclose)},
                                 {"dist_m", rounded_json(g.costs.dist)}}},
                      {"contact_height_m", rounded_json(g.contact_height)},
                      {"gravity_lever_m", rounded_json(g.gravity_lever)},
                      {"force_closure", g.force_closure},
                      {"cone_margin_rad", rounded_json(g.cone_margin)},
                      {"robustness", rounded_json(g.robustness)},
                      {"parts", parts}});
  }
  const GraspCounts& c = p.counts;
  nlohmann::json timings = nlohmann::json::object();
  for (const auto& [k, v] : p.timings_ms) timings[k] = rounded_json(v);
  return {{"object", {{"centroid", vec_json(p.cloud.centroid)}, {"mass_centroid", vec_json(p.cloud.mass_centroid)},
                      {"planning_points", p.cloud.cloud.size()},
                      {"object_points", p.cloud.object_points}, {"fill_points", p.cloud.fill_points}}},
          {"grasps", grasps},
          {"counts", {{"samples", c.samples}, {"poses", c.poses}, {"hypotheses", c.hypotheses},
                      {"collision_free", c.collision_free}, {"force_closure", c.force_closure},
                      {"balanced", c.balanced}, {"robust", c.robust}}},
          {"timings_ms", timings}};
}

}  // namespace cairn::grasp
