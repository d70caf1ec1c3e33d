#pragma once
// Drone pre-map (Sec. 4.1): a camera flight over the site and the photogrammetry-like cloud that
// an SfM + multi-view-stereo reconstruction of its images would give, plus the camera positions
// as the SfM model (COLMAP) and a visual-inertial estimator (VINS-Mono) report them — the inputs
// of the scale-recovery step (similarity between SfM and VINS camera positions).
//
// Model:
//  - flight: a lawnmower pattern over the region (nadir camera, image overlaps as configured)
//    and/or an orbit of oblique images looking at the region centre, at a fixed altitude;
//  - images: pinhole camera (default: VI-Sensor / EuRoC cam0 intrinsics, 752×480); rays through
//    a pixel grid are cast with Embree (TBB parallel) and hit the first surface;
//  - fusion: hits are thinned to at most one per cube of 1.5 × `point_spacing` (mean
//    nearest-neighbour spacing ≈ point_spacing; the first camera in flight order keeps a cube) and kept only when at least `min_views` cameras see
//    the surface point (in the image, unoccluded, not at grazing incidence): MVS needs two views,
//    so occluded terrain (under stones) and stone undersides are missing;
//  - noise: along the viewing ray of the camera that kept the point, Gaussian with a standard
//    deviation growing linearly with range;
//  - frames: the cloud and the SfM camera poses are expressed in an SfM frame related to the world
//    by a random similarity (arbitrary 3-D rotation, translation, log-uniform scale); the VINS
//    positions in a gravity-aligned frame (random yaw + translation) with white noise and slow
//    drift; the SfM camera poses carry small residuals.
// Everything is deterministic for a seed, whatever the number of threads.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "cairn/core/io/colmap.hpp"
#include "cairn/core/io/trajectory.hpp"
#include "cairn/core/point_cloud.hpp"
#include "cairn/core/transform.hpp"
#include "cairn/sim/procedural_site.hpp"
#include "cairn/sim/raycast.hpp"

namespace cairn::sim {

/// Pinhole camera, COLMAP / OpenCV convention: x right, y down, z forward; pixel (u, v) of a
/// camera-frame point p is (fx p.x/p.z + cx, fy p.y/p.z + cy), the top-left pixel's centre (0.5, 0.5).
struct PinholeCamera {
  int width = 752, height = 480;  // [px] VI-Sensor (MT9V034)
  double fx = 458.654, fy = 457.296, cx = 367.215, cy = 248.375;  // [px] EuRoC cam0

  template <class V>
  void visit(V& v) {
    v("width", width, "image width [px]");
    v("height", height, "image height [px]");
    v("fx", fx, "focal length x [px]");
    v("fy", fy, "focal length y [px]");
    v("cx", cx, "principal point x [px]");
    v("cy", cy, "principal point y [px]");
  }
};

struct DroneConfig {
  // Flight
  double altitude = 12.0;  // [m] above the terrain at the region centre
  double center_x = 0.0, center_y = 0.0;  // [m] region centre (world)
  double extent_x = 10.0, extent_y = 10.0;  // [m] region covered by the lawnmower
  bool lawnmower = true;          // nadir images on parallel lines along x
  double forward_overlap = 0.85;  // along-track overlap of consecutive images (0..1)
  double side_overlap = 0.7;      // overlap of neighbouring lines (0..1)
  int orbit_images = 24;          // oblique images on a circle around the centre (0: none)
  double orbit_radius = 7.0;      // [m] horizontal radius of the orbit
  double speed = 2.0;             // [m/s] flight speed (image timestamps)
  PinholeCamera camera;
  int pixel_stride = 1;  // cast a ray through every n-th pixel in both directions

  // Reconstruction
  /// [m] mean nearest-neighbour spacing aimed at: fusion keeps at most one point per cube of
  /// 1.5 × this edge (the first camera in flight order that saw the cube keeps it).
  double point_spacing = 0.02;
  int min_views = 2;            // cameras that must see a surface point (MVS needs two)
  double max_incidence = 1.35;  // [rad] views more oblique to the surface than this do not count
  double depth_noise = 0.012;   // [m] depth noise std at noise_range, along the viewing ray
  double noise_range = 12.0;    // [m] range at which the depth noise is depth_noise (linear)
  double margin = 1.0;          // [m] points farther than this outside the region are dropped
  bool colors = true;           // terrain brown/grey, stones grey shades, sun shading

  // Frames
  double sfm_min_scale = 0.2, sfm_max_scale = 5.0;  // SfM units per metre (log-uniform)
  double sfm_max_translation = 20.0;  // [SfM units] per axis, uniform in ±
  bool sfm_gravity_aligned = false;   // true: SfM rotation about z only
  double sfm_position_noise = 0.01;   // [m] SfM camera centre residual std per axis
  double sfm_rotation_noise = 0.001;  // [rad] SfM camera rotation residual std per axis
  double vins_max_translation = 10.0;  // [m] per horizontal axis, uniform in ± (z: ±1 m)
  double vins_position_noise = 0.03;   // [m] white noise std per axis
  double vins_drift = 0.002;           // [m per m flown] slowly turning drift
  double vins_rotation_noise = 0.005;  // [rad] orientation noise std per axis

  template <class V>
  void visit(V& v) {
    v("altitude", altitude, "flight altitude above the terrain at the region centre [m]");
    v("center_x", center_x, "region centre x (world) [m]");
    v("center_y", center_y, "region centre y (world) [m]");
    v("extent_x", extent_x, "region size along x covered by the lawnmower [m]");
    v("extent_y", extent_y, "region size along y covered by the lawnmower [m]");
    v("lawnmower", lawnmower, "fly a lawnmower pattern of nadir images");
    v("forward_overlap", forward_overlap, "along-track image overlap (0..1)");
    v("side_overlap", side_overlap, "overlap of neighbouring lawnmower lines (0..1)");
    v("orbit_images", orbit_images, "oblique images on an orbit around the centre (0: none)");
    v("orbit_radius", orbit_radius, "horizontal orbit radius [m]");
    v("speed", speed, "flight speed, for image timestamps [m/s]");
    v("camera", camera, "pinhole intrinsics (default: VI-Sensor / EuRoC cam0)");
    v("pixel_stride", pixel_stride, "cast rays through every n-th pixel");
    v("point_spacing", point_spacing, "mean point spacing aimed at (one point per cube of 1.5x this edge) [m]");
    v("min_views", min_views, "cameras that must see a point for it to be reconstructed");
    v("max_incidence", max_incidence, "views more oblique to the surface do not count [rad]");
    v("depth_noise", depth_noise, "depth noise std at noise_range, along the viewing ray [m]");
    v("noise_range", noise_range, "range at which the depth noise equals depth_noise [m]");
    v("margin", margin, "points farther outside the region are dropped [m]");
    v("colors", colors, "colour the points (terrain brown/grey, stones grey, sun shading)");
    v("sfm_min_scale", sfm_min_scale, "smallest SfM scale [SfM units per m] (log-uniform)");
    v("sfm_max_scale", sfm_max_scale, "largest SfM scale [SfM units per m] (log-uniform)");
    v("sfm_max_translation", sfm_max_translation, "SfM translation per axis, uniform in ± [SfM units]");
    v("sfm_gravity_aligned", sfm_gravity_aligned, "SfM rotation about z only");
    v("sfm_position_noise", sfm_position_noise, "SfM camera centre residual std per axis [m]");
    v("sfm_rotation_noise", sfm_rotation_noise, "SfM camera rotation residual std per axis [rad]");
    v("vins_max_translation", vins_max_translation, "VINS frame translation per horizontal axis, ± [m]");
    v("vins_position_noise", vins_position_noise, "VINS camera position white noise std per axis [m]");
    v("vins_drift", vins_drift, "VINS position drift per metre flown [m/m]");
    v("vins_rotation_noise", vins_rotation_noise, "VINS orientation noise std per axis [rad]");
  }
};

/// One image of the flight.
struct DroneImage {
  std::string name;        // "frame_0000.png", ...
  double timestamp = 0.0;  // [s] from take-off
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();  // true pose
  /// SfM pose as COLMAP stores it: X_cam = R(q_cam_sfm) X_sfm + t_cam_sfm (with SfM residuals).
  Eigen::Quaterniond q_cam_sfm = Eigen::Quaterniond::Identity();
  Eigen::Vector3d t_cam_sfm = Eigen::Vector3d::Zero();
  Eigen::Vector3d position_sfm = Eigen::Vector3d::Zero();  // camera centre -R^T t [SfM units]
  /// VINS estimate (gravity-aligned frame; noise + drift): camera position and orientation.
  Eigen::Vector3d position_vins = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q_vins_cam = Eigen::Quaterniond::Identity();
};

struct DroneSurvey {
  PointCloud cloud;                 // SfM frame (origin zero); colours; labels = truth
  std::vector<std::int32_t> truth;  // per point: -1 terrain, k = stone k
  /// Per point: the image that kept it and a second image that sees it (indices into images).
  std::vector<std::array<std::uint32_t, 2>> views;
  std::vector<DroneImage> images;
  PinholeCamera camera;
  Similarity T_sfm_world;  // world -> SfM (the true similarity)
  Similarity T_world_sfm;  // its inverse: what registration must recover (up to the map frame)
  Eigen::Isometry3d T_vins_world = Eigen::Isometry3d::Identity();  // world -> VINS (true)
  std::uint64_t seed = 0;
  double seconds = 0.0;  // wall time of simulate_drone
};

/// Flies the drone over the site and reconstructs the photogrammetry-like cloud. `scene` must be
/// the committed world scene of `site` (make_world_scene). Throws ConfigError on invalid
/// configuration values, InputError if the scene is not committed.
DroneSurvey simulate_drone(const Site& site, const RayScene& scene, const DroneConfig& config,
                           std::uint64_t seed);

/// The survey as a COLMAP text model: one PINHOLE camera, the images with their SfM poses and the
/// 2-D observations of the 3-D points, and up to `max_points` cloud points (every n-th, each with
/// the track of its two views; reprojection error from ~0.3 px observation noise).
io::ColmapModel to_colmap_model(const DroneSurvey& survey, std::size_t max_points = 20000);

/// The VINS camera trajectory (camera -> VINS frame), in image order.
std::vector<io::TrajectoryPose> vins_trajectory(const DroneSurvey& survey);

/// Writes the survey's files into dir (created if missing):
///   sparse/cameras.txt, sparse/images.txt, sparse/points3D.txt   COLMAP text model (SfM frame)
///   drone_cloud.ply          dense cloud, SfM frame, colours + truth labels (binary PLY)
///   vins_trajectory.txt      TUM trajectory of the cameras in the VINS frame
///   drone_truth.json         T_sfm_world, T_world_sfm, T_vins_world (4×4), true camera poses
void write_drone_survey(const std::filesystem::path& dir, const DroneSurvey& survey);

}  // namespace cairn::sim
