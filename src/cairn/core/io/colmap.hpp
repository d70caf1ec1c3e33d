#pragma once
// COLMAP text model (cameras.txt, images.txt, points3D.txt): the output of the drone's SfM
// reconstruction (Sec. 4.1). Layout as COLMAP writes it
// (https://colmap.github.io/format.html#text-format):
//
//   cameras.txt   CAMERA_ID MODEL WIDTH HEIGHT PARAMS[]
//   images.txt    IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME       (pose: world-to-camera)
//                 POINTS2D[] as (X Y POINT3D_ID) ...                 (this line may be empty)
//   points3D.txt  POINT3D_ID X Y Z R G B ERROR TRACK[] as (IMAGE_ID POINT2D_IDX) ...
//
// "#" lines are comments. The image pose maps model ("world", here the SfM frame) points into
// the camera: X_cam = R(q) X + t, so the camera centre is C = -R^T t. Numbers are written in the
// shortest form that reads back to the same double, so write -> read is an exact round trip.
// Malformed input throws cairn::InputError naming the file and the line.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "cairn/core/point_cloud.hpp"

namespace cairn::io {

struct ColmapCamera {
  std::uint32_t id = 1;
  std::string model = "PINHOLE";  // any COLMAP model; PINHOLE params: fx fy cx cy
  int width = 0, height = 0;      // [px]
  std::vector<double> params;
  bool operator==(const ColmapCamera&) const = default;
};

struct ColmapObservation {
  Eigen::Vector2d xy = Eigen::Vector2d::Zero();  // [px], COLMAP convention (pixel centres at +0.5)
  std::int64_t point3d_id = -1;                  // -1: not triangulated
  bool operator==(const ColmapObservation&) const = default;
};

struct ColmapImage {
  std::uint32_t id = 1;
  /// World-to-camera rotation (COLMAP's QW QX QY QZ), stored exactly as read (not normalised).
  Eigen::Quaterniond q_cam_world = Eigen::Quaterniond::Identity();
  Eigen::Vector3d t_cam_world = Eigen::Vector3d::Zero();  // world-to-camera translation
  std::uint32_t camera_id = 1;
  std::string name;  // no whitespace (COLMAP splits on spaces)
  std::vector<ColmapObservation> points2d;

  /// X_cam = rotation_cam_world() X_world + t_cam_world (normalised quaternion).
  [[nodiscard]] Eigen::Matrix3d rotation_cam_world() const { return q_cam_world.normalized().toRotationMatrix(); }
  /// Camera centre in the model frame: C = -R^T t.
  [[nodiscard]] Eigen::Vector3d center() const { return -(rotation_cam_world().transpose() * t_cam_world); }
  /// Camera pose in the model frame (maps camera coordinates into the model frame).
  [[nodiscard]] Eigen::Isometry3d T_world_cam() const;
  bool operator==(const ColmapImage& o) const {
    return id == o.id && q_cam_world.coeffs() == o.q_cam_world.coeffs() && t_cam_world == o.t_cam_world &&
           camera_id == o.camera_id && name == o.name && points2d == o.points2d;
  }
};

struct ColmapTrackElement {
  std::uint32_t image_id = 0;
  std::uint32_t point2d_idx = 0;
  bool operator==(const ColmapTrackElement&) const = default;
};

struct ColmapPoint3D {
  std::uint64_t id = 1;
  Eigen::Vector3d xyz = Eigen::Vector3d::Zero();
  Rgb color;
  double error = 0.0;  // mean reprojection error [px]
  std::vector<ColmapTrackElement> track;
  bool operator==(const ColmapPoint3D&) const = default;
};

struct ColmapModel {
  std::vector<ColmapCamera> cameras;
  std::vector<ColmapImage> images;
  std::vector<ColmapPoint3D> points;
  bool operator==(const ColmapModel&) const = default;
};

/// Number of parameters of a COLMAP camera model, or -1 for an unknown model name.
int colmap_model_num_params(const std::string& model);

/// Writes dir/cameras.txt, dir/images.txt and dir/points3D.txt (dir is created if missing).
/// Throws InputError on unwritable files, unknown camera models, wrong parameter counts or image
/// names containing whitespace.
void write_colmap_text(const std::filesystem::path& dir, const ColmapModel& model);

/// Reads the three files of a text model from dir. Throws InputError (file and line named) on
/// missing files, malformed lines, unknown camera models, wrong parameter counts, duplicate ids.
ColmapModel read_colmap_text(const std::filesystem::path& dir);

// The single files, for tools that need only one of them.
void write_colmap_cameras(const std::filesystem::path& file, const std::vector<ColmapCamera>& cameras);
void write_colmap_images(const std::filesystem::path& file, const std::vector<ColmapImage>& images);
void write_colmap_points3d(const std::filesystem::path& file, const std::vector<ColmapPoint3D>& points);
std::vector<ColmapCamera> read_colmap_cameras(const std::filesystem::path& file);
std::vector<ColmapImage> read_colmap_images(const std::filesystem::path& file);
std::vector<ColmapPoint3D> read_colmap_points3d(const std::filesystem::path& file);

/// The model's 3-D points as a cloud (positions and colours; origin zero).
PointCloud colmap_points_cloud(const ColmapModel& model);

}  // namespace cairn::io
