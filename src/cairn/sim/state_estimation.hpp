#pragma once
// What the excavator's state estimator (GNSS + IMUs + encoders, paper Sec. 3 and 4.2) reports:
// the cabin pose at a high rate with realistic errors, and the joint encoder readings.
//
// Error model of the pose: the fused GNSS/IMU solution is smooth at short time scales (the IMU
// integrates) and wrong at long ones (RTK-GNSS noise and multipath, heading error). Each of the
// three position axes and three rotation axes carries
//   - a first-order Gauss–Markov error (correlation time `correlation_time`, stationary sigma),
//   - a random-walk drift (sigma growing with sqrt(t)),
//   both drawn at knots every `knot_interval` and interpolated by Catmull–Rom splines (smooth),
//   - a small white jitter.
// So neighbouring poses agree to millimetres (good enough to de-skew a sweep) while the absolute
// pose is off by centimetres, which scan matching has to correct.
#include <Eigen/Geometry>
#include <cstdint>
#include <functional>
#include <vector>

#include "cairn/core/robot_model.hpp"
#include "cairn/core/transform.hpp"

namespace cairn::sim {

struct StateEstimationConfig {
  double rate = 100.0;                  // [Hz] pose and joint-state output rate
  double position_sigma = 0.02;         // [m] Gauss–Markov position error per axis
  double rotation_sigma_deg = 0.08;     // [deg] Gauss–Markov roll/pitch error
  double yaw_sigma_deg = 0.15;          // [deg] Gauss–Markov heading error (dual-antenna GNSS)
  double correlation_time = 3.0;        // [s]
  double knot_interval = 0.5;           // [s] spacing of the slow-error spline knots
  double position_drift = 0.002;        // [m/sqrt(s)] random walk
  double rotation_drift_deg = 0.005;    // [deg/sqrt(s)] random walk (all three axes)
  double position_jitter = 0.0005;      // [m] white noise
  double rotation_jitter_deg = 0.002;   // [deg] white noise
  double joint_noise_deg = 0.05;        // [deg] encoder noise of revolute joints
  double prismatic_noise = 0.002;       // [m] encoder noise of prismatic joints

  template <class V>
  void visit(V& v) {
    v("rate", rate, "[Hz] pose and joint-state output rate");
    v("position_sigma", position_sigma, "[m] correlated position error per axis");
    v("rotation_sigma_deg", rotation_sigma_deg, "[deg] correlated roll/pitch error");
    v("yaw_sigma_deg", yaw_sigma_deg, "[deg] correlated heading error");
    v("correlation_time", correlation_time, "[s] correlation time of those errors");
    v("knot_interval", knot_interval, "[s] spacing of the knots of the smooth slow errors");
    v("position_drift", position_drift, "[m/sqrt(s)] position random walk");
    v("rotation_drift_deg", rotation_drift_deg, "[deg/sqrt(s)] rotation random walk");
    v("position_jitter", position_jitter, "[m] white position noise");
    v("rotation_jitter_deg", rotation_jitter_deg, "[deg] white rotation noise");
    v("joint_noise_deg", joint_noise_deg, "[deg] encoder noise of revolute joints");
    v("prismatic_noise", prismatic_noise, "[m] encoder noise of prismatic joints");
  }
};

struct StateEstimate {
  std::vector<StampedPose> truth;      // true cabin poses at the output times
  std::vector<StampedPose> estimate;   // what the estimator reports
  std::vector<JointState> joints_truth;
  std::vector<JointState> joints;      // encoder readings
};

/// Samples [t0, t1] at `rate`. `robot` tells which joints are prismatic (metres of noise instead
/// of degrees). Deterministic for the seed. Throws ConfigError on invalid values.
StateEstimate simulate_state_estimation(const std::function<Eigen::Isometry3d(double)>& T_world_cabin,
                                        const std::function<JointState(double)>& joints,
                                        const RobotModel& robot, double t0, double t1,
                                        const StateEstimationConfig& config, std::uint64_t seed);

}  // namespace cairn::sim
