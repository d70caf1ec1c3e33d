#include "cairn/mapping/scan_pair.hpp"

#include <algorithm>
#include <cmath>

namespace cairn {

std::size_t deskew_into(const SweepInput& sweep, const std::vector<StampedPose>& T_world_cabin,
                        const Eigen::Isometry3d& T_cabin_ref, double t_ref, const DeskewConfig& config,
                        PointCloud& out) {
  const PointCloud& c = *sweep.cloud;
  const Eigen::Isometry3d T_ref_world = (interpolate_pose(T_world_cabin, t_ref) * T_cabin_ref).inverse();
  auto T_ref_sensor = [&](double t) {
    return Eigen::Isometry3f((T_ref_world * interpolate_pose(T_world_cabin, t) * sweep.T_cabin_sensor).cast<float>());
  };
  // Pose lookup table over the sweep at `slot` resolution (nearest slot per point).
  const double t0 = sweep.t_start, t1 = std::max(sweep.t_end, sweep.t_start);
  const bool per_point = config.enabled && c.has_times();
  const int slots = per_point ? std::max(1, int(std::ceil((t1 - t0) / config.slot)) + 1) : 1;
  std::vector<Eigen::Isometry3f> table(slots);
  if (per_point)
    for (int k = 0; k < slots; ++k) table[k] = T_ref_sensor(t0 + k * config.slot);
  else
    table[0] = T_ref_sensor(0.5 * (t0 + t1));
  const std::size_t n = sweep.keep.empty() ? c.size() : sweep.keep.size();
  const bool with_times = out.has_times() || out.empty();
  std::size_t added = 0;
  for (std::size_t j = 0; j < n; ++j) {
    const std::uint32_t i = sweep.keep.empty() ? std::uint32_t(j) : sweep.keep[j];
    const Vec3f& p = c.points[i];
    if (!p.allFinite()) continue;
    int k = 0;
    if (per_point) {
      const double t = c.times[i];
      if (!std::isfinite(t)) continue;
      k = std::clamp(int(std::lround((t - t0) / config.slot)), 0, slots - 1);
    }
    out.points.push_back(table[k] * p);
    if (with_times) out.times.push_back(c.has_times() ? c.times[i] : t_ref);
    ++added;
  }
  return added;
}

ScanPair assemble_scan_pair(const SweepInput* h, const SweepInput* v, const Eigen::Isometry3d& T_cabin_H,
                            const std::vector<StampedPose>& T_world_cabin, const DeskewConfig& config) {
  ScanPair pair;
  const SweepInput* ref = h ? h : v;
  if (!ref) return pair;
  pair.time = 0.5 * (ref->t_start + ref->t_end);
  if (h) pair.num_h = deskew_into(*h, T_world_cabin, T_cabin_H, pair.time, config, pair.cloud);
  if (v) pair.num_v = deskew_into(*v, T_world_cabin, T_cabin_H, pair.time, config, pair.cloud);
  return pair;
}

}  // namespace cairn
