#pragma once
// Sec. 4.2, step 2 (scan pair assembly): the vertical sweep S_k^V is merged with the horizontal
// sweep S_k^H into one cloud S_k in the frame of the horizontal LiDAR. The sensors are not
// synchronised and the cabin swings while they spin, so every point is moved with the state-
// estimate pose interpolated at its own timestamp (de-skewing) into the H frame at one reference
// time t_ref:  p_ref = (T_W_C(t_ref) T_C_H)^-1 · T_W_C(t) · T_C_S · p_S.
#include <Eigen/Geometry>
#include <cstdint>
#include <span>
#include <vector>

#include "cairn/core/point_cloud.hpp"
#include "cairn/core/transform.hpp"
#include "cairn/mapping/config.hpp"

namespace cairn {

/// One sweep ready for assembly: sensor-frame points with absolute times, the kept indices
/// (self-filter output; empty span = all) and the sensor's mount on the cabin.
struct SweepInput {
  const PointCloud* cloud = nullptr;
  std::span<const std::uint32_t> keep;
  Eigen::Isometry3d T_cabin_sensor = Eigen::Isometry3d::Identity();
  double t_start = 0.0, t_end = 0.0;
};

struct ScanPair {
  PointCloud cloud;  // reference-sensor frame at `time` (origin zero); times kept per point
  double time = 0.0;  // t_ref
  std::size_t num_h = 0, num_v = 0;
};

/// Moves the sweep's kept points into the reference frame (T_cabin_ref at t_ref) and appends
/// them to `out`. With config.enabled = false, every point uses the pose at the sweep's mid time.
/// Non-finite points are skipped; returns the number appended.
std::size_t deskew_into(const SweepInput& sweep, const std::vector<StampedPose>& T_world_cabin,
                        const Eigen::Isometry3d& T_cabin_ref, double t_ref, const DeskewConfig& config,
                        PointCloud& out);

/// Assembles S_k from S_k^H and S_k^V (either may be null, not both) in the H frame
/// (T_cabin_H) at t_ref = mid time of the H sweep (of the V sweep when H is missing).
[[nodiscard]] ScanPair assemble_scan_pair(const SweepInput* h, const SweepInput* v, const Eigen::Isometry3d& T_cabin_H,
                                          const std::vector<StampedPose>& T_world_cabin,
                                          const DeskewConfig& config);

}  // namespace cairn
