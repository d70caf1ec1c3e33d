#pragma once
// Velodyne VLP-16 model (paper Sec. 3: two VLP-16 on the cabin roof). Each firing cycle fires the
// 16 lasers one after the other (2.304 us apart, in the sensor's interleaved elevation order);
// 1 800 cycles per revolution at 10 Hz (0.2 deg azimuth step; the real sensor's 55.3 us cycle
// gives 1 808). The head spins clockwise
// seen from above; azimuth is measured clockwise from the sensor's +y axis (Velodyne convention).
// Every return carries its own timestamp, so a sweep taken while the cabin swings is skewed.
#include <Eigen/Geometry>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "cairn/core/robot_model.hpp"
#include "cairn/sim/raycast.hpp"

namespace cairn::sim {

struct LidarConfig {
  double rate = 10.0;                // [Hz] revolutions per second
  double azimuth_step_deg = 0.2;     // [deg] between firing cycles (~0.2 deg at 10 Hz)
  double laser_interval = 2.304e-6;  // [s] between consecutive lasers of one cycle
  double min_range = 0.5;            // [m] closer returns are dropped (as the sensor does)
  double max_range = 100.0;          // [m]
  double range_noise = 0.03;         // [m] Gaussian range noise sigma (VLP-16: +-3 cm)
  double dropout = 0.01;             // probability that a return is lost
  /// Extra loss at grazing incidence: a return is kept with probability cos(incidence)^k
  /// (0 disables). Models the weak echoes of surfaces seen edge-on.
  double grazing_exponent = 0.3;

  template <class V>
  void visit(V& v) {
    v("rate", rate, "[Hz] revolutions per second");
    v("azimuth_step_deg", azimuth_step_deg, "[deg] azimuth between firing cycles");
    v("laser_interval", laser_interval, "[s] between the lasers of one firing cycle");
    v("min_range", min_range, "[m] closer returns are dropped");
    v("max_range", max_range, "[m] farther surfaces give no return");
    v("range_noise", range_noise, "[m] range noise sigma");
    v("dropout", dropout, "probability that a return is lost");
    v("grazing_exponent", grazing_exponent, "returns kept with probability cos(incidence)^k");
  }
};

/// VLP-16 elevation of each laser in firing order [deg] (-15, 1, -13, 3, ...).
inline constexpr double kVlp16Elevation[16] = {-15, 1, -13, 3, -11, 5, -9, 7, -7, 9, -5, 11, -3, 13, -1, 15};
/// Ring index of laser l: 0 = lowest beam (-15 deg), 15 = highest (+15 deg), as ROS drivers number them.
inline int vlp16_ring(int laser) { return static_cast<int>((kVlp16Elevation[laser] + 15.0) / 2.0); }

/// Throws ConfigError naming the first invalid value.
void validate(const LidarConfig& config);

/// One revolution of one sensor: returns in the sensor frame at their own firing time.
struct Sweep {
  std::string sensor;  // "H" or "V"
  int index = 0;
  double t_start = 0.0, t_end = 0.0;  // [s] first and last firing of the revolution
  std::vector<Eigen::Vector3f> points;
  std::vector<double> times;          // [s] absolute
  std::vector<std::uint8_t> rings;
  std::vector<std::int32_t> truth;    // what was hit: -1 terrain, k stone, kLabelRobot
  std::size_t num_rays = 0;           // rays fired (returns + misses + dropouts)
};

/// What moves during a sweep, as functions of time: the sensor pose in the world and the robot's
/// own shapes (poses in the world of every link, matching robot.links), and what the robot holds.
struct LidarMotion {
  std::function<Eigen::Isometry3d(double)> T_world_sensor;
  const RobotModel* robot = nullptr;  // optional: self-occlusion by the robot's links
  std::function<std::vector<Eigen::Isometry3d>(double)> link_poses;
  /// Optional: meshes fixed to link `held_link` (a stone in the gripper), in that link's frame,
  /// moving with it; their hits keep the scene's labels. Needs robot and link_poses.
  const RayScene* held = nullptr;
  int held_link = -1;
};

/// Direction of laser l at azimuth `azimuth_rad` in the sensor frame (unit vector).
Eigen::Vector3d vlp16_direction(int laser, double azimuth_rad);

/// Simulates one revolution starting at t_start. Deterministic for (seed, sensor, index) no matter
/// how TBB schedules the work. Throws ConfigError on invalid configuration values.
Sweep simulate_sweep(const RayScene& world, const LidarMotion& motion, const LidarConfig& config,
                     const std::string& sensor, int index, double t_start, std::uint64_t seed);

/// Counter-based random numbers (SplitMix64): cheap to seed per firing, so parallel simulation
/// stays deterministic.
struct SplitMix64 {
  std::uint64_t state;
  explicit SplitMix64(std::uint64_t seed) : state(seed) {}
  std::uint64_t next() {
    std::uint64_t z = (state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  double uniform01() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }
  double normal();  // Box–Muller
};

/// Mixes several integers into one seed.
std::uint64_t mix_seed(std::uint64_t a, std::uint64_t b, std::uint64_t c = 0, std::uint64_t d = 0);
/// FNV-1a hash of a name (stable across platforms, unlike std::hash).
std::uint64_t name_hash(const std::string& name);

}  // namespace cairn::sim
