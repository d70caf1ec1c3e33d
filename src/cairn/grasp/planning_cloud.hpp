#pragma once
// The grasp planning point cloud (paper Sec. 5.2, Fig. 5-6): the LiDAR map cropped around the
// object with a margin of the gripper's full width, merged with the registered drone cloud (when
// there is one) or else with the object database's model of the object, unobserved ground filled
// with points of a RANSAC ground plane, downsampled to a uniform density, normals estimated.
#include <Eigen/Core>
#include <cstdint>
#include <optional>

#include "cairn/core/plane.hpp"
#include "cairn/core/point_cloud.hpp"
#include "cairn/grasp/config.hpp"
#include "cairn/robot/gripper.hpp"

namespace cairn::grasp {

/// What a planning-cloud point is (PointCloud::labels).
enum PointKind : std::int32_t { kEnvironment = 0, kObject = 1, kGroundFill = 2 };

struct PlanningCloud {
  /// Points relative to `cloud.origin` (the object's centroid), normals (PCA, outwards on the
  /// object; the ground plane's normal elsewhere), labels = PointKind.
  PointCloud cloud;
  Vec3d centroid = Vec3d::Zero();  // the object's model centroid (map frame)
  /// The object's centre of mass estimated as a solid: the columns from the ground plane up to the
  /// object's highest point in each voxel-sized cell (a stone rests on the ground; the model's
  /// points are its surface seen from above and the sides, so their mean lies too high). The
  /// model centroid when there is no ground plane.
  Vec3d mass_centroid = Vec3d::Zero();
  std::optional<Plane> ground;     // in the cloud's frame (relative to the origin), normal upwards
  Vec3d ground_normal = Vec3d::UnitZ();  // upwards (+z when no plane was found)
  std::size_t object_points = 0, environment_points = 0, fill_points = 0;
};

/// The crop (Sec. 5.2): half-extent around the object's centroid, horizontally, and the
/// gripper's full width used as margin (its widest part fully open).
[[nodiscard]] double gripper_full_width(const GripperConfig& gripper);

/// Builds the planning cloud. `map` and `object` (the object's model: its segment or database
/// cloud) and the optional `drone` cloud are in the map frame. Throws InputError on an empty
/// object model or non-finite points.
[[nodiscard]] PlanningCloud build_planning_cloud(const PointCloud& map, const PointCloud& object,
                                                 const PointCloud* drone, const GripperConfig& gripper,
                                                 const PlanningCloudConfig& config);

/// Fills the ground where `cloud` saw none (Fig. 6c): one point per voxel-sized cell of the
/// cloud's horizontal extent that holds no environment point; under object points only where the
/// fill lies a voxel below the object's lowest point of that cell. The fill lies on `plane`
/// raised by the seen ground's height above it, carried from the nearest seen columns
/// (environment points within `follow_band` of the plane; 0: on the plane). Appends kGroundFill
/// points; returns how many.
std::size_t fill_ground(PointCloud& cloud, const Plane& plane, double voxel, double follow_band = 0.0);

/// The solid's centroid of the object points of `cloud` standing on `plane` (same frame).
[[nodiscard]] Vec3d solid_centroid(const PointCloud& cloud, const Plane& plane, double voxel);

/// Normals on a labelled cloud: on object points PCA over `radius` (neighbours among all points),
/// oriented away from `object_centroid` (same frame); elsewhere `up` (the planner reads only the
/// object's normals: the environment is only ever collided with).
void orient_normals(PointCloud& cloud, double radius, const Vec3f& object_centroid, const Vec3f& up);

}  // namespace cairn::grasp
