#pragma once
// Rigid and similarity transforms. `T_a_b` maps points of frame b into frame a (p_a = T_a_b p_b).
// Rigid transforms are Eigen::Isometry3d; a similarity adds a uniform scale (SfM → metric,
// Sec. 4.1). JSON form: a 4×4 row-major nested array.
#include <Eigen/Geometry>
#include <string>
#include <vector>
#include <nlohmann/json.hpp>

#include "cairn/core/point_cloud.hpp"

namespace cairn {

/// The rigid transform that only translates by (x, y, z).
inline Eigen::Isometry3d pure_translation(double x, double y, double z) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(x, y, z);
  return T;
}

/// p ↦ scale · R · p + t
struct Similarity {
  double scale = 1.0;
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();

  [[nodiscard]] static Similarity from_isometry(const Eigen::Isometry3d& T);
  [[nodiscard]] Eigen::Vector3d operator*(const Eigen::Vector3d& p) const { return scale * (rotation * p) + translation; }
  /// (this ∘ other)(p) = this(other(p))
  [[nodiscard]] Similarity operator*(const Similarity& other) const;
  [[nodiscard]] Similarity inverse() const;
  [[nodiscard]] Eigen::Matrix4d matrix() const;
  /// Throws InputError unless m is scale·rotation | t with a proper rotation and positive scale.
  [[nodiscard]] static Similarity from_matrix(const Eigen::Matrix4d& m);
};

/// Applies a similarity to a cloud in place: positions in double precision through the cloud's
/// origin (the new origin is the transformed old one, rounded to whole metres when the cloud was
/// recentred), normals rotated only.
void transform_cloud(PointCloud& cloud, const Similarity& S);
void transform_cloud(PointCloud& cloud, const Eigen::Isometry3d& T);

/// Rotation angle of R [rad] and the distance between translations: the error measures of a
/// registration against ground truth.
[[nodiscard]] double rotation_angle(const Eigen::Matrix3d& R);

/// A pose at a time (e.g. the state estimate of the cabin, T_world_cabin).
struct StampedPose {
  double time = 0.0;  // [s]
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
};

/// Pose at time t: linear interpolation of the translation and slerp of the rotation between the
/// two neighbouring samples, clamped at the ends. `poses` must be sorted by time; throws
/// InputError when it is empty.
[[nodiscard]] Eigen::Isometry3d interpolate_pose(const std::vector<StampedPose>& poses, double t);

nlohmann::json matrix_to_json(const Eigen::Matrix4d& m);
/// Throws InputError unless j is a 4×4 array of numbers.
Eigen::Matrix4d matrix_from_json(const nlohmann::json& j);
/// The rigid transform a 4×4 matrix holds; InputError (prefixed by `what`) unless it is finite,
/// its last row 0 0 0 1 and its 3×3 block a rotation (Similarity::from_matrix with scale 1).
[[nodiscard]] Eigen::Isometry3d rigid_from_matrix(const Eigen::Matrix4d& m, const std::string& what);

}  // namespace cairn
