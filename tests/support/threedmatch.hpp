#pragma once
// The GeoTransformer demo pair of 3DMatch fragments (shared/data/real/geotransformer-3dmatch-demo):
// indoor RGB-D, 2.5 cm voxels, ground-truth pose in a NumPy file.
#include <Eigen/Geometry>
#include <algorithm>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>

#include "cairn/core/point_cloud.hpp"
#include "cairn/core/transform.hpp"
#include "support/feature_data.hpp"
#include "support/registration_scenes.hpp"

namespace cairn::test {

/// The 4x4 float64 matrix of a NumPy .npy file (C order), as GeoTransformer stores gt.npy.
inline Eigen::Isometry3d read_npy_matrix(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  char magic[8] = {};
  in.read(magic, 8);
  if (!in || std::memcmp(magic, "\x93NUMPY", 6) != 0) throw std::runtime_error("not a .npy file: " + path.string());
  if (magic[6] != 1) throw std::runtime_error("only .npy format version 1 is read: " + path.string());
  std::uint16_t header_len = 0;
  in.read(reinterpret_cast<char*>(&header_len), 2);
  std::string header(header_len, '\0');
  in.read(header.data(), header_len);
  if (header.find("'<f8'") == std::string::npos || header.find("(4, 4)") == std::string::npos ||
      header.find("'fortran_order': False") == std::string::npos)
    throw std::runtime_error("expected a C-order 4x4 float64 matrix: " + header);
  Eigen::Matrix<double, 4, 4, Eigen::RowMajor> m;
  in.read(reinterpret_cast<char*>(m.data()), sizeof(double) * 16);
  if (!in) throw std::runtime_error("truncated .npy file: " + path.string());
  Eigen::Isometry3d T;
  T.matrix() = m;
  return T;
}

struct ThreeDMatchPair {
  PointCloud source, target;
  Eigen::Isometry3d T_gt;  // maps source points into the target frame
};

inline ThreeDMatchPair load_3dmatch_pair() {
  ThreeDMatchPair p;
  p.source.points = load_real_points("geotransformer-3dmatch-demo/src.xyz");
  p.target.points = load_real_points("geotransformer-3dmatch-demo/ref.xyz");
  p.T_gt = read_npy_matrix(real_data("geotransformer-3dmatch-demo/gt.npy"));
  return p;
}

/// Rotation error and displacement at the source's centroid (where the points are; a bare
/// translation difference also charges the rotation error times the camera's lever arm).
inline PoseError error_at_centroid(const Eigen::Isometry3d& T, const Eigen::Isometry3d& T_ref, const PointCloud& source) {
  Vec3d c = Vec3d::Zero();
  for (const Vec3f& p : source.points) c += p.cast<double>();
  c /= double(std::max<std::size_t>(1, source.size()));
  return {.rotation = rotation_angle(T.linear() * T_ref.linear().transpose()), .translation = (T * c - T_ref * c).norm()};
}

}  // namespace cairn::test
