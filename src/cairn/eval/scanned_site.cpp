#include "cairn/eval/scanned_site.hpp"

#include <algorithm>

#include "cairn/core/transform.hpp"
#include "cairn/segmentation/segmenter.hpp"

namespace cairn::eval {
namespace {

sim::SimulationConfig at_rest(sim::SimulationConfig c) {
  c.settle_in_physics = true;  // one world at rest for the sensors, the physics and the truth
  return c;
}

}  // namespace

void require_scenarios(const std::vector<std::string>& scenarios) {
  const std::vector<std::string> known = sim::scenario_names();
  for (const std::string& s : scenarios)
    if (std::find(known.begin(), known.end(), s) == known.end()) (void)sim::scenario_config(s, {});  // throws
}

SurfaceTruth::SurfaceTruth(const sim::Site& site, const Vec3d& base, double radius, double spacing, std::uint64_t seed) {
  sim::SamplingConfig s;
  s.spacing = spacing;
  s.noise_sigma = 0.0;
  const sim::SampledSite sampled = sim::sample_site(site, s, seed);
  std::vector<std::uint32_t> keep;
  for (std::size_t i = 0; i < sampled.cloud.size(); ++i)
    if ((sampled.cloud.world(i) - base).head<2>().norm() < radius) keep.push_back(std::uint32_t(i));
  cloud = select(sampled.cloud, keep);
  tree = std::make_unique<KdTree>(cloud.points);
  offset = std::make_unique<ObjectSurfaceTruth>(cloud);
}

std::int32_t SurfaceTruth::label_near(const Vec3d& world, double near) const {
  float d2 = 0.0f;
  const std::uint32_t i = tree->nearest_within((world - cloud.origin).cast<float>(), sq_dist_bound(near), &d2);
  return double(d2) <= near * near ? cloud.labels[i] : kLabelNone;
}

int SurfaceTruth::stone_of(const PointCloud& c, const Eigen::Isometry3d& E, double near, std::size_t stones,
                           double* share) const {
  std::vector<int> votes(stones, 0);
  for (std::size_t i = 0; i < c.size(); ++i) {
    const std::int32_t l = label_near(E * c.world(i), near);
    if (l >= 0 && std::size_t(l) < votes.size()) ++votes[std::size_t(l)];
  }
  const auto best = std::max_element(votes.begin(), votes.end());
  if (share) *share = best == votes.end() || c.empty() ? 0.0 : double(*best) / double(c.size());
  return best == votes.end() || 2 * *best < int(c.size()) ? -1 : int(best - votes.begin());
}

const PointCloud* nearest_cloud(const std::vector<PointCloud>& clouds, const Vec3d& c, double max_distance) {
  const PointCloud* best = nullptr;
  double best_d = max_distance;
  for (const PointCloud& o : clouds) {
    if (o.empty()) continue;
    const double d = (o.origin + centroid(o.points).cast<double>() - c).norm();
    if (d < best_d) best_d = d, best = &o;
  }
  return best;
}

ScanningMachine::ScanningMachine(const sim::SimulationConfig& config, std::uint64_t seed, double duration,
                                 const MappingConfig& mapping)
    : sim_(at_rest(config)), seed_(seed), world_(sim::make_world(sim_, seed)) {
  base_ = world_.excavator.T_world_base(0.0).translation();
  const sim::Excavator& ex = world_.excavator;
  state_ = sim::simulate_state_estimation([&ex](double t) { return ex.T_world_cabin(t); },
                                          [&ex](double t) { return ex.joints_at(t); }, ex.model(), 0.0, duration,
                                          sim_.state, seed);
  schedule_ = sim::sweep_schedule(sim_.lidar, duration, seed);
  MapperSetup setup{.robot = ex.model(), .T_cabin_sensor = {{"H", ex.T_cabin_H()}, {"V", ex.T_cabin_V()}}};
  mapper_ = std::make_unique<Mapper>(std::move(setup), mapping);
  mapper_->add_state_estimates(state_.estimate);
}

double ScanningMachine::joints_fed_until() const {
  return next_joints_ == 0 ? -INFINITY : state_.joints[next_joints_ - 1].time;
}

void ScanningMachine::feed_joints(double t_to) {
  // The encoder noise was drawn with the state estimate; the arm is read as commanded by now (a
  // grasp moves it after the state estimate was simulated).
  const double dt = 1.0 / sim_.state.rate;
  for (; next_joints_ < state_.joints.size() && state_.joints[next_joints_].time <= t_to + 2.0 * dt; ++next_joints_) {
    const JointState& drawn = state_.joints[next_joints_];
    const JointState& was = state_.joints_truth[next_joints_];
    JointState truth = world_.excavator.joints_at(drawn.time);
    JointState measured = truth;
    for (std::size_t j = 0; j < measured.names.size(); ++j) {
      const std::string& name = measured.names[j];
      const double before = was.get(name);  // unchanged joints keep their reading bit for bit
      measured.positions[j] = measured.positions[j] == before ? drawn.get(name)
                                                              : measured.positions[j] + (drawn.get(name) - before);
    }
    mapper_->add_joint_state(measured);
    state_.joints_truth[next_joints_] = std::move(truth);
    state_.joints[next_joints_] = std::move(measured);
  }
}

void ScanningMachine::scan(double t_from, double t_to) {
  const double period = 1.0 / sim_.lidar.rate;
  feed_joints(t_to);
  while (next_ < schedule_.size() && schedule_[next_].t_start < t_from) ++next_;  // busy carrying
  for (; next_ < schedule_.size() && schedule_[next_].t_start + period <= t_to; ++next_) {
    const sim::Sweep sweep = sim::simulate_scheduled_sweep(world_, sim_.lidar, schedule_[next_], seed_);
    PointCloud cloud;
    cloud.points = sweep.points;
    cloud.times = sweep.times;
    mapper_->add_sweep(sweep.sensor, cloud, sweep.t_start, sweep.t_end);
  }
  now_ = t_to;
}

Eigen::Isometry3d ScanningMachine::E_state(double t) const {
  return interpolate_pose(state_.truth, t) * interpolate_pose(state_.estimate, t).inverse();
}

}  // namespace cairn::eval
