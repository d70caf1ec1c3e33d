#pragma once
// A pose from a position, a yaw and a roll, for tests that place objects and grippers.
#include <Eigen/Geometry>

#include "cairn/core/transform.hpp"

namespace cairn::test {

inline Eigen::Isometry3d pose(double x, double y, double z, double yaw, double roll = 0.0) {
  Eigen::Isometry3d T = pure_translation(x, y, z);
  T.rotate(Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()));
  return T;
}

}  // namespace cairn::test
