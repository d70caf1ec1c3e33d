#include "cairn/mapping/self_filter.hpp"

#include <algorithm>
#include <cmath>

#include "cairn/core/error.hpp"

namespace cairn {

std::vector<PosedShape> pose_shapes(const RobotModel& robot, const JointState& q,
                                    const Eigen::Isometry3d& T_root_F, double padding) {
  const std::vector<Eigen::Isometry3d> T_root_link = robot.forward_kinematics(q);
  std::vector<PosedShape> out;
  for (std::size_t l = 0; l < robot.links.size(); ++l)
    for (const Shape& shape : robot.links[l].shapes) {
      const Eigen::Isometry3d T_F_shape = T_root_F.inverse() * T_root_link[l] * shape.T_link_shape;
      out.push_back({.shape = &shape,
                     .T_shape_frame = T_F_shape.inverse(),
                     .center = T_F_shape.translation(),
                     .radius = shape.bounding_radius() + padding});
    }
  return out;
}

bool hits_robot(std::span<const PosedShape> shapes, const Vec3d& p, double padding) {
  for (const PosedShape& s : shapes) {
    if ((p - s.center).squaredNorm() > s.radius * s.radius) continue;
    if (s.shape->contains(s.T_shape_frame * p, padding)) return true;
  }
  return false;
}

std::vector<std::uint32_t> self_filter(const PointCloud& sweep, const RobotModel& robot,
                                       const std::vector<JointState>& joint_states,
                                       const Eigen::Isometry3d& T_cabin_sensor, const SelfFilterConfig& config,
                                       double t_fallback) {
  std::vector<std::uint32_t> kept;
  kept.reserve(sweep.size());
  if (!config.enabled || sweep.empty()) {
    for (std::uint32_t i = 0; i < sweep.size(); ++i) kept.push_back(i);
    return kept;
  }
  const int cabin = robot.link_index("cabin");
  if (cabin < 0) throw InputError("self-filter: the robot model has no link named 'cabin'");
  const bool timed = sweep.has_times();
  double t0 = t_fallback, t1 = t_fallback;
  if (timed) {
    const auto [lo, hi] = std::minmax_element(sweep.times.begin(), sweep.times.end());
    t0 = *lo;
    t1 = *hi;
  }
  const int slots = std::max(1, config.time_slots);
  std::vector<std::vector<PosedShape>> posed(slots);
  for (int k = 0; k < slots; ++k) {
    const double t = t0 + (t1 - t0) * (k + 0.5) / slots;
    const JointState q = interpolate_joints(joint_states, t);
    const Eigen::Isometry3d T_root_cabin = robot.forward_kinematics(q)[cabin];
    posed[k] = pose_shapes(robot, q, T_root_cabin * T_cabin_sensor, config.padding);
  }
  const double span = std::max(t1 - t0, 1e-9);
  for (std::uint32_t i = 0; i < sweep.size(); ++i) {
    const int k = timed ? std::clamp(int((sweep.times[i] - t0) / span * slots), 0, slots - 1) : 0;
    if (!hits_robot(posed[k], sweep.points[i].cast<double>(), config.padding)) kept.push_back(i);
  }
  return kept;
}

}  // namespace cairn
