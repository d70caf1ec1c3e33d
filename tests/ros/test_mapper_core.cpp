// The cairn_mapper node's core without ROS (ros/cairn_ros/mapper_core.hpp): the bag's messages fed
// one by one in their recorded order, as `rosbag play` delivers them, map like `map_bag`; sweeps
// wait for the state estimate that covers them; bad messages are InputErrors.
#include "cairn_ros/mapper_core.hpp"

#include <gtest/gtest.h>

#include "cairn/core/error.hpp"
#include "cairn_ros/convert.hpp"
#include "cairn_ros/run_bag.hpp"
#include "support/shared_runs.hpp"

namespace cairn::bag {
namespace {

namespace fs = std::filesystem;

/// Feeds every message of `bag` into `core` in the bag's order.
void play(const fs::path& bag, MapperCore& core) {
  const io::BagTopics& t = core.topics();
  file::Reader reader(bag.string(), {t.robot_model, "/tf_static", t.odometry, t.joint_states, t.lidar_h, t.lidar_v}, true);
  using K = file::Message::Kind;
  for (file::Message m; reader.next(m);) {
    if (m.kind == K::text) core.set_robot_model(m.text);
    if (m.kind == K::transforms)
      for (const file::FrameTransform& f : m.transforms) core.set_transform(f.parent, f.child, f.T);
    if (m.kind == K::odometry) core.add_state(m.stamp, m.pose);
    if (m.kind == K::joints) core.add_joints(m.stamp, m.names, m.positions);
    if (m.kind == K::cloud) core.add_sweep(m.topic, m.cloud);
  }
}

TEST(MapperCore, MessagesInRecordedOrderMapLikeTheBag) {
  const fs::path dir = test::temp_dir("mapper_core");
  io::RunDirectory run = io::open_run_directory(test::shared_run(test::kExp1Drone8s) / "run");
  test::shorten_under_sanitizers(run, 3.0);  // the same comparison on 3 s of scans
  (void)write_run_bag(run, dir / "run.bag");
  MapperCore core("", {}, 0.1);
  play(dir / "run.bag", core);
  const MapperStatus before = core.status();
  EXPECT_TRUE(before.started);
  EXPECT_EQ(before.sweeps_received, run.scans.size());
  EXPECT_LE(before.sweeps_waiting, 2u);  // the last sweeps' ends lie beyond the last state estimate
  core.finish();
  EXPECT_EQ(core.status().sweeps_mapped, run.scans.size());
  const MapRunResult reference = map_bag(open_run_bag(dir / "run.bag"));
  const auto trajectory = core.trajectory();
  ASSERT_EQ(trajectory.size(), reference.trajectory.size());
  double worst = 0.0;
  for (std::size_t i = 0; i < trajectory.size(); ++i)
    worst = std::max(worst, (from_file(trajectory[i].second).translation() - reference.trajectory[i].pose.translation()).norm());
  EXPECT_LT(worst, 1e-6) << "the same inputs, another interleaving";
  const file::Cloud map = core.map();
  EXPECT_NEAR(double(map.xyz.size() / 3) / double(reference.map.size()), 1.0, 1e-3);
  const file::Transform c = core.map_correction();
  EXPECT_LT(std::abs(c.t[0]) + std::abs(c.t[1]) + std::abs(c.t[2]), 0.5);  // a correction of centimetres
}

TEST(MapperCore, SweepsWaitForTheStateEstimateThatCoversThem) {
  const io::RunDirectory run = io::open_run_directory(test::shared_run(test::kExp1Drone8s) / "run");
  MapperCore core("", {"mapping.self_filter.enabled=false"}, 0.1);
  const io::ScanInfo& scan = run.scans.at(4);
  const PointCloud c = run.read_scan(scan);
  file::Cloud sweep;
  sweep.stamp = scan.t_start;
  for (std::size_t i = 0; i < c.size(); ++i) {
    sweep.xyz.insert(sweep.xyz.end(), {c.points[i].x(), c.points[i].y(), c.points[i].z()});
    sweep.time.push_back(float(c.times[i] - scan.t_start));
    sweep.ring.push_back(std::uint16_t(c.field("ring")->values[i]));
  }
  const io::BagTopics& t = core.topics();
  core.add_sweep(scan.sensor == "H" ? t.lidar_h : t.lidar_v, sweep);
  EXPECT_FALSE(core.status().started);  // no robot model, no extrinsics yet
  core.set_robot_model(to_json(run.robot).dump());
  for (const auto& [sensor, T] : run.T_cabin_sensor) core.set_transform(t.cabin_frame, t.lidar_frame(sensor), to_file(T));
  for (const StampedPose& p : run.state_estimate) {
    if (p.time > scan.t_start + 0.05) break;
    core.add_state(p.time, to_file(p.pose));
  }
  EXPECT_TRUE(core.status().started);
  EXPECT_EQ(core.status().sweeps_waiting, 1u);  // its end is not covered yet
  for (const StampedPose& p : run.state_estimate)
    if (p.time <= scan.t_end + 0.1) core.add_state(p.time, to_file(p.pose));
  EXPECT_EQ(core.status().sweeps_mapped, 1u);
  // Bad input: not a LiDAR topic, a sweep without per-point times, bad settings.
  EXPECT_THROW(core.add_sweep("/elsewhere", sweep), InputError);
  file::Cloud untimed = sweep;
  untimed.time.clear();
  EXPECT_THROW(core.add_sweep(t.lidar_h, untimed), InputError);
  EXPECT_THROW(MapperCore("", {"mapping.nonexistent=1"}, 0.1), ConfigError);
  EXPECT_THROW(MapperCore("", {}, 0.0), ConfigError);
  MapperCore empty("", {}, 0.1);
  EXPECT_THROW(empty.finish(), InputError);
}

}  // namespace
}  // namespace cairn::bag
