#include "cairn_ros/mapper_core.hpp"

#include <deque>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>

#include "cairn/core/error.hpp"
#include "cairn/eval/app_config.hpp"
#include "cairn/mapping/mapper.hpp"
#include "cairn_ros/convert.hpp"

namespace cairn::bag {

struct MapperCore::Impl {
  AppConfig config;
  double sweep_period = 0.1;
  std::optional<RobotModel> robot;
  std::map<std::string, Eigen::Isometry3d> T_cabin_sensor;
  std::vector<StampedPose> states;  // until the Mapper exists
  std::vector<JointState> joints;
  double last_state = -1e300, last_joints = -1e300;
  std::deque<RecordedSweep> waiting;
  std::unique_ptr<Mapper> mapper;
  MapperStatus status;
  mutable std::mutex mutex;  // ROS callbacks and the publishing timer

  [[nodiscard]] bool covered(const RecordedSweep& s) const {
    return last_state >= s.t_end && (!config.mapping.self_filter.enabled || last_joints >= s.t_end);
  }

  /// Builds the Mapper when the first sweep is ready and the robot model and the extrinsics of
  /// every LiDAR seen so far are known (the Mapper takes its extrinsics once).
  void start() {
    if (mapper || !robot || !T_cabin_sensor.contains("H") || waiting.empty()) return;
    for (const RecordedSweep& s : waiting)
      if (!T_cabin_sensor.contains(s.sensor)) return;
    mapper = std::make_unique<Mapper>(MapperSetup{.robot = *robot, .T_cabin_sensor = T_cabin_sensor}, config.mapping);
    mapper->add_state_estimates(states);
    mapper->add_joint_states(joints);
    states.clear();
    joints.clear();
    status.started = true;
  }

  /// Maps the queued sweeps the state estimate covers (all of them when `all`).
  void drain(bool all) {
    start();
    if (!mapper) return;
    while (!waiting.empty() && (all || covered(waiting.front()))) {
      const RecordedSweep s = std::move(waiting.front());
      waiting.pop_front();  // before mapping: a bad sweep is reported once, never blocks the queue
      if (!T_cabin_sensor.contains(s.sensor))
        throw InputError("cairn_mapper: a " + s.sensor + " sweep but no extrinsic of that LiDAR when mapping started");
      mapper->add_sweep(s.sensor, s.cloud, s.t_start, s.t_end);
      ++status.sweeps_mapped;
    }
  }
};

MapperCore::MapperCore(const std::string& config_file, const std::vector<std::string>& overrides, double sweep_period)
    : impl_(std::make_unique<Impl>()) {
  impl_->config = load_app_config(AppConfig{}, config_file, overrides);
  impl_->config.mapping.validate();
  if (!(sweep_period > 0.0)) throw ConfigError("cairn_mapper: ~sweep_period must be positive");
  impl_->sweep_period = sweep_period;
}

MapperCore::~MapperCore() = default;

const io::BagTopics& MapperCore::topics() const { return impl_->config.bag; }

void MapperCore::set_robot_model(const std::string& robot_json) {
  const std::lock_guard lock(impl_->mutex);
  if (impl_->robot) return;  // latched and re-published: the first one counts
  try {
    impl_->robot = robot_from_json(nlohmann::json::parse(robot_json));
  } catch (const std::exception& e) {
    throw InputError(std::string("cairn_mapper: robot model: ") + e.what());
  }
}

void MapperCore::set_transform(const std::string& parent, const std::string& child, const file::Transform& T) {
  const std::lock_guard lock(impl_->mutex);
  const io::BagTopics& t = impl_->config.bag;
  if (parent != t.cabin_frame || impl_->mapper) return;
  if (child == t.lidar_h_frame) impl_->T_cabin_sensor["H"] = from_file(T);
  if (child == t.lidar_v_frame) impl_->T_cabin_sensor["V"] = from_file(T);
}

void MapperCore::add_state(double t, const file::Transform& T_world_cabin) {
  const std::lock_guard lock(impl_->mutex);
  Impl& s = *impl_;
  if (t <= s.last_state) return;  // out of order or repeated
  s.last_state = t;
  const StampedPose p{.time = t, .pose = from_file(T_world_cabin)};
  if (s.mapper) s.mapper->add_state_estimate(p);
  else s.states.push_back(p);
  s.drain(false);
}

void MapperCore::add_joints(double t, const std::vector<std::string>& names, const std::vector<double>& positions) {
  const std::lock_guard lock(impl_->mutex);
  Impl& s = *impl_;
  if (t <= s.last_joints) return;
  if (names.size() != positions.size()) throw InputError("cairn_mapper: joint states with as many positions as names expected");
  s.last_joints = t;
  const JointState q{.time = t, .names = names, .positions = positions};
  if (s.mapper) s.mapper->add_joint_state(q);
  else s.joints.push_back(q);
  s.drain(false);
}

void MapperCore::add_sweep(const std::string& topic, const file::Cloud& sweep) {
  const std::lock_guard lock(impl_->mutex);
  Impl& s = *impl_;
  const io::BagTopics& t = s.config.bag;
  if (topic != t.lidar_h && topic != t.lidar_v) throw InputError("cairn_mapper: " + topic + " is not a LiDAR topic");
  if (s.status.finished) throw InputError("cairn_mapper: a sweep after ~finish is not mapped");
  s.waiting.push_back(sweep_from(sweep, topic == t.lidar_h ? "H" : "V", s.sweep_period, "cairn_mapper: " + topic));
  ++s.status.sweeps_received;
  s.drain(false);
}

void MapperCore::finish() {
  const std::lock_guard lock(impl_->mutex);
  Impl& s = *impl_;
  if (s.status.finished) return;
  s.drain(true);
  if (!s.mapper) throw InputError("cairn_mapper: finish before any robot model, extrinsics and sweeps");
  s.mapper->finish();
  s.status.finished = true;
}

MapperStatus MapperCore::status() const {
  const std::lock_guard lock(impl_->mutex);
  MapperStatus st = impl_->status;
  st.sweeps_waiting = impl_->waiting.size();
  if (impl_->mapper) st.nodes = impl_->mapper->trajectory().size();
  return st;
}

std::size_t MapperCore::apply_edit(const file::MapEdit& edit) {
  const std::lock_guard lock(impl_->mutex);
  if (!impl_->mapper) throw InputError("cairn_mapper: a map edit before mapping started");
  const std::size_t removed = impl_->mapper->apply_edit(from_file(edit));
  ++impl_->status.edits;
  return removed;
}

file::Cloud MapperCore::map() const {
  const std::lock_guard lock(impl_->mutex);
  if (!impl_->mapper) return {};
  const std::vector<StampedPose> nodes = impl_->mapper->trajectory();
  return cloud_of(impl_->mapper->map(), nodes.empty() ? 0.0 : nodes.back().time, "");  // the run's clock: the newest node
}

std::vector<std::pair<double, file::Transform>> MapperCore::trajectory() const {
  const std::lock_guard lock(impl_->mutex);
  std::vector<std::pair<double, file::Transform>> out;
  if (!impl_->mapper) return out;
  for (const StampedPose& p : impl_->mapper->trajectory()) out.emplace_back(p.time, to_file(p.pose));
  return out;
}

file::Transform MapperCore::map_correction() const {
  const std::lock_guard lock(impl_->mutex);
  if (!impl_->mapper) return {};
  const std::vector<StampedPose> opt = impl_->mapper->trajectory(), raw = impl_->mapper->raw_trajectory();
  if (opt.empty() || raw.empty()) return {};
  return to_file(opt.back().pose * raw.back().pose.inverse());
}

}  // namespace cairn::bag
