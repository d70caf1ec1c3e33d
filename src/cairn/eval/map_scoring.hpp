#pragma once
// The mapper scored against the simulator's truth: the trajectory error of an estimate, and the
// map's own rigid offset from the true surfaces at the objects (the georeferencing error no
// relative constraint observes), which the registration protocol and the experiments remove
// before they score poses in the map's frame.
#include <Eigen/Geometry>
#include <memory>
#include <vector>

#include "cairn/core/kdtree.hpp"
#include "cairn/core/point_cloud.hpp"
#include "cairn/core/transform.hpp"
#include "cairn/registration/icp.hpp"

namespace cairn::eval {

/// Trajectory error against ground truth: RMSE of the position differences at the estimate's
/// times (truth interpolated), without alignment (the world frame is georeferenced).
struct TrajectoryError {
  double ate_rmse = 0.0, ate_max = 0.0;  // [m]
  Vec3d mean_error = Vec3d::Zero();       // [m] constant part of the position error
  double ate_rmse_without_mean = 0.0;     // [m] RMSE after removing mean_error
  double rotation_rmse_deg = 0.0;        // [deg]
  std::size_t num = 0;
};
[[nodiscard]] TrajectoryError trajectory_error(const std::vector<StampedPose>& estimate,
                                               const std::vector<StampedPose>& truth);
/// One pose of an estimate against the truth interpolated at its time.
struct PoseError {
  double time = 0.0;                // [s]
  double position_error_m = 0.0;    // [m]
  double rotation_error_deg = 0.0;  // [deg]
};
/// The error of every pose of `estimate` (empty when either is empty); trajectory_error's terms.
[[nodiscard]] std::vector<PoseError> pose_errors(const std::vector<StampedPose>& estimate,
                                                 const std::vector<StampedPose>& truth);

/// The truth side of map_offset_at_objects, prepared once per truth cloud (a labelled dense
/// snapshot of the true surfaces: label >= 0 object, else terrain): ICP target with normals over
/// all of it, kd-tree over its object points. Throws InputError when `truth` has no labels.
class ObjectSurfaceTruth {
 public:
  explicit ObjectSurfaceTruth(const PointCloud& truth);
  ObjectSurfaceTruth(const ObjectSurfaceTruth&) = delete;
  ObjectSurfaceTruth& operator=(const ObjectSurfaceTruth&) = delete;
  /// Rigid offset of a map from the true surfaces where the objects are (the map's own
  /// georeferencing error there: GNSS bias and heading error no relative constraint observes).
  /// ICP (point-to-plane, robust) of the map's points within `near_distance` of a true object
  /// point onto the truth. Returns T_true_map: map (world) coordinates -> where those points truly
  /// are. Identity when fewer than 10 map points are near objects or ICP finds too few pairs.
  [[nodiscard]] Eigen::Isometry3d map_offset(const PointCloud& map, double near_distance = 0.5) const;

 private:
  Vec3d origin_;
  std::vector<Vec3f> objects_;             // object points, truth-local coordinates
  std::unique_ptr<KdTree> object_tree_;    // indexes objects_
  std::unique_ptr<IcpTarget> target_;
};

/// ObjectSurfaceTruth(truth).map_offset(map, near_distance), for one-off use.
[[nodiscard]] Eigen::Isometry3d map_offset_at_objects(const PointCloud& map, const PointCloud& truth,
                                                      double near_distance = 0.5);

}  // namespace cairn::eval
