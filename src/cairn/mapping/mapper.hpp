#pragma once
// The LiDAR mapping stage (Sec. 4.2), streaming: sweeps of the two LiDARs go in one at a time
// (after the state estimate and joint states covering them), a robot-centric voxel map and the
// optimised trajectory come out at any time.
//
//   add_sweep ─► self-filter ─► scan pair assembly + de-skew ─► node? (moved > d_poses)
//              ─► scan-to-submap ICP (last m pairs) ─► pose graph (odometry, scan matching,
//                 weak GNSS priors; windowed Ceres update) ─► local map (R_map, res_voxel)
//
// Graph nodes are T_world_H (the horizontal LiDAR, the frame of the assembled pairs);
// trajectory() reports T_world_cabin = T_world_H T_cabin_H^-1.
#include <Eigen/Geometry>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <tbb/task_group.h>

#include "cairn/core/io/run_dir.hpp"
#include "cairn/core/log.hpp"
#include "cairn/core/point_cloud.hpp"
#include "cairn/core/robot_model.hpp"
#include "cairn/core/transform.hpp"
#include "cairn/mapping/config.hpp"
#include "cairn/mapping/local_map.hpp"
#include "cairn/mapping/pose_graph.hpp"
#include "cairn/mapping/scan_pair.hpp"
#include "cairn/registration/icp.hpp"

namespace cairn {

/// Fixed inputs of a mapping session.
struct MapperSetup {
  RobotModel robot;                                         // for the self-filter ("cabin" link)
  std::map<std::string, Eigen::Isometry3d> T_cabin_sensor;  // "H" and "V" (V optional)
};

struct MapperStats {
  std::size_t sweeps = 0, empty_sweeps = 0, pairs = 0, single_sweep_pairs = 0;
  std::size_t nodes = 0, skipped_pairs = 0;  // skipped: moved less than d_poses
  std::size_t scan_edges = 0, loop_edges = 0, icp_rejected = 0, submaps = 0;
  std::size_t points_in = 0, points_self_filtered = 0, points_non_finite = 0;
  std::size_t time_gaps = 0;  // sweeps starting > 1.5 periods after the previous one
};

class Mapper {
 public:
  /// Throws ConfigError on an invalid config, InputError when the H extrinsic is missing.
  Mapper(MapperSetup setup, MappingConfig config = {});
  ~Mapper();
  Mapper(const Mapper&) = delete;
  Mapper& operator=(const Mapper&) = delete;

  // ---- inputs (state estimate and joint states must cover a sweep before it is added) ------
  void add_state_estimate(const StampedPose& T_world_cabin);  // increasing times
  void add_state_estimates(const std::vector<StampedPose>& poses);
  void add_joint_state(const JointState& q);
  void add_joint_states(const std::vector<JointState>& states);
  /// One revolution of sensor "H" or "V": points in the sensor frame, absolute per-point times.
  /// Empty sweeps are counted and skipped with a warning; NaN points are dropped. Throws
  /// InputError on an unknown sensor or attribute arrays that do not match the points.
  void add_sweep(const std::string& sensor, const PointCloud& cloud, double t_start, double t_end);
  /// Processes a pending lone sweep (end of input).
  void flush();
  /// flush(), full optimisation, and (config.rebuild_on_finish) the map rebuilt from final poses.
  void finish();
  /// Full optimisation of every node (not only the newest window) and the map rebuilt from the
  /// new poses, mid-stream: the map's absolute frame follows the mean of all GNSS/INS priors so
  /// far instead of staying where the first window's priors put it. remove_sphere / insert edits
  /// are replayed moved with the node that was newest when they were made.
  void reoptimize();

  // ---- what the robot holds (Sec. 4.5) --------------------------------------------------------
  /// From time t on, `shape` is fixed to the robot's link `link` (a grasped object, in the
  /// gripper frame): the self-filter removes the points inside it, padded like the links, until
  /// detach. Sec. 4.5: "the self-filter ... will prevent the object from being remapped as long
  /// as it lies inside the gripper". InputError for an unknown link or a non-finite time.
  void attach(const std::string& link, const Shape& shape, double t);
  /// Ends every attachment at time t (the object released).
  void detach(double t);

  // ---- outputs ------------------------------------------------------------------------------
  [[nodiscard]] PointCloud map() const {
    background_->wait();  // the last node's map update
    return map_.snapshot();
  }
  /// Optimised T_world_cabin of every node, by time.
  [[nodiscard]] std::vector<StampedPose> trajectory() const;
  /// The state estimate at the node times (what the graph started from).
  [[nodiscard]] std::vector<StampedPose> raw_trajectory() const;
  /// Latest optimised T_world_cabin (identity before the first node).
  [[nodiscard]] Eigen::Isometry3d current_pose() const;
  [[nodiscard]] const MapperStats& stats() const { return stats_; }
  [[nodiscard]] const Timings& timings() const { return timings_; }
  [[nodiscard]] const PoseGraph& graph() const { return graph_; }
  [[nodiscard]] const MappingConfig& config() const { return config_; }

  // ---- edits by other stages (recorded, so a rebuild replays them) ---------------------------
  /// Removes map points within `radius` of `center` (grasped object, Sec. 5: R_obj).
  std::size_t remove_sphere(const Vec3d& center, double radius);
  /// Inserts world points (cloud.origin + point).
  void insert(const PointCloud& points);
  /// Applies any map edit (e.g. an object's own voxels removed, Sec. 4.5); returns the number of
  /// voxels removed. Throws InputError on an invalid edit.
  std::size_t apply_edit(const MapEdit& edit);

 private:
  struct Pending {
    PointCloud cloud;
    std::vector<std::uint32_t> keep;
    double t_start = 0, t_end = 0;
  };
  struct Node {
    double time = 0;
    Eigen::Isometry3d T_world_H_raw;  // state estimate
    std::vector<Vec3f> map_points;    // H frame, voxel-downsampled at res_voxel
    std::vector<Vec3f> submap_points; // H frame, downsampled at submap_voxel
  };
  struct Submap {  // a prepared ICP target: the last m pairs around node `center` at build time
    std::size_t center = 0;
    double time = 0;
    Eigen::Isometry3d T_world_center;  // node pose when the submap was built
    Vec3d anchor;                      // target points are relative to this world position
    std::shared_ptr<const IcpTarget> target;
  };
  /// A map edit, made in the map as it stood after node after_node - 1 (whose pose then was
  /// T_world_anchor): a rebuild moves it with that node, as the scans around it move.
  struct Edit {
    std::size_t after_node = 0;
    MapEdit edit;
    Eigen::Isometry3d T_world_anchor = Eigen::Isometry3d::Identity();
  };
  /// The edit's anchor-node motion since it was made (identity before the first node).
  [[nodiscard]] Eigen::Isometry3d edit_motion(const Edit& e) const;
  void record_edit(Edit e);

  void process_pair(const Pending* h, const Pending* v);
  void add_node(ScanPair pair, const Eigen::Isometry3d& T_world_H_raw);
  /// Starts building a submap from the last m nodes: the points are gathered here, the voxel
  /// filter, normals and kd-tree are built in the background (used from node `due` on).
  void start_submap();
  struct Match {
    std::size_t center = 0;
    bool loop = false;
    bool ok = false;  // accepted: z + information are set
    Eigen::Isometry3d z = Eigen::Isometry3d::Identity();  // T_center_new
    Matrix6d information = Matrix6d::Zero();
    double ms = 0.0;
  };
  /// ICP of the source against a submap; on success the relative pose z_center_new + information.
  [[nodiscard]] Match match_scan(const std::vector<Vec3f>& source, const Eigen::Isometry3d& T_init,
                                 const Submap& submap, bool loop) const;
  /// Waits for the previous node's map update and, once it is due (or `all`), the pending submap.
  void sync_background(bool all);
  [[nodiscard]] const Submap* find_loop_submap(const Eigen::Isometry3d& T_world_H, double time) const;
  void update_map(std::size_t node);
  /// The map from every node at its current pose, edits replayed; final_crop: then cropped to
  /// R_map around the newest node (else only the crops every crop_every nodes, as when streaming).
  void rebuild_map(bool final_crop);
  /// Full optimisation, then (rebuild) the map rebuilt; timed under the two names.
  void solve_all(const char* solve_timing, bool rebuild, bool final_crop, const char* rebuild_timing);
  [[nodiscard]] Eigen::Isometry3d T_world_cabin_estimate(double t) const;

  MappingConfig config_;
  MapperSetup setup_;
  Eigen::Isometry3d T_cabin_H_ = Eigen::Isometry3d::Identity();
  std::vector<StampedPose> state_;
  std::vector<JointState> joints_;
  struct Attachment {
    std::size_t link = 0;
    Shape shape;
    double t_from = 0, t_to = 0;
  };
  std::vector<Attachment> attached_;
  /// The robot as the self-filter sees it over [t0, t1]: with the shapes attached then.
  [[nodiscard]] const RobotModel& robot_during(double t0, double t1, RobotModel& buffer) const;
  std::optional<Pending> pending_h_, pending_v_;
  double last_sweep_start_[2] = {-1e300, -1e300};
  std::vector<Node> nodes_;
  PoseGraph graph_;
  LocalMap map_;
  std::vector<Edit> edits_;
  std::vector<Submap> submaps_;  // submaps_.back() is the current one
  MapperStats stats_;
  Timings timings_;
  // The previous node's map update and submap build run here while the next pair is assembled
  // (deterministic: everything that reads their results waits first).
  std::unique_ptr<tbb::task_group> background_ = std::make_unique<tbb::task_group>();
  std::unique_ptr<tbb::task_group> submap_task_ = std::make_unique<tbb::task_group>();
  std::optional<Submap> next_submap_;  // being built; used from node next_submap_due_ on
  std::size_t next_submap_due_ = 0;
  double background_map_ms_ = 0.0, background_submap_ms_ = 0.0;
};

/// Progress callback: (pairs done, pairs total).
using MappingProgress = std::function<void(std::size_t, std::size_t)>;

struct MapRunResult {
  PointCloud map;
  std::vector<StampedPose> trajectory;      // optimised T_world_cabin per node
  std::vector<StampedPose> raw_trajectory;  // state estimate at the same times
  MapperStats stats;
  Timings timings;
  double seconds = 0.0;
  double online_seconds = 0.0;  // streaming part only (reading sweeps .. last node), without finish()
};

/// One sweep as a source hands it over: points in the sensor frame, absolute per-point times,
/// the "ring" field.
struct RecordedSweep {
  std::string sensor;  // "H" or "V"
  PointCloud cloud;
  double t_start = 0.0, t_end = 0.0;  // [s]
};
/// Fills the next sweep in time order; false when none is left.
using SweepSource = std::function<bool(RecordedSweep&)>;

/// What mapping a recorded run needs besides its sweeps.
struct MapRunInputs {
  RobotModel robot;
  std::map<std::string, Eigen::Isometry3d> T_cabin_sensor;
  std::vector<StampedPose> state_estimate;  // T_world_cabin
  std::vector<JointState> joint_states;
  std::size_t num_sweeps = 0;  // for the progress
  std::string name;            // for messages
};

/// Maps a recorded run: every state estimate and joint state first, then the sweeps streamed
/// from `next` (a run directory's files, a rosbag, ...), then finish(). Throws InputError when
/// the source holds no sweep.
[[nodiscard]] MapRunResult map_sweeps(const MapRunInputs& inputs, const SweepSource& next,
                                      const MappingConfig& config = {}, const MappingProgress& progress = {});

/// Maps a whole run directory (sweeps in time order; unreadable sweeps are InputErrors).
[[nodiscard]] MapRunResult map_run(const io::RunDirectory& run, const MappingConfig& config = {},
                                   const MappingProgress& progress = {});

}  // namespace cairn
