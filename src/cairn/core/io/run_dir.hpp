#pragma once
// Run directories: what `cairn simulate` writes and `cairn map` reads (and, later, what a logger
// on the real machine writes). Layout (docs/run-directory.md):
//
//   run.json                 metadata: format version, scenario, seed, duration, sensors, config
//   robot.json               kinematic tree + collision shapes of the machine (RobotModel)
//   extrinsics.json          T_cabin_H, T_cabin_V, T_H_V (4×4 row-major)
//   scans/index.csv          sensor,index,t_start,t_end,num_points,file
//   scans/H/000000.ply ...   one revolution per file, sensor frame, per point: x y z time ring
//   state/cabin_poses.tum    state estimate T_world_cabin (TUM format), 100 Hz
//   state/joint_states.csv   time + one column per joint (encoder readings)
//   drone/cloud.ply          photogrammetry cloud in the SfM frame
//   drone/sparse/            COLMAP text model (cameras.txt, images.txt, points3D.txt)
//   drone/vins_trajectory.tum camera positions from visual-inertial odometry (metric)
//   truth/...                ground truth (see docs); never read by the algorithms
#include <Eigen/Geometry>
#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "cairn/core/point_cloud.hpp"
#include "cairn/core/robot_model.hpp"
#include "cairn/core/transform.hpp"

namespace cairn::io {

inline constexpr int kRunFormatVersion = 1;

struct ScanInfo {
  std::string sensor;  // "H" or "V"
  int index = 0;
  double t_start = 0.0, t_end = 0.0;  // [s]
  std::size_t num_points = 0;
  std::string file;  // relative to the run directory
};

struct RunDirectory {
  std::filesystem::path root;
  std::string scenario;
  std::uint64_t seed = 0;
  double duration = 0.0;
  RobotModel robot;
  std::map<std::string, Eigen::Isometry3d> T_cabin_sensor;  // "H", "V"
  std::vector<ScanInfo> scans;              // sorted by t_start
  std::vector<StampedPose> state_estimate;  // T_world_cabin
  std::vector<JointState> joint_states;
  std::filesystem::path drone_cloud, drone_sparse, drone_vins;  // empty when absent

  /// One sweep: points in the sensor frame, `times` absolute [s], scalar field "ring".
  /// Throws InputError when the file is missing or does not match the index.
  [[nodiscard]] PointCloud read_scan(const ScanInfo& scan) const;
  /// Ground-truth label of every point of that sweep (-1 terrain, k stone k, -3 robot).
  [[nodiscard]] std::vector<std::int32_t> read_scan_truth(const ScanInfo& scan) const;
  [[nodiscard]] std::filesystem::path truth_dir() const { return root / "truth"; }
};

/// Opens a run directory with one call: validates and loads metadata, robot model, extrinsics,
/// scan index, state estimates and joint states (the scans themselves are read on demand).
/// Throws InputError naming the missing or malformed file.
RunDirectory open_run_directory(const std::filesystem::path& root);

// Building blocks (also used by the writer).
void write_joint_states(const std::filesystem::path& file, const std::vector<JointState>& states);
std::vector<JointState> read_joint_states(const std::filesystem::path& file);
void write_stamped_poses(const std::filesystem::path& file, const std::vector<StampedPose>& poses);
std::vector<StampedPose> read_stamped_poses(const std::filesystem::path& file);
void write_scan_index(const std::filesystem::path& file, const std::vector<ScanInfo>& scans);
std::vector<ScanInfo> read_scan_index(const std::filesystem::path& file);
/// 1-D int32 arrays as NumPy .npy files (little endian).
void write_npy_int32(const std::filesystem::path& file, const std::vector<std::int32_t>& values);
std::vector<std::int32_t> read_npy_int32(const std::filesystem::path& file);

}  // namespace cairn::io
