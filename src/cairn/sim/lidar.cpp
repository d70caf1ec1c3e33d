#include "cairn/sim/lidar.hpp"

#include <tbb/parallel_for.h>

#include <cmath>
#include <limits>
#include <numbers>

#include "cairn/core/error.hpp"
#include "cairn/sim/world.hpp"
#include "cairn/core/units.hpp"

namespace cairn::sim {

namespace {
constexpr int kLasers = 16;

}  // namespace

void validate(const LidarConfig& c) {
  const auto require = [](bool ok, const char* message) {
    if (!ok) throw ConfigError(std::string("LidarConfig: ") + message);
  };
  require(std::isfinite(c.rate) && c.rate > 0, "rate must be positive");
  require(std::isfinite(c.azimuth_step_deg) && c.azimuth_step_deg > 0 && c.azimuth_step_deg <= 10,
          "azimuth_step_deg must be in (0, 10]");
  require(std::isfinite(c.laser_interval) && c.laser_interval >= 0 &&
              kLasers * c.laser_interval <= 1.0 / c.rate * c.azimuth_step_deg / 360.0,
          "laser_interval: 16 lasers must fit in one firing cycle");
  require(c.min_range >= 0 && c.max_range > c.min_range, "need 0 <= min_range < max_range");
  require(std::isfinite(c.range_noise) && c.range_noise >= 0, "range_noise must be >= 0");
  require(c.dropout >= 0 && c.dropout < 1, "dropout must be in [0, 1)");
  require(std::isfinite(c.grazing_exponent) && c.grazing_exponent >= 0, "grazing_exponent must be >= 0");
}

namespace {

constexpr int kCyclesPerShapeUpdate = 16;

struct ShapePose {
  const Shape* shape;
  Eigen::Isometry3d T_shape_sensor;
  Eigen::Vector3d centre;  // in the sensor frame
  double radius;
  // Azimuths (vlp16_direction's convention) of the rays that can pass through the bounding
  // sphere: within half_width of `azimuth`, or any when the sphere is close to the sensor.
  double azimuth = 0.0;
  double half_width = 0.0;
  bool any_azimuth = true;
};

ShapePose pose_shape(const Shape& s, const Eigen::Isometry3d& T_sensor_shape) {
  ShapePose p{&s, T_sensor_shape.inverse(), T_sensor_shape.translation(), s.bounding_radius()};
  // A ray d passing the sphere test of simulate_sweep (c.d + r >= 0, |c - (c.d) d| <= r) has
  // c.d >= 0 once |c| > sqrt(2) r, so its horizontal projection passes within r of the centre's
  // projection, at an azimuth within asin(r / rho) of the centre's (rho > r its horizontal
  // distance). Conservative: every ray this rejects, the sphere test rejects too. The margins
  // (1.5 r for sqrt(2) r, 1.01 r for r, 1e-6 rad on the interval) absorb the rounding of
  // atan2/asin; a shape inside them is tested for every azimuth.
  const double rho = p.centre.head<2>().norm();
  if (p.centre.norm() > 1.5 * p.radius && rho > 1.01 * p.radius) {
    p.any_azimuth = false;
    p.azimuth = std::atan2(p.centre.x(), p.centre.y());
    p.half_width = std::asin(p.radius / rho) + 1e-6;
  }
  return p;
}

/// Whether the rays of a firing cycle at `azimuth` can reach the shape's bounding sphere.
bool in_azimuth(const ShapePose& p, double azimuth) {
  return p.any_azimuth || std::abs(std::remainder(azimuth - p.azimuth, 2.0 * std::numbers::pi)) <= p.half_width;
}
}  // namespace

double SplitMix64::normal() {
  const double u1 = std::max(uniform01(), std::numeric_limits<double>::min());
  const double u2 = uniform01();
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * std::numbers::pi * u2);
}

std::uint64_t mix_seed(std::uint64_t a, std::uint64_t b, std::uint64_t c, std::uint64_t d) {
  SplitMix64 m(a);
  std::uint64_t h = m.next();
  for (std::uint64_t v : {b, c, d}) {
    SplitMix64 n(h ^ (v * 0xD6E8FEB86659FD93ull));
    h = n.next();
  }
  return h;
}

std::uint64_t name_hash(const std::string& name) {
  std::uint64_t h = 0xcbf29ce484222325ull;
  for (unsigned char ch : name) {
    h ^= ch;
    h *= 0x100000001b3ull;
  }
  return h;
}

Eigen::Vector3d vlp16_direction(int laser, double azimuth_rad) {
  const double el = kVlp16Elevation[laser] * kDeg;
  return {std::cos(el) * std::sin(azimuth_rad), std::cos(el) * std::cos(azimuth_rad), std::sin(el)};
}

Sweep simulate_sweep(const RayScene& world, const LidarMotion& motion, const LidarConfig& config,
                     const std::string& sensor, int index, double t_start, std::uint64_t seed) {
  validate(config);
  if (!motion.T_world_sensor) throw ConfigError("simulate_sweep: no sensor trajectory");
  const int cycles = static_cast<int>(std::lround(360.0 / config.azimuth_step_deg));
  const double period = 1.0 / config.rate;
  const double cycle_time = period / cycles;
  const std::uint64_t sweep_seed = mix_seed(seed, name_hash(sensor), static_cast<std::uint64_t>(index));

  struct Return {
    Eigen::Vector3f p;
    std::int32_t truth;
    bool valid = false;
  };
  std::vector<Return> returns(static_cast<std::size_t>(cycles) * kLasers);
  const bool held = motion.held != nullptr;
  if (held && (motion.robot == nullptr || !motion.link_poses || motion.held_link < 0 ||
               std::size_t(motion.held_link) >= motion.robot->links.size()))
    throw ConfigError("simulate_sweep: a held mesh needs the robot, its link poses and a valid link");
  // Robot shapes move with the cabin, so they are posed relative to the sensor; that relative
  // pose changes only with the arm joints (and, for the base, the cabin yaw), slowly enough to be
  // evaluated once per block of kCyclesPerShapeUpdate firing cycles (< 1 ms).
  tbb::parallel_for(tbb::blocked_range<int>(0, cycles, kCyclesPerShapeUpdate), [&](const tbb::blocked_range<int>& range) {
    std::vector<ShapePose> shapes;
    Eigen::Isometry3d T_held_sensor = Eigen::Isometry3d::Identity();  // sensor -> held link
    if (motion.robot != nullptr && motion.link_poses) {
      const double t = t_start + range.begin() * cycle_time;
      const Eigen::Isometry3d T_sensor_world = motion.T_world_sensor(t).inverse();
      const auto links = motion.link_poses(t);
      for (std::size_t l = 0; l < motion.robot->links.size(); ++l) {
        for (const auto& s : motion.robot->links[l].shapes) {
          shapes.push_back(pose_shape(s, T_sensor_world * links[l] * s.T_link_shape));
        }
      }
      if (held) T_held_sensor = (T_sensor_world * links[std::size_t(motion.held_link)]).inverse();
    }
    std::vector<const ShapePose*> facing;  // the shapes the cycle's rays can reach
    for (int c = range.begin(); c != range.end(); ++c) {
      const double t = t_start + c * cycle_time;
      const Eigen::Isometry3d T_ws = motion.T_world_sensor(t);
      SplitMix64 rng(mix_seed(sweep_seed, static_cast<std::uint64_t>(c)));
      // Azimuth clockwise from +y: the head turns by 360 deg per revolution.
      const double azimuth = 2.0 * std::numbers::pi * c / cycles;
      facing.clear();
      for (const ShapePose& sp : shapes)
        if (in_azimuth(sp, azimuth)) facing.push_back(&sp);
      const Eigen::Vector3d origin = T_ws.translation();
      for (int l = 0; l < kLasers; ++l) {
        const Eigen::Vector3d d_sensor = vlp16_direction(l, azimuth);
        const Eigen::Vector3d d = T_ws.linear() * d_sensor;
        Ray ray{.origin = origin.cast<float>(), .direction = d.cast<float>(),
                .t_near = static_cast<float>(config.min_range), .t_far = static_cast<float>(config.max_range)};
        RayHit hit = world.intersect(ray);
        double range_hit = hit.hit() ? hit.t : std::numeric_limits<double>::infinity();
        std::int32_t label = hit.label;
        double cos_incidence = hit.hit() ? std::abs(hit.normal.cast<double>().dot(d)) : 1.0;
        if (held) {  // the held mesh in its link's frame: the ray moved there
          const Eigen::Vector3d o_h = T_held_sensor.translation(), d_h = T_held_sensor.linear() * d_sensor;
          const RayHit h = motion.held->intersect(Ray{.origin = o_h.cast<float>(), .direction = d_h.cast<float>(),
                                                      .t_near = ray.t_near, .t_far = ray.t_far});
          if (h.hit() && h.t < range_hit) {
            range_hit = h.t;
            label = h.label;
            cos_incidence = std::abs(h.normal.cast<double>().dot(d_h));
          }
        }
        for (const ShapePose* sp : facing) {
          // Sensor frame: the ray starts at the origin. Sphere rejection before the exact test.
          const double along = sp->centre.dot(d_sensor);
          if (along + sp->radius < 0 || (sp->centre - along * d_sensor).squaredNorm() > sp->radius * sp->radius) continue;
          const double ts = sp->shape->intersect(sp->T_shape_sensor.translation(), sp->T_shape_sensor.linear() * d_sensor);
          if (ts >= config.min_range && ts < range_hit) {
            range_hit = ts;
            label = kLabelRobot;
            cos_incidence = 1.0;
          }
        }
        // Draw the random numbers for every laser, hit or not, so the sequence never depends on
        // what was hit.
        const double u_drop = rng.uniform01(), u_graze = rng.uniform01(), noise = rng.normal();
        if (!(range_hit <= config.max_range)) continue;
        if (u_drop < config.dropout) continue;
        if (config.grazing_exponent > 0 && u_graze > std::pow(cos_incidence, config.grazing_exponent)) continue;
        const double r = range_hit + config.range_noise * noise;
        if (r < config.min_range || r > config.max_range) continue;
        Return& out = returns[static_cast<std::size_t>(c) * kLasers + static_cast<std::size_t>(l)];
        out.p = (r * d_sensor).cast<float>();
        out.truth = label;
        out.valid = true;
      }
    }
  }, tbb::simple_partitioner());

  Sweep sweep;
  sweep.sensor = sensor;
  sweep.index = index;
  sweep.t_start = t_start;
  sweep.t_end = t_start + (cycles - 1) * cycle_time + (kLasers - 1) * config.laser_interval;
  sweep.num_rays = returns.size();
  std::size_t n = 0;
  for (const auto& r : returns) n += r.valid ? 1 : 0;
  sweep.points.reserve(n);
  sweep.times.reserve(n);
  sweep.rings.reserve(n);
  sweep.truth.reserve(n);
  for (int c = 0; c < cycles; ++c) {
    for (int l = 0; l < kLasers; ++l) {
      const Return& r = returns[static_cast<std::size_t>(c) * kLasers + static_cast<std::size_t>(l)];
      if (!r.valid) continue;
      sweep.points.push_back(r.p);
      sweep.times.push_back(t_start + c * cycle_time + l * config.laser_interval);
      sweep.rings.push_back(static_cast<std::uint8_t>(vlp16_ring(l)));
      sweep.truth.push_back(r.truth);
    }
  }
  return sweep;
}

}  // namespace cairn::sim
