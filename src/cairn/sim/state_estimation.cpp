#include "cairn/sim/state_estimation.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

#include "cairn/core/error.hpp"
#include "cairn/sim/lidar.hpp"
#include "cairn/core/units.hpp"

namespace cairn::sim {

namespace {
constexpr double kMaxSamples = 1e8;

void validate(const StateEstimationConfig& c, double t0, double t1) {
  const auto require = [](bool ok, const char* message) {
    if (!ok) throw ConfigError(std::string("StateEstimationConfig: ") + message);
  };
  require(std::isfinite(c.rate) && c.rate > 0, "rate must be positive");
  require(std::isfinite(t0) && std::isfinite(t1) && t1 >= t0, "need t0 <= t1");
  require((t1 - t0) * c.rate < kMaxSamples, "too many samples");
  require(c.correlation_time > 0, "correlation_time must be positive");
  require(std::isfinite(c.knot_interval) && c.knot_interval > 0, "knot_interval must be positive");
  for (double v : {c.position_sigma, c.rotation_sigma_deg, c.yaw_sigma_deg, c.position_drift,
                   c.rotation_drift_deg, c.position_jitter, c.rotation_jitter_deg, c.joint_noise_deg,
                   c.prismatic_noise}) {
    require(std::isfinite(v) && v >= 0, "noise levels must be finite and >= 0");
  }
}

/// First-order Gauss–Markov process with stationary sigma, sampled every dt.
struct GaussMarkov {
  double value = 0.0, phi = 0.0, drive = 0.0;
  GaussMarkov(double sigma, double tau, double dt, SplitMix64& rng)
      : value(sigma * rng.normal()), phi(std::exp(-dt / tau)), drive(sigma * std::sqrt(1.0 - phi * phi)) {}
  double step(SplitMix64& rng) { return value = phi * value + drive * rng.normal(); }
};
}  // namespace

StateEstimate simulate_state_estimation(const std::function<Eigen::Isometry3d(double)>& T_world_cabin,
                                        const std::function<JointState(double)>& joints,
                                        const RobotModel& robot, double t0, double t1,
                                        const StateEstimationConfig& c, std::uint64_t seed) {
  validate(c, t0, t1);
  const double dt = 1.0 / c.rate;
  const auto n = static_cast<std::size_t>(std::floor((t1 - t0) * c.rate + 1e-9)) + 1;
  SplitMix64 rng(mix_seed(seed, name_hash("state_estimation")));
  // Slow errors: knots every knot_interval (Gauss–Markov + random walk), interpolated by
  // Catmull–Rom splines, so the error is smooth between output samples.
  const double h = c.knot_interval;
  const auto knots = static_cast<std::size_t>(std::ceil((t1 - t0) / h)) + 4;  // one before, two after
  const double rot_sigma[3] = {c.rotation_sigma_deg * kDeg, c.rotation_sigma_deg * kDeg, c.yaw_sigma_deg * kDeg};
  std::vector<Eigen::Matrix<double, 6, 1>> e(knots);
  {
    std::vector<GaussMarkov> gm;
    for (int k = 0; k < 3; ++k) gm.emplace_back(c.position_sigma, c.correlation_time, h, rng);
    for (int k = 0; k < 3; ++k) gm.emplace_back(rot_sigma[k], c.correlation_time, h, rng);
    Eigen::Matrix<double, 6, 1> walk = Eigen::Matrix<double, 6, 1>::Zero();
    const double pos_step = c.position_drift * std::sqrt(h), rot_step = c.rotation_drift_deg * kDeg * std::sqrt(h);
    for (std::size_t k = 0; k < knots; ++k) {
      for (int a = 0; a < 6; ++a) {
        if (k > 0) walk[a] += (a < 3 ? pos_step : rot_step) * rng.normal();
        e[k][a] = gm[static_cast<std::size_t>(a)].step(rng) + walk[a];
      }
    }
  }
  const auto slow_error = [&](double t) {
    const double u = (t - t0) / h + 1.0;  // knot 1 sits at t0
    const auto k = std::min(static_cast<std::size_t>(u), knots - 3);
    const double s = u - static_cast<double>(k);
    const auto& p0 = e[k - 1];
    const auto& p1 = e[k];
    const auto& p2 = e[k + 1];
    const auto& p3 = e[k + 2];
    return (0.5 * ((2.0 * p1) + (-p0 + p2) * s + (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3) * s * s +
                   (-p0 + 3.0 * p1 - 3.0 * p2 + p3) * s * s * s))
        .eval();
  };
  const auto is_prismatic = [&robot](const std::string& joint) {
    return std::any_of(robot.links.begin(), robot.links.end(), [&](const Link& l) {
      return l.joint == Link::Joint::Prismatic && l.joint_name == joint;
    });
  };

  StateEstimate out;
  out.truth.reserve(n);
  out.estimate.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double t = t0 + static_cast<double>(i) * dt;
    const Eigen::Isometry3d T = T_world_cabin(t);
    const Eigen::Matrix<double, 6, 1> slow = slow_error(t);
    Eigen::Vector3d dp, dr;
    for (int k = 0; k < 3; ++k) {
      dp[k] = slow[k] + c.position_jitter * rng.normal();
      dr[k] = slow[k + 3] + c.rotation_jitter_deg * kDeg * rng.normal();
    }
    Eigen::Isometry3d E = T;
    E.translation() += dp;
    const double angle = dr.norm();
    if (angle > 0) E.linear() = Eigen::AngleAxisd(angle, dr / angle).toRotationMatrix() * T.linear();
    out.truth.push_back({t, T});
    out.estimate.push_back({t, E});

    JointState q = joints(t);
    q.time = t;
    JointState m = q;
    for (std::size_t j = 0; j < m.names.size(); ++j) {
      m.positions[j] += (is_prismatic(m.names[j]) ? c.prismatic_noise : c.joint_noise_deg * kDeg) * rng.normal();
    }
    out.joints_truth.push_back(std::move(q));
    out.joints.push_back(std::move(m));
  }
  return out;
}

}  // namespace cairn::sim
