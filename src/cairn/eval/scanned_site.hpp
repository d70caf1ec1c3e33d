#pragma once
// The simulated machine scanning one persistent world, shared by the experiments of the
// evaluation library: a settled site (the world at rest), the state estimate with its GNSS/INS
// error, both LiDARs' sweeps streamed into one Mapper, and the true surfaces for scoring.
#include <Eigen/Geometry>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "cairn/core/kdtree.hpp"
#include "cairn/eval/map_scoring.hpp"
#include "cairn/mapping/config.hpp"
#include "cairn/mapping/mapper.hpp"
#include "cairn/sim/simulation.hpp"

namespace cairn::eval {

/// [m] truth kept around the swing axis for scoring (R_map = 10 m + margin).
inline constexpr double kTruthRadius = 12.0;

/// Throws the ConfigError of sim::scenario_config (listing the known names) for the first
/// unknown scenario.
void require_scenarios(const std::vector<std::string>& scenarios);

/// The true surfaces at one moment: labelled points (-1 terrain, k stone k) within `radius` of
/// `base` (horizontally), a kd-tree over them, and the map-offset estimator.
struct SurfaceTruth {
  PointCloud cloud;
  std::unique_ptr<KdTree> tree;
  std::unique_ptr<ObjectSurfaceTruth> offset;
  SurfaceTruth(const sim::Site& site, const Vec3d& base, double radius, double spacing, std::uint64_t seed);
  /// Label of the nearest true surface within `near` of a world point, or kLabelNone.
  [[nodiscard]] std::int32_t label_near(const Vec3d& world, double near) const;
  /// The stone most of a map-frame cloud lies on (E: map -> world), or -1; the share in *share.
  [[nodiscard]] int stone_of(const PointCloud& cloud, const Eigen::Isometry3d& E, double near, std::size_t stones,
                             double* share = nullptr) const;
};

/// [m] A merged object's centroid lies this near the segment or object it grew from (the drone
/// adds the top and far side the LiDARs did not see, shifting the centroid by decimetres).
inline constexpr double kMergedNear = 0.5;

/// The non-empty cloud whose centroid lies nearest `centroid` and within `max_distance`, or
/// nullptr: the registration's merged object (LiDAR + drone) that holds a segment or object.
[[nodiscard]] const PointCloud* nearest_cloud(const std::vector<PointCloud>& clouds, const Vec3d& centroid,
                                              double max_distance);

/// One settled world (settle_in_physics forced on), its state estimate over [0, duration] and the
/// sweep schedule of both sensors, streamed into a Mapper on demand.
class ScanningMachine {
 public:
  ScanningMachine(const sim::SimulationConfig& config, std::uint64_t seed, double duration, const MappingConfig& mapping);
  /// Feeds the sweeps that start in [t_from, t_to) and end by t_to (earlier ones are skipped: the
  /// machine was busy), and the joint states up to t_to: the encoders read the arm as it was
  /// commanded by then (sim::hold_stone, sim::release_stone), with their noise.
  void scan(double t_from, double t_to);
  /// Estimate frame -> world at time t: where the machine's own state estimate puts what it
  /// commands (the map frame is the estimate's).
  [[nodiscard]] Eigen::Isometry3d E_state(double t) const;
  [[nodiscard]] Vec3d base() const { return base_; }
  /// Time of the last joint state given to the mapper (-inf before the first scan): an arm
  /// command must come after it, or the mapper keeps the readings of the arm before the command.
  [[nodiscard]] double joints_fed_until() const;
  [[nodiscard]] double now() const { return now_; }
  [[nodiscard]] const sim::SimulationConfig& config() const { return sim_; }
  [[nodiscard]] sim::SimulatedWorld& world() { return world_; }
  [[nodiscard]] const sim::SimulatedWorld& world() const { return world_; }
  [[nodiscard]] Mapper& mapper() { return *mapper_; }
  [[nodiscard]] const Mapper& mapper() const { return *mapper_; }
  /// The simulated state estimate and its truth (scoring only).
  [[nodiscard]] const sim::StateEstimate& state() const { return state_; }

 private:
  sim::SimulationConfig sim_;
  std::uint64_t seed_;
  sim::SimulatedWorld world_;
  sim::StateEstimate state_;
  std::vector<sim::SweepSchedule> schedule_;
  std::size_t next_ = 0;
  std::size_t next_joints_ = 0;  // the next state_.joints sample to feed (fed up to a scan's end)
  void feed_joints(double t_to);
  std::unique_ptr<Mapper> mapper_;
  Vec3d base_ = Vec3d::Zero();
  double now_ = 0.0;
};

}  // namespace cairn::eval
