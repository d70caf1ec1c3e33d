#include "cairn/objects/updates.hpp"

#include <cmath>
#include <cstdio>
#include <numbers>
#include <optional>
#include <set>

#include "cairn/core/error.hpp"
#include "cairn/core/transform.hpp"
#include "cairn/objects/association.hpp"
#include "cairn/registration/icp.hpp"

namespace cairn {
namespace {

void require_finite(const Eigen::Isometry3d& T, const std::string& what) {
  if (!T.matrix().allFinite()) throw InputError(what + ": the gripper pose is not finite");
}

std::string object_name(const ObjectRecord& o) { return "object " + std::to_string(o.id); }

/// Largest distance of the object's points from its centroid.
double object_radius(const ObjectRecord& o) {
  double r2 = 0.0;
  for (std::size_t i = 0; i < o.cloud.size(); ++i) r2 = std::max(r2, (o.cloud.world(i) - o.centroid).squaredNorm());
  return std::sqrt(r2);
}

/// Map points within `radius` of `center`, relative to `center` (float precision near the object).
std::vector<Vec3f> crop_around(const PointCloud& map, const Vec3d& center, double radius) {
  std::vector<Vec3f> out;
  for (std::size_t i = 0; i < map.size(); ++i) {
    const Vec3d d = map.world(i) - center;
    if (d.squaredNorm() <= radius * radius) out.push_back(d.cast<float>());
  }
  return out;
}

std::string join_ids(const std::set<std::int64_t>& ids) {
  std::string out;
  for (std::int64_t id : ids) out += (out.empty() ? "" : ", ") + std::to_string(id);
  return out;
}

template <class... Args>
std::string format(const char* fmt, Args... args) {
  char buf[256];
  std::snprintf(buf, sizeof(buf), fmt, args...);
  return buf;
}

}  // namespace

Eigen::Isometry3d release_transform(const Eigen::Isometry3d& T_map_gripper_grasp,
                                    const Eigen::Isometry3d& T_map_gripper_release) {
  return T_map_gripper_release * T_map_gripper_grasp.inverse();  // Eq. 3
}

MapEdit grasp_map_edit(const ObjectRecord& object, const GraspRemovalConfig& config) {
  if (config.method == "sphere") return MapEdit::sphere(object.centroid, config.R_obj);  // Sec. 4.5
  if (object.cloud.empty()) throw InputError(object_name(object) + ": no cloud to remove from the map");
  return MapEdit::near(object.cloud, config.distance, object.centroid, config.R_obj);
}

Operation grasp_operation(const ObjectRecord& object, const Eigen::Isometry3d& T_map_gripper, double time,
                          const GraspRemovalConfig& config) {
  const std::string what = "grasp of " + object_name(object);
  require_finite(T_map_gripper, what);
  if (object.status != ObjectStatus::on_ground && object.status != ObjectStatus::placed)
    throw InputError(what + ": it is " + to_string(object.status) + ", not on the ground");
  Operation op{.time = time, .kind = "grasp", .changes = {}, .map_edits = {grasp_map_edit(object, config)}};
  op.changes.push_back({.id = object.id,
                        .status = ObjectStatus::grasped,
                        .reason = "",
                        .source = "",
                        .cloud = std::nullopt,
                        .T_map_gripper_grasp = T_map_gripper,
                        .cause = PoseCause::grasp,
                        .transform = Eigen::Isometry3d::Identity()});
  return op;
}

Operation release_operation(const ObjectRecord& object, const Eigen::Isometry3d& T_map_gripper, double time) {
  const std::string what = "release of " + object_name(object);
  require_finite(T_map_gripper, what);
  if (object.status != ObjectStatus::grasped || !object.T_map_gripper_grasp)
    throw InputError(what + ": it is " + to_string(object.status) + ", not grasped");
  const Eigen::Isometry3d T = release_transform(*object.T_map_gripper_grasp, T_map_gripper);
  PointCloud moved = object.cloud;
  transform_cloud(moved, T);
  Operation op{.time = time, .kind = "release", .changes = {}, .map_edits = {}};
  op.changes.push_back({.id = object.id,
                        .status = ObjectStatus::placed,
                        .reason = "",
                        .source = "",
                        .cloud = std::move(moved),
                        .T_map_gripper_grasp = std::nullopt,
                        .cause = PoseCause::release,
                        .transform = T});
  return op;
}

RealignResult realign_object(const ObjectRecord& object, const PointCloud& map, const RealignConfig& config) {
  if (object.cloud.empty()) throw InputError(object_name(object) + ": no cloud to re-align");
  RealignResult r;
  const Vec3d c = object.centroid;
  std::vector<Vec3f> target_points = crop_around(map, c, object_radius(object) + config.crop_margin);
  r.map_points = target_points.size();
  const std::size_t min_points = 10;
  if (r.map_points < min_points) {
    r.reason = "no map points near its predicted pose";
    return r;
  }
  std::vector<Vec3f> source;  // the model relative to the predicted centroid
  source.reserve(object.cloud.size());
  for (std::size_t i = 0; i < object.cloud.size(); ++i) source.push_back((object.cloud.world(i) - c).cast<float>());
  const IcpTarget target(std::move(target_points), NormalConfig{.k = 20});
  IcpConfig icp;
  icp.max_iterations = config.max_iterations;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();  // in the frame centred at c
  // Coarse, fine, then the inlier distance with a robust kernel: the model and the new view are
  // different partial views, so only the surface they share should pull.
  for (double d : {config.coarse_distance, config.fine_distance, config.inlier_distance}) {
    icp.max_correspondence_distance = d;
    icp.kernel = d == config.inlier_distance ? "huber" : "none";
    icp.kernel_scale = 0.5 * config.inlier_distance;
    const IcpResult res = register_icp(source, target, T, icp);
    if (res.status == IcpStatus::converged || res.status == IcpStatus::max_iterations) T = res.T_target_source;
  }
  const IcpResult eval = evaluate_alignment(source, target, T, config.inlier_distance);
  r.fitness = eval.fitness;
  r.rmse = eval.rmse;
  // The correction in world coordinates: x ↦ c + T (x - c).
  r.correction = Eigen::Translation3d(c) * T * Eigen::Translation3d(-c);
  r.translation = (r.correction * c - c).norm();
  r.rotation_deg = rotation_angle(T.linear()) * 180.0 / std::numbers::pi;
  r.found = r.fitness >= config.min_fitness && r.rmse <= config.max_rmse;
  if (r.found && (r.translation > config.max_direct_translation || r.rotation_deg > config.max_direct_rotation_deg)) {
    r.found = false;  // ICP slid off the prediction (a round stone spins): not evidence of a pose
    r.reason = format("ICP from its predicted pose slid %.2f m, %.0f deg: not believed", r.translation, r.rotation_deg);
    return r;
  }
  if (!r.found) {
    r.reason = "not found near its predicted pose: " +
               format("%.0f %% of its points seen (min %.0f %%)", 100 * r.fitness, 100 * config.min_fitness) +
               format(", rmse %.3f m (max %.3f m)", r.rmse, config.max_rmse);
    return r;
  }
  r.large = r.translation > config.report_translation || r.rotation_deg > config.report_rotation_deg;
  if (r.large) r.reason = format("fell or rolled after release: moved %.2f m, turned %.1f deg", r.translation, r.rotation_deg);
  return r;
}

RealignResult relocate_object(const ObjectRecord& object, const PointCloud& map,
                              const std::vector<ObjectRecord>& others, const ObjectsConfig& config,
                              const SegmentationConfig& segmentation) {
  RealignResult r = realign_object(object, map, config.realign);
  if (r.found) return r;
  const double reach = object_radius(object) + config.realign.search_radius;
  std::vector<std::uint32_t> near;
  for (std::uint32_t i = 0; i < map.size(); ++i)
    if ((map.world(i) - object.centroid).head<2>().norm() <= reach) near.push_back(i);
  if (near.size() < 100) return r;
  const PointCloud crop = select(map, near);
  const SegmentationResult seg = segment(crop, segmentation);
  const SegmentOwners owners(others, object.id, map, object.centroid, reach, config.association);
  ModelFit best;
  std::set<std::int64_t> taken;  // other objects whose segments were not tried
  for (const Segment& s : seg.segments) {
    const double distance = (crop.origin + s.centroid.cast<double>() - object.centroid).head<2>().norm();
    if (s.planar || distance > config.realign.search_radius) continue;
    const PointCloud points = select(crop, s.indices);
    if (const std::optional<std::int64_t> id = owners.owner(points)) {
      taken.insert(*id);  // another object's segment, as the association's overlap would match it
      continue;
    }
    const ModelFit f = fit_model_to_segment(points, object.cloud, config.association, true);
    if (f.fitness > best.fitness) best = f;
  }
  if (best.fitness < config.realign.search_min_fitness || best.rmse > config.realign.search_max_rmse) {
    r.reason += format("; no segment within %.1f m fits its model (best %.0f %% of its points, min %.0f %%; "
                       "rmse %.3f m, max %.3f m)",
                       config.realign.search_radius, 100 * best.fitness, 100 * config.realign.search_min_fitness,
                       best.rmse, config.realign.search_max_rmse);
    if (!taken.empty()) r.reason += "; segments of objects " + join_ids(taken) + " not tried";
    return r;
  }
  if (!best.unambiguous(config.association.ambiguity_margin)) {
    r.reason += format("; a segment fits its model in several poses (%.0f %% and %.0f %% of its points)",
                       100 * best.fitness, 100 * best.runner_up);
    return r;
  }
  ObjectRecord found = object;
  transform_cloud(found.cloud, best.motion);
  found.centroid = best.motion * object.centroid;
  RealignResult refined = realign_object(found, map, config.realign);
  if (!refined.found) {
    r.reason += "; a segment near fits its model but the map does not confirm it (" + refined.reason + ")";
    return r;
  }
  refined.correction = refined.correction * best.motion;
  refined.translation = (refined.correction * object.centroid - object.centroid).norm();
  refined.rotation_deg = rotation_angle(refined.correction.linear()) * 180.0 / std::numbers::pi;
  refined.large = true;
  refined.reason = format("fell or rolled after release: found %.2f m, %.1f deg from its prediction by search",
                          refined.translation, refined.rotation_deg);
  return refined;
}

Operation realign_operation(const ObjectRecord& object, const RealignResult& result, double time) {
  Operation op{.time = time, .kind = "realign", .changes = {}, .map_edits = {}};
  ObjectChange c{.id = object.id,
                 .status = ObjectStatus::lost,
                 .reason = result.reason,
                 .source = "",
                 .cloud = std::nullopt,
                 .T_map_gripper_grasp = std::nullopt,
                 .cause = PoseCause::lost,
                 .transform = Eigen::Isometry3d::Identity()};
  if (result.found) {
    PointCloud moved = object.cloud;
    transform_cloud(moved, result.correction);
    c.status = ObjectStatus::placed;
    c.cloud = std::move(moved);
    c.cause = PoseCause::realign;
    c.transform = result.correction;
  }
  op.changes.push_back(std::move(c));
  return op;
}

}  // namespace cairn
