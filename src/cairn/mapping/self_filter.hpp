#pragma once
// Sec. 4.2, step 1 (self-filtering): the excavator's links are approximated by boxes and cylinders
// (robot.json), posed from the joint states at the time of each point, grown by a padding margin;
// returns that fall inside any of them are discarded (Jud et al., 2019).
#include <Eigen/Geometry>
#include <cstdint>
#include <span>
#include <vector>

#include "cairn/core/point_cloud.hpp"
#include "cairn/core/robot_model.hpp"
#include "cairn/mapping/config.hpp"

namespace cairn {

/// One collision shape posed in a query frame F, with its bounding sphere for a quick reject.
struct PosedShape {
  const Shape* shape = nullptr;
  Eigen::Isometry3d T_shape_frame = Eigen::Isometry3d::Identity();
  Vec3d center = Vec3d::Zero();  // shape origin in F
  double radius = 0.0;           // bounding radius incl. padding
};

/// All shapes of `robot` at joint state q, posed in frame F given T_root_F (root link ← F).
[[nodiscard]] std::vector<PosedShape> pose_shapes(const RobotModel& robot, const JointState& q,
                                                  const Eigen::Isometry3d& T_root_F, double padding);

/// Whether p (frame F) lies inside any posed shape grown by `padding`.
[[nodiscard]] bool hits_robot(std::span<const PosedShape> shapes, const Vec3d& p, double padding);

/// Indices of the sweep's points (sensor frame, absolute `times`) that do NOT hit the robot.
/// T_cabin_sensor: sensor mount; the link named "cabin" must exist in the model (InputError
/// otherwise). Without per-point times, the joint state at `t_fallback` is used.
[[nodiscard]] std::vector<std::uint32_t> self_filter(const PointCloud& sweep, const RobotModel& robot,
                                                     const std::vector<JointState>& joint_states,
                                                     const Eigen::Isometry3d& T_cabin_sensor,
                                                     const SelfFilterConfig& config, double t_fallback = 0.0);

}  // namespace cairn
