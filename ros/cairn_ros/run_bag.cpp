#include "cairn_ros/run_bag.hpp"

#include <algorithm>
#include <nlohmann/json.hpp>

#include "cairn/core/error.hpp"
#include "cairn/core/io/io.hpp"
#include "cairn_ros/bag_file.hpp"
#include "cairn_ros/convert.hpp"

namespace cairn::bag {
namespace {

/// A sweep as the Velodyne driver publishes it: sensor-frame points, per-point time relative to
/// the stamp (the sweep's start), ring.
file::Cloud sweep_of(const PointCloud& c, double t_start, const std::string& frame) {
  file::Cloud s;
  s.stamp = t_start;
  s.frame = frame;
  const ScalarField* ring = c.field("ring");
  s.xyz.reserve(3 * c.size());
  for (std::size_t i = 0; i < c.size(); ++i) {
    const Vec3f p = (c.origin + c.points[i].cast<double>()).cast<float>();
    s.xyz.insert(s.xyz.end(), {p.x(), p.y(), p.z()});
    s.time.push_back(float(c.times[i] - t_start));  // the stamp is stored to the nanosecond
    s.ring.push_back(ring ? std::uint16_t(ring->values[i]) : std::uint16_t{0});
  }
  return s;
}

double median_spacing(std::vector<double> stamps) {
  if (stamps.size() < 2) return 0.0;
  std::sort(stamps.begin(), stamps.end());
  std::vector<double> d;
  for (std::size_t i = 1; i < stamps.size(); ++i) d.push_back(stamps[i] - stamps[i - 1]);
  std::nth_element(d.begin(), d.begin() + std::ptrdiff_t(d.size() / 2), d.end());
  return d[d.size() / 2];
}

}  // namespace

BagWriteSummary write_run_bag(const io::RunDirectory& run, const std::filesystem::path& bag, const io::BagTopics& topics) {
  file::Writer w(bag.string());
  const double t0 = run.state_estimate.front().time;
  w.text(topics.robot_model, t0, to_json(run.robot).dump(), /*latched=*/true);
  std::vector<file::FrameTransform> statics;
  for (const auto& [sensor, T] : run.T_cabin_sensor) statics.push_back({topics.cabin_frame, topics.lidar_frame(sensor), to_file(T)});
  w.transforms("/tf_static", t0, statics, /*latched=*/true);
  for (const StampedPose& p : run.state_estimate) {
    w.odometry(topics.odometry, p.time, topics.world_frame, topics.cabin_frame, to_file(p.pose));
    w.transforms("/tf", p.time, {{topics.world_frame, topics.cabin_frame, to_file(p.pose)}});
  }
  for (const JointState& j : run.joint_states) w.joints(topics.joint_states, j.time, j.names, j.positions);
  for (const io::ScanInfo& scan : run.scans)
    w.cloud(topics.lidar_topic(scan.sensor), sweep_of(run.read_scan(scan), scan.t_start, topics.lidar_frame(scan.sensor)));
  if (!run.drone_cloud.empty()) w.cloud(topics.drone_cloud, cloud_of(io::load_cloud(run.drone_cloud), run.duration, topics.drone_frame));
  w.close();
  return {.messages = w.messages()};
}

namespace {

/// One message of the first pass into `run`.
void take(BagRun& run, const file::Message& m, const io::BagTopics& topics, std::map<std::string, std::vector<double>>& stamps,
          bool& has_robot) {
  const std::string what = run.file.string() + ": " + m.topic;
  using K = file::Message::Kind;
  if (m.topic == topics.lidar_h || m.topic == topics.lidar_v) {
    if (m.kind != K::cloud) throw InputError(what + " is not sensor_msgs/PointCloud2");
    stamps[m.topic == topics.lidar_h ? "H" : "V"].push_back(m.stamp);
  } else if (m.topic == topics.drone_cloud) {
    run.has_drone_cloud = m.kind == K::cloud;
  } else if (m.topic == topics.robot_model && m.kind == K::text) {
    try {
      run.robot = robot_from_json(nlohmann::json::parse(m.text));
    } catch (const std::exception& e) {
      throw InputError(what + ": " + e.what());
    }
    has_robot = true;
  } else if (m.topic == "/tf_static" && m.kind == K::transforms) {
    for (const file::FrameTransform& f : m.transforms)
      if (f.parent == topics.cabin_frame && f.child == topics.lidar_h_frame) run.T_cabin_sensor["H"] = from_file(f.T);
      else if (f.parent == topics.cabin_frame && f.child == topics.lidar_v_frame) run.T_cabin_sensor["V"] = from_file(f.T);
  } else if (m.topic == topics.odometry && m.kind == K::odometry) {
    run.state_estimate.push_back({.time = m.stamp, .pose = from_file(m.pose)});
  } else if (m.topic == topics.joint_states && m.kind == K::joints) {
    run.joint_states.push_back({.time = m.stamp, .names = m.names, .positions = m.positions});
  } else {
    throw InputError(what + " has an unexpected message type (" + m.type + ")");
  }
}

}  // namespace

BagRun open_run_bag(const std::filesystem::path& bag, const io::BagTopics& topics) {
  if (!std::filesystem::is_regular_file(bag)) throw InputError(bag.string() + ": bag not found");
  BagRun run;
  run.file = bag;
  std::map<std::string, std::vector<double>> stamps;
  bool has_robot = false;
  file::Reader reader(bag.string(), {topics.robot_model, "/tf_static", topics.odometry, topics.joint_states, topics.lidar_h,
                                     topics.lidar_v, topics.drone_cloud},
                      /*decode_clouds=*/false);
  for (file::Message m; reader.next(m);) take(run, m, topics, stamps, has_robot);
  if (!has_robot) throw InputError(bag.string() + ": no robot model on " + topics.robot_model);
  if (run.state_estimate.empty()) throw InputError(bag.string() + ": no state estimate on " + topics.odometry);
  if (stamps.empty()) throw InputError(bag.string() + ": no sweeps on " + topics.lidar_h + " or " + topics.lidar_v);
  for (const auto& [sensor, t] : stamps) {
    if (!run.T_cabin_sensor.contains(sensor))
      throw InputError(bag.string() + ": no /tf_static " + topics.cabin_frame + " -> " + topics.lidar_frame(sensor));
    run.sweeps[sensor] = t.size();
    run.sweep_period[sensor] = median_spacing(t);
  }
  const auto by_time = [](const auto& a, const auto& b) { return a.time < b.time; };
  std::stable_sort(run.state_estimate.begin(), run.state_estimate.end(), by_time);
  std::stable_sort(run.joint_states.begin(), run.joint_states.end(), by_time);
  return run;
}

SweepSource bag_sweeps(const BagRun& run, const io::BagTopics& topics) {
  auto reader = std::make_shared<file::Reader>(run.file.string(), std::vector<std::string>{topics.lidar_h, topics.lidar_v},
                                               /*decode_clouds=*/true);
  return [reader, path = run.file, period = run.sweep_period, lidar_h = topics.lidar_h](RecordedSweep& out) {
    file::Message m;
    if (!reader->next(m)) return false;
    std::string what = path.string();  // step by step: GCC 12's -Wrestrict misfires on a + b + c
    what += ": ";
    what += m.topic;
    if (m.kind != file::Message::Kind::cloud) throw InputError(what + " is not sensor_msgs/PointCloud2");
    const std::string sensor = m.topic == lidar_h ? "H" : "V";
    out = sweep_from(m.cloud, sensor, period.at(sensor), what);
    return true;
  };
}

PointCloud bag_drone_cloud(const BagRun& run, const io::BagTopics& topics) {
  file::Reader reader(run.file.string(), {topics.drone_cloud}, /*decode_clouds=*/true);
  for (file::Message m; reader.next(m);)
    if (m.kind == file::Message::Kind::cloud) return points_of(m.cloud);
  throw InputError(run.file.string() + ": no drone cloud on " + topics.drone_cloud);
}

MapRunResult map_bag(const BagRun& run, const MappingConfig& config, const MappingProgress& progress,
                     const io::BagTopics& topics) {
  std::size_t sweeps = 0;
  for (const auto& [sensor, n] : run.sweeps) sweeps += n;
  const MapRunInputs inputs{.robot = run.robot, .T_cabin_sensor = run.T_cabin_sensor,
                            .state_estimate = run.state_estimate, .joint_states = run.joint_states,
                            .num_sweeps = sweeps, .name = run.file.string()};
  return map_sweeps(inputs, bag_sweeps(run, topics), config, progress);
}

}  // namespace cairn::bag
