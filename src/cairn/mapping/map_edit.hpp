#pragma once
// Edits of the LiDAR map by other stages (Sec. 4.5): a grasped object's points are removed, a
// model's points inserted. One definition of what an edit removes, used by the streaming map
// (LocalMap / Mapper, which replay edits after a rebuild), by map snapshots and by the object
// database, which stores every edit with the object update it belongs to.
#include <Eigen/Geometry>
#include <memory>
#include <string>

#include "cairn/core/kdtree.hpp"
#include "cairn/core/point_cloud.hpp"

namespace cairn {

struct MapEdit {
  enum class Kind {
    remove_sphere,  // every point within `radius` of `center` (the paper's R_obj sphere)
    remove_near,    // points within `distance` of `points` (an object's own voxels), and only
                    // inside the sphere (center, radius): the sphere is the upper bound
    insert,         // `points` are added
  };
  Kind kind = Kind::remove_sphere;
  Vec3d center = Vec3d::Zero();
  double radius = 0.0;
  PointCloud points;
  double distance = 0.0;

  [[nodiscard]] static MapEdit sphere(const Vec3d& center, double radius);
  [[nodiscard]] static MapEdit near(PointCloud points, double distance, const Vec3d& center, double radius);
  [[nodiscard]] static MapEdit add(PointCloud points);

  /// Throws InputError on non-finite values, negative radii, or a missing point set.
  void validate() const;
  /// The same edit moved rigidly by D (world frame), e.g. with the node it was anchored to.
  [[nodiscard]] MapEdit transformed(const Eigen::Isometry3d& D) const;
};

[[nodiscard]] const char* to_string(MapEdit::Kind kind);
/// Throws InputError on an unknown name.
[[nodiscard]] MapEdit::Kind map_edit_kind_from_string(const std::string& name);

/// The region a remove edit deletes, ready for many queries (the object's points indexed once).
class MapEditRegion {
 public:
  explicit MapEditRegion(const MapEdit& edit);
  ~MapEditRegion();
  MapEditRegion(const MapEditRegion&) = delete;
  MapEditRegion& operator=(const MapEditRegion&) = delete;
  /// True when the world position is removed by the edit (never for insert edits).
  [[nodiscard]] bool removes(const Vec3d& world) const;

 private:
  const MapEdit& edit_;
  std::unique_ptr<KdTree> tree_;
};

/// Applies an edit to a map held as a point cloud (a snapshot or a stored map); returns the
/// number of points removed (0 for inserts). Attributes of kept points are kept.
std::size_t apply_edit(PointCloud& map, const MapEdit& edit);

}  // namespace cairn
