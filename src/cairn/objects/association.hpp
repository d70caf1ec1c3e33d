#pragma once
// Re-segmentation against the object database (Sec. 4.5, extended): which new segment is which
// stored object. An object is never duplicated and never silently dropped:
//   1. an object whose points still have map points near them is still there (support);
//   2. a segment sharing most of its points with an object is that object (overlap);
//   3. an unmatched segment near an object that is no longer where it was (or that was lost) is
//      tried as that object moved — ICP of the segment onto the object's model from several yaws
//      (a neighbour bumped by the gripper, a stone that fell): reassociated with the motion;
//   4. remaining segments become new objects; remaining objects that are in view but gone are
//      lost (with the reason); objects out of view stay as they are.
#include <Eigen/Geometry>
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "cairn/core/point_cloud.hpp"
#include "cairn/objects/config.hpp"
#include "cairn/objects/object_db.hpp"

namespace cairn {

struct Association {
  struct Moved {
    std::int64_t id = 0;
    std::size_t segment = 0;
    Eigen::Isometry3d motion = Eigen::Isometry3d::Identity();  // applied to the object's cloud
    double fitness = 0.0, rmse = 0.0;
  };
  std::vector<std::pair<std::size_t, std::int64_t>> matched;  // (segment, object) where it was
  std::vector<std::int64_t> present;       // objects still there (support), matched or not
  std::vector<Moved> moved;                // found elsewhere
  std::vector<std::size_t> new_segments;   // become new objects
  std::vector<std::size_t> ignored_segments;  // unmatched and too small
  std::vector<std::int64_t> vanished;      // in view, gone, not found elsewhere
  std::vector<std::int64_t> out_of_view;   // not checked
};

/// Where a stored object's model lies in a segment: ICP of the segment's points onto the model
/// from starting rotations (yaw_seeds about the vertical; with all_faces also each face of a box
/// turned down: a stone that fell or rolled); the best fit. fitness: share of the segment's points
/// within overlap_distance of the model; motion: moves the model onto the segment (world).
struct ModelFit {
  double fitness = 0.0, rmse = 0.0;
  Eigen::Isometry3d motion = Eigen::Isometry3d::Identity();
  double runner_up = 0.0;  // best fitness of a pose turned > distinct_rotation_deg from this one
  /// The fit is unambiguous: no clearly different pose comes within `margin` of its fitness.
  [[nodiscard]] bool unambiguous(double margin) const { return runner_up < fitness - margin; }
};
/// Which stored object a segment already is, for a search that must not take another object's
/// segment (relocate_object): the objects on the ground or placed (not `self`) within `reach` of
/// `center` horizontally that the map still shows where their clouds are (min_support of their
/// points with a map point within overlap_distance: present, as the association's step 1 finds
/// them); a segment is the one sharing the largest share of its points, when that is at least
/// min_overlap (the association's step 2).
class SegmentOwners {
 public:
  SegmentOwners(const std::vector<ObjectRecord>& objects, std::int64_t self, const PointCloud& map, const Vec3d& center,
                double reach, const AssociationConfig& config);
  SegmentOwners(const SegmentOwners&) = delete;
  SegmentOwners& operator=(const SegmentOwners&) = delete;
  ~SegmentOwners();
  /// The owner's id, or nullopt.
  [[nodiscard]] std::optional<std::int64_t> owner(const PointCloud& segment) const;

 private:
  struct Owner;
  std::vector<std::unique_ptr<Owner>> owners_;
  Vec3d center_;
  AssociationConfig config_;
};

[[nodiscard]] ModelFit fit_model_to_segment(const PointCloud& segment, const PointCloud& model,
                                            const AssociationConfig& config, bool all_faces);

/// Associates the segments of a re-segmentation of `map` (world clouds) with the stored objects
/// (grasped objects are skipped: they are in the gripper). Throws InputError on non-finite input.
[[nodiscard]] Association associate(const std::vector<PointCloud>& segments, const std::vector<ObjectRecord>& objects,
                                    const PointCloud& map, const AssociationConfig& config);

/// The operation that stores an association: new objects (source as given), moved objects with
/// their motion (cause reassociated), vanished ones lost, lost ones seen again back on the ground.
[[nodiscard]] Operation association_operation(const Association& a, const std::vector<PointCloud>& segments,
                                              const std::vector<ObjectRecord>& objects, double time,
                                              const std::string& source);

}  // namespace cairn
