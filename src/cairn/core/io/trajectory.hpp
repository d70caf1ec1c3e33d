#pragma once
// TUM RGB-D trajectory format: one pose per line, "timestamp tx ty tz qx qy qz qw", "#" comments.
// The pose maps the body (camera) frame into the trajectory's frame: p_frame = R(q) p_body + t.
// Used for the drone's visual-inertial (VINS-like) camera positions (Sec. 4.1). Numbers are
// written in their shortest round-trip form, so write -> read is exact.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <filesystem>
#include <span>
#include <vector>

namespace cairn::io {

struct TrajectoryPose {
  double timestamp = 0.0;                                      // [s]
  Eigen::Vector3d position = Eigen::Vector3d::Zero();          // t: body origin in the frame [m]
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();  // R: body -> frame (as read)

  [[nodiscard]] Eigen::Isometry3d pose() const;
  bool operator==(const TrajectoryPose& o) const {
    return timestamp == o.timestamp && position == o.position && orientation.coeffs() == o.orientation.coeffs();
  }
};

/// Writes a TUM trajectory (one header comment line). Throws InputError on write failure or
/// non-finite values.
void write_tum_trajectory(const std::filesystem::path& file, std::span<const TrajectoryPose> poses);

/// Reads a TUM trajectory. Blank lines and lines starting with '#' are skipped; every other line
/// must hold exactly 8 finite numbers with a non-zero quaternion, else InputError naming the
/// file and line.
std::vector<TrajectoryPose> read_tum_trajectory(const std::filesystem::path& file);

}  // namespace cairn::io
