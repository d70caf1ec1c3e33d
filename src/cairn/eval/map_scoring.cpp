#include "cairn/eval/map_scoring.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "cairn/core/error.hpp"

namespace cairn::eval {

std::vector<PoseError> pose_errors(const std::vector<StampedPose>& estimate, const std::vector<StampedPose>& truth) {
  std::vector<PoseError> out;
  if (estimate.empty() || truth.empty()) return out;
  out.reserve(estimate.size());
  for (const StampedPose& p : estimate) {
    const Eigen::Isometry3d T = interpolate_pose(truth, p.time);
    out.push_back({.time = p.time,
                   .position_error_m = (p.pose.translation() - T.translation()).norm(),
                   .rotation_error_deg = rotation_angle(T.linear().transpose() * p.pose.linear()) * 180.0 / std::numbers::pi});
  }
  return out;
}

TrajectoryError trajectory_error(const std::vector<StampedPose>& estimate, const std::vector<StampedPose>& truth) {
  TrajectoryError e;
  const std::vector<PoseError> errors = pose_errors(estimate, truth);
  if (errors.empty()) return e;
  double sum = 0, sum_rot = 0;
  for (const PoseError& pe : errors) {
    sum += pe.position_error_m * pe.position_error_m;
    sum_rot += pe.rotation_error_deg * pe.rotation_error_deg;
    e.ate_max = std::max(e.ate_max, pe.position_error_m);
    ++e.num;
  }
  e.ate_rmse = std::sqrt(sum / e.num);
  for (const StampedPose& p : estimate) e.mean_error += (p.pose.translation() - interpolate_pose(truth, p.time).translation()) / double(e.num);
  e.ate_rmse_without_mean = std::sqrt(std::max(0.0, e.ate_rmse * e.ate_rmse - e.mean_error.squaredNorm()));
  e.rotation_rmse_deg = std::sqrt(sum_rot / e.num);
  return e;
}

ObjectSurfaceTruth::ObjectSurfaceTruth(const PointCloud& truth) : origin_(truth.origin) {
  if (truth.labels.size() != truth.size()) throw InputError("map offset: the truth cloud has no labels");
  for (std::size_t i = 0; i < truth.size(); ++i)
    if (truth.labels[i] >= 0) objects_.push_back(truth.points[i]);
  object_tree_ = std::make_unique<KdTree>(objects_);
  if (!objects_.empty()) target_ = std::make_unique<IcpTarget>(IcpTarget::from_cloud(truth, {.k = 20}));
}

Eigen::Isometry3d ObjectSurfaceTruth::map_offset(const PointCloud& map, double near_distance) const {
  if (!target_) return Eigen::Isometry3d::Identity();  // no objects in the truth
  std::vector<std::uint32_t> keep;
  const float near_sq = float(near_distance * near_distance);
  for (std::uint32_t i = 0; i < map.size(); ++i) {
    float d2 = 0.0f;
    (void)object_tree_->nearest_within((map.world(i) - origin_).cast<float>(), near_sq, &d2);
    if (d2 < near_sq) keep.push_back(i);
  }
  constexpr std::size_t kMinPoints = 10;
  if (keep.size() < kMinPoints) return Eigen::Isometry3d::Identity();
  const IcpConfig icp{.objective = "point_to_plane", .kernel = "huber", .kernel_scale = 0.03,
                      .max_correspondence_distance = 0.15, .max_iterations = 30};
  const IcpResult r = register_icp(select(map, keep), *target_, Eigen::Isometry3d::Identity(), icp);
  return r.status == IcpStatus::too_few_correspondences || r.status == IcpStatus::degenerate
             ? Eigen::Isometry3d::Identity()
             : r.T_target_source;
}

Eigen::Isometry3d map_offset_at_objects(const PointCloud& map, const PointCloud& truth, double near_distance) {
  return ObjectSurfaceTruth(truth).map_offset(map, near_distance);
}

}  // namespace cairn::eval
