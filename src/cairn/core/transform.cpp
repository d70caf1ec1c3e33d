#include "cairn/core/transform.hpp"

#include <algorithm>

#include <cmath>

#include "cairn/core/error.hpp"

namespace cairn {

Similarity Similarity::from_isometry(const Eigen::Isometry3d& T) { return {1.0, T.linear(), T.translation()}; }

Similarity Similarity::operator*(const Similarity& o) const {
  return {scale * o.scale, rotation * o.rotation, scale * (rotation * o.translation) + translation};
}

Similarity Similarity::inverse() const {
  const Eigen::Matrix3d Rt = rotation.transpose();
  return {1.0 / scale, Rt, -(Rt * translation) / scale};
}

Eigen::Matrix4d Similarity::matrix() const {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() = scale * rotation;
  m.topRightCorner<3, 1>() = translation;
  return m;
}

Similarity Similarity::from_matrix(const Eigen::Matrix4d& m) {
  constexpr double kTolerance = 1e-6;
  if (!m.allFinite()) throw InputError("transform: matrix has non-finite entries");
  if ((m.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).norm() > kTolerance)
    throw InputError("transform: last row must be 0 0 0 1");
  const Eigen::Matrix3d A = m.topLeftCorner<3, 3>();
  const double det = A.determinant();
  if (!(det > 0)) throw InputError("transform: the 3×3 block is not a proper (det > 0) rotation × scale");
  const double s = std::cbrt(det);
  const Eigen::Matrix3d R = A / s;
  if ((R.transpose() * R - Eigen::Matrix3d::Identity()).norm() > kTolerance * 100)
    throw InputError("transform: the 3×3 block is not a scaled rotation");
  return {s, R, m.topRightCorner<3, 1>()};
}

Eigen::Isometry3d rigid_from_matrix(const Eigen::Matrix4d& m, const std::string& what) {
  constexpr double kTolerance = 1e-6;
  try {
    const Similarity S = Similarity::from_matrix(m);
    if (std::abs(S.scale - 1.0) > kTolerance) throw InputError("transform: scaled by " + std::to_string(S.scale));
  } catch (const InputError& e) {
    throw InputError(what + ": not a rigid transform (" + e.what() + ")");
  }
  Eigen::Isometry3d T;
  T.matrix() = m;
  T.makeAffine();  // the last row exactly 0 0 0 1
  return T;
}

void transform_cloud(PointCloud& cloud, const Similarity& S) {
  const bool recentred = !cloud.origin.isZero();
  Eigen::Vector3d new_origin = S * cloud.origin;
  if (recentred) new_origin = new_origin.array().floor();
  const Eigen::Matrix3d sR = S.scale * S.rotation;
  const Eigen::Vector3d shift = S * cloud.origin - new_origin;  // where the old origin lands
  for (auto& p : cloud.points) p = (sR * p.cast<double>() + shift).cast<float>();
  const Eigen::Matrix3f R = S.rotation.cast<float>();
  for (auto& n : cloud.normals) n = R * n;
  cloud.origin = new_origin;
}

void transform_cloud(PointCloud& cloud, const Eigen::Isometry3d& T) { transform_cloud(cloud, Similarity::from_isometry(T)); }

double rotation_angle(const Eigen::Matrix3d& R) {
  return std::acos(std::clamp((R.trace() - 1.0) / 2.0, -1.0, 1.0));
}

nlohmann::json matrix_to_json(const Eigen::Matrix4d& m) {
  nlohmann::json j = nlohmann::json::array();
  for (int r = 0; r < 4; ++r) j.push_back({m(r, 0), m(r, 1), m(r, 2), m(r, 3)});
  return j;
}

Eigen::Matrix4d matrix_from_json(const nlohmann::json& j) {
  if (!j.is_array() || j.size() != 4) throw InputError("transform: expected a 4×4 nested array");
  Eigen::Matrix4d m;
  for (int r = 0; r < 4; ++r) {
    if (!j[r].is_array() || j[r].size() != 4) throw InputError("transform: row " + std::to_string(r) + " must have 4 numbers");
    for (int c = 0; c < 4; ++c) {
      if (!j[r][c].is_number()) throw InputError("transform: entry (" + std::to_string(r) + "," + std::to_string(c) + ") is not a number");
      m(r, c) = j[r][c].get<double>();
    }
  }
  return m;
}

Eigen::Isometry3d interpolate_pose(const std::vector<StampedPose>& poses, double t) {
  if (poses.empty()) throw InputError("interpolate_pose: no poses");
  if (t <= poses.front().time) return poses.front().pose;
  if (t >= poses.back().time) return poses.back().pose;
  const auto it = std::upper_bound(poses.begin(), poses.end(), t,
                                   [](double v, const StampedPose& p) { return v < p.time; });
  const StampedPose& b = *it;
  const StampedPose& a = *(it - 1);
  const double s = (t - a.time) / (b.time - a.time);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = (1 - s) * a.pose.translation() + s * b.pose.translation();
  T.linear() = Eigen::Quaterniond(a.pose.linear()).slerp(s, Eigen::Quaterniond(b.pose.linear())).toRotationMatrix();
  return T;
}

}  // namespace cairn
