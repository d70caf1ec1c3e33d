#pragma once
// Configuration of the LiDAR mapping stage (Sec. 4.2). Defaults: Table 3 where the paper gives a
// value (m, d_poses, R_map, res_voxel, n_min), measured choices otherwise (docs/mapping.md).
#include "cairn/core/voxel_grid.hpp"
#include "cairn/registration/icp.hpp"

namespace cairn {

struct SelfFilterConfig {
  bool enabled = true;
  double padding = 0.15;  // [m] the robot's shapes are grown by this margin
  int time_slots = 10;    // link poses per sweep (the cabin swings while the sensor spins)

  template <class V>
  void visit(V& v) {
    v("enabled", enabled, "remove points on the robot's own links (Sec. 4.2, step 1)");
    v("padding", padding, "[m] margin added to every link shape");
    v("time_slots", time_slots, "link poses evaluated per sweep (joint motion during a sweep)");
  }
};

struct DeskewConfig {
  bool enabled = true;  // false: one pose per sweep (its mid time) instead of one per point
  double slot = 0.0005;  // [s] pose lookup resolution inside a sweep

  template <class V>
  void visit(V& v) {
    v("enabled", enabled, "motion-correct every point at its own timestamp (false: one pose per sweep)");
    v("slot", slot, "[s] time resolution of the per-point pose lookup");
  }
};

struct ScanMatchingConfig {
  bool enabled = true;
  double source_voxel = 0.15;  // [m] scan pair downsampled before ICP (raw rings bias ICP)
  double submap_voxel = 0.12;  // [m] submap downsampled before normals + kd-tree
  int normal_k = 30;           // PCA normals of the submap (fewer: noisy normals bias x/y)
  int submap_every = 5;        // nodes between submap rebuilds (a submap = the last m pairs then)
  int submap_latency = 2;      // a submap built after node n is used from node n + latency on
                               // (built in the background meanwhile; 1 = by the next node)
  bool loop_closures = true;   // also match against older submaps seen from the same place
  double loop_min_age = 4.0;   // [s] older than this
  double loop_radius = 0.3;    // [m] sensor positions closer than this
  double loop_max_angle_deg = 10.0;  // [deg] and orientations closer than this
  IcpConfig icp{.objective = "point_to_plane", .kernel = "huber", .kernel_scale = 0.05,
                .max_correspondence_distance = 0.3, .max_iterations = 10};  // from a cm-accurate guess
  double min_fitness = 0.3;         // fewer inliers per source point: no scan-matching edge
  double max_correction = 0.25;     // [m] ICP moving the initial guess farther: rejected
  double max_correction_deg = 2.0;  // [deg] likewise for the rotation
  double residual_sigma = 0.03;     // [m] information = Hessian / sigma^2 * info_scale
  double info_scale = 0.02;         // neighbouring ICP residuals are correlated: discount
  double loop_info_scale = 0.3;     // the same for loop-closure edges (full overlap: more reliable)
  bool sequential_edges = true;     // false: the scan-to-submap ICP only gives the initial node pose
  double min_sigma_translation = 0.002;  // [m] information capped at this standard deviation
  double min_sigma_rotation_deg = 0.02;  // [deg]

  template <class V>
  void visit(V& v) {
    v("enabled", enabled, "scan-to-submap ICP constraints (Sec. 4.2, step 3)");
    v("source_voxel", source_voxel, "[m] voxel size of the scan pair before ICP");
    v("submap_voxel", submap_voxel, "[m] voxel size of the submap");
    v("normal_k", normal_k, "neighbours for the submap's PCA normals");
    v("submap_every", submap_every, "nodes between submap rebuilds");
    v("submap_latency", submap_latency, "nodes after its build until a submap is used (built in the background)");
    v("loop_closures", loop_closures, "also match each pair against an older submap seen from the same place");
    v("loop_min_age", loop_min_age, "[s] minimum age of a loop-closure submap");
    v("loop_radius", loop_radius, "[m] max. sensor distance to a loop-closure submap's pose");
    v("loop_max_angle_deg", loop_max_angle_deg, "[deg] max. rotation to a loop-closure submap's pose");
    v("icp", icp, "ICP settings");
    v("min_fitness", min_fitness, "minimum inlier share for a scan-matching edge");
    v("max_correction", max_correction, "[m] larger ICP corrections of the initial guess are rejected");
    v("max_correction_deg", max_correction_deg, "[deg] larger ICP rotation corrections are rejected");
    v("residual_sigma", residual_sigma, "[m] residual sigma turning the ICP Hessian into information");
    v("info_scale", info_scale, "factor on the ICP information (correlated residuals)");
    v("loop_info_scale", loop_info_scale, "factor on the ICP information of loop-closure edges");
    v("sequential_edges", sequential_edges, "add the scan-to-submap ICP of consecutive pairs as graph edges");
    v("min_sigma_translation", min_sigma_translation, "[m] cap of the ICP information (translation)");
    v("min_sigma_rotation_deg", min_sigma_rotation_deg, "[deg] cap of the ICP information (rotation)");
  }
};

struct PoseGraphConfig {
  // Odometry edges (state estimation between consecutive nodes): sigma = base + rate * dt.
  double odometry_sigma_translation = 0.001;   // [m]
  double odometry_translation_rate = 0.03;     // [m/s] GNSS error velocity (~2 cm/s, smooth)
  double odometry_sigma_rotation_deg = 0.01;   // [deg]
  double odometry_rotation_rate_deg = 0.05;    // [deg/s]
  // Absolute priors (GNSS/INS state estimate) on every node: weak, their errors are correlated.
  bool priors = true;
  double prior_sigma_translation = 0.03;    // [m]
  double prior_sigma_roll_pitch_deg = 0.1;  // [deg]
  double prior_sigma_yaw_deg = 0.2;         // [deg]
  int window = 30;              // nodes optimised after each new node (incremental)
  int window_iterations = 5;
  int final_iterations = 30;    // full optimisation in finish()

  template <class V>
  void visit(V& v) {
    v("odometry_sigma_translation", odometry_sigma_translation, "[m] odometry edge sigma (constant part)");
    v("odometry_translation_rate", odometry_translation_rate, "[m/s] odometry sigma growth with the time gap");
    v("odometry_sigma_rotation_deg", odometry_sigma_rotation_deg, "[deg] odometry edge sigma (constant part)");
    v("odometry_rotation_rate_deg", odometry_rotation_rate_deg, "[deg/s] odometry sigma growth with the time gap");
    v("priors", priors, "absolute priors from the state estimate on every node");
    v("prior_sigma_translation", prior_sigma_translation, "[m] absolute prior sigma per axis");
    v("prior_sigma_roll_pitch_deg", prior_sigma_roll_pitch_deg, "[deg] absolute prior sigma, roll and pitch");
    v("prior_sigma_yaw_deg", prior_sigma_yaw_deg, "[deg] absolute prior sigma, yaw");
    v("window", window, "newest nodes optimised after each new node");
    v("window_iterations", window_iterations, "solver iterations per incremental update");
    v("final_iterations", final_iterations, "solver iterations of the final full optimisation");
  }
};

struct LocalMapConfig {
  double R_map = 10.0;  // Table 3: local map radius [m] (cylinder around the cabin's axis)
  VoxelGridConfig voxel;  // Table 3: res_voxel = 3 cm, n_min = 1
  int crop_every = 50;  // nodes between crops of the cylinder
  // Deviation (docs/mapping.md): snapshots move every voxel centroid onto the moving-least-squares
  // surface of its neighbours within this radius (where they form a surface), then re-voxelise.
  // With n_min = 1 the raw voxel grid keeps the sensor's range noise (VLP-16: 3 cm) as a thick
  // shell. 0 = the paper's plain voxel grid.
  double smoothing_radius = 0.15;  // [m]
  double smoothing_max_curvature = 0.3;  // neighbourhoods less planar than this are left as they are
  bool smoothing_quadratic = true;  // quadratic height field over the local plane (false: the plane)
  // One surface is fitted per cube of this side (around the mean of its points) and used for all
  // of them: 4x faster than one fit per point at the same accuracy (docs/mapping.md). 0: per point.
  double smoothing_block = 0.06;  // [m]

  template <class V>
  void visit(V& v) {
    v("R_map", R_map, "[m] radius of the robot-centric map cylinder (Table 3)");
    v("voxel", voxel, "voxel grid of the map (Table 3)");
    v("crop_every", crop_every, "nodes between two crops of the map cylinder");
    v("smoothing_radius", smoothing_radius, "[m] snapshot: move points onto the local MLS surface of this radius (0: off)");
    v("smoothing_max_curvature", smoothing_max_curvature, "snapshot: only where the curvature is below this");
    v("smoothing_quadratic", smoothing_quadratic, "snapshot: fit a quadratic height field (false: a plane)");
    v("smoothing_block", smoothing_block, "[m] snapshot: one fitted surface per cube of this side (0: per point)");
  }
};

struct MappingConfig {
  int m = 10;             // Table 3: scan pairs in the ICP submap
  double d_poses = 0.01;  // Table 3: min. distance between poses [m]
  double max_pair_gap = 0.15;  // [s] H and V sweeps farther apart are not assembled into one pair
  SelfFilterConfig self_filter;
  DeskewConfig deskew;
  ScanMatchingConfig scan_matching;
  PoseGraphConfig pose_graph;
  LocalMapConfig local_map;
  bool rebuild_on_finish = true;  // finish(): re-insert every node with its final pose

  template <class V>
  void visit(V& v) {
    v("m", m, "scan pairs in the scan-matching submap (Table 3)");
    v("d_poses", d_poses, "[m] min. sensor motion for a new pose-graph node (Table 3)");
    v("max_pair_gap", max_pair_gap, "[s] max. time between the H and V sweeps of a scan pair");
    v("self_filter", self_filter, "self-filter (Sec. 4.2, step 1)");
    v("deskew", deskew, "scan pair assembly with motion correction (Sec. 4.2, step 2)");
    v("scan_matching", scan_matching, "scan-to-submap ICP (Sec. 4.2, step 3)");
    v("pose_graph", pose_graph, "pose graph (Sec. 4.2, Eq. 1)");
    v("local_map", local_map, "robot-centric voxel map (Sec. 4.2)");
    v("rebuild_on_finish", rebuild_on_finish, "rebuild the map from the final poses at the end");
  }

  /// Throws ConfigError naming the key of the first invalid value.
  void validate() const;
};

}  // namespace cairn
