#include "cairn/grasp/force_closure.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include "cairn/core/units.hpp"

namespace cairn::grasp {
namespace {

using Eigen::Isometry3d;
using Eigen::Vector3d;

double angle_between(const Vector3d& a, const Vector3d& b) { return std::acos(std::clamp(a.dot(b), -1.0, 1.0)); }

}  // namespace

double cone_margin(const Closing& c, double mu) {
  const Vector3d line = c.contacts[1] - c.contacts[0];
  if (line.norm() < 1e-9) return -std::numbers::pi;
  const Vector3d u = line.normalized();
  const double half = std::atan(mu);
  return half - std::max(angle_between(c.forces[0], u), angle_between(c.forces[1], -u));
}

bool force_closure(const Closing& c, double mu) { return c.closed && cone_margin(c, mu) >= 0.0; }

double robustness(const PlanningCloud& pc, const KdTree& tree, const Candidate& cand, const GripperConfig& g,
                  const ForceClosureConfig& c, double voxel, std::uint64_t salt) {
  const double mu_design = c.mu / c.mu_safety;
  if (c.perturbations == 0) return force_closure(cand.closing, mu_design) ? 1.0 : 0.0;
  Neighbors nb;
  const Vector3d centre = closing_centre(g, cand.T);
  const double sigma_t = c.sigma_translation_voxels * voxel;
  tree.radius(centre.cast<float>(), float(closing_reach(g, cand.opening) + 4.0 * sigma_t), nb);
  std::mt19937_64 rng(c.seed ^ (salt * 0x9E3779B97F4A7C15ULL));
  std::normal_distribution<double> gauss(0.0, 1.0);
  const double open_angle = jaw_angle_for(g, cand.opening);
  LocalPoints local;
  int kept = 0;
  for (int k = 0; k < c.perturbations; ++k) {
    // One draw per statement: a call's argument order is unspecified (GCC: right to left, the order
    // kept so that a seed gives the same result with every compiler and as before).
    const double tz = gauss(rng), ty = gauss(rng), tx = gauss(rng);
    const Vector3d dt = sigma_t * Vector3d(tx, ty, tz);
    const double rz = gauss(rng), ry = gauss(rng), rx = gauss(rng);
    const Vector3d dr(rx, ry, rz);
    const double mu = std::max(0.0, mu_design * (1.0 + c.sigma_mu * gauss(rng)));
    Isometry3d P = Isometry3d::Identity();
    P.translation() = dt;
    const Vector3d w = dr * (c.sigma_rotation_deg * kDeg);
    if (w.norm() > 0) P.linear() = Eigen::AngleAxisd(w.norm(), w.normalized()).toRotationMatrix();
    gather_local(pc.cloud, nb.indices, cand.T * P, cand.opening, g, local);
    const Closing closing = close_jaws(g, open_angle, local.object, local.normals, local.environment, c.patch_voxels * voxel);
    kept += force_closure(closing, mu) ? 1 : 0;
  }
  return double(kept) / double(c.perturbations);
}

}  // namespace cairn::grasp
