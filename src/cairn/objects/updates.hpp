#pragma once
// The object database's updates under manipulation (Sec. 4.5), as operations to commit:
//   grasp   — T_MG^grasp stored, the object's points removed from the map (a MapEdit in the same
//             operation): its own voxels bounded by the R_obj sphere, or the paper's sphere;
//   release — Eq. 3, T^i = T_MG^release · (T_MG^grasp)^-1, applied to the cloud and centroid;
//   realign — after the next scanning, ICP of the moved cloud to the map; a large correction is
//             reported (fell or rolled), a poor fit marks the object lost with the reason.
#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "cairn/core/point_cloud.hpp"
#include "cairn/objects/config.hpp"
#include "cairn/segmentation/segmenter.hpp"
#include "cairn/objects/object_db.hpp"

namespace cairn {

/// Eq. 3: the motion of a held object from grasp to release (world frame).
[[nodiscard]] Eigen::Isometry3d release_transform(const Eigen::Isometry3d& T_map_gripper_grasp,
                                                  const Eigen::Isometry3d& T_map_gripper_release);

/// The map edit of a grasp: the object's voxels (cloud dilated by `distance`) within R_obj of its
/// centroid, or (method sphere) the whole R_obj sphere.
[[nodiscard]] MapEdit grasp_map_edit(const ObjectRecord& object, const GraspRemovalConfig& config);

/// Status grasped, T_MG^grasp stored, the map edit. Throws InputError unless the object is
/// on_ground or placed, or when a pose is not finite.
[[nodiscard]] Operation grasp_operation(const ObjectRecord& object, const Eigen::Isometry3d& T_map_gripper,
                                        double time, const GraspRemovalConfig& config);

/// Eq. 3 applied to the object's cloud; status placed. Throws InputError unless it is grasped.
[[nodiscard]] Operation release_operation(const ObjectRecord& object, const Eigen::Isometry3d& T_map_gripper,
                                          double time);

struct RealignResult {
  bool found = false;       // the fit passed min_fitness and max_rmse
  bool large = false;       // found, with a correction above report_translation / report_rotation
  Eigen::Isometry3d correction = Eigen::Isometry3d::Identity();  // world frame, applied to the cloud
  double translation = 0.0, rotation_deg = 0.0;                  // of the correction
  double fitness = 0.0, rmse = 0.0;
  std::size_t map_points = 0;  // map points near the predicted pose
  std::string reason;          // set when large or not found
};

/// ICP of the object's cloud (at its stored pose) to the map around it, coarse then fine.
[[nodiscard]] RealignResult realign_object(const ObjectRecord& object, const PointCloud& map,
                                           const RealignConfig& config);

/// realign_object, and when the object is not found near its prediction a search for a stone that
/// fell or rolled: the map within search_radius of the prediction segmented, every object segment
/// there that is not another object's (SegmentOwners over `others`: present where their clouds
/// are, the segment mostly on one of them) fitted to the model from each face turned down
/// (fit_model_to_segment), the best one (search_min_fitness, search_max_rmse) refined by
/// realign_object from where it was found; reported as large. The reason names the objects whose
/// segments were not tried.
[[nodiscard]] RealignResult relocate_object(const ObjectRecord& object, const PointCloud& map,
                                            const std::vector<ObjectRecord>& others, const ObjectsConfig& config,
                                            const SegmentationConfig& segmentation);

/// The stored outcome: found → cloud corrected, status placed (reason set when large);
/// not found → status lost with the reason, cloud unchanged.
[[nodiscard]] Operation realign_operation(const ObjectRecord& object, const RealignResult& result, double time);

}  // namespace cairn
