#pragma once
// What the cairn_objects node does, without ROS: the object database of Sec. 4.5 (SQLite, the
// same file `cairn objects` reads) filled by segmenting the newest map on request and updated by
// grasp and release events, as the CLI and the experiments do (objects/pipeline.hpp,
// objects/updates.hpp). C++17-clean header.
#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "cairn_ros/bag_file.hpp"

namespace cairn::bag {

struct ObjectView {
  std::int64_t id = 0;
  std::string status;  // on_ground, grasped, placed, lost
  std::array<double, 3> centroid{0.0, 0.0, 0.0};
  file::Cloud cloud;  // thinned to the view voxel
  std::array<std::uint8_t, 3> color{0, 0, 0};  // per id, as in the HTML report (report::object_color)
};

struct ObjectEventAnswer {
  std::string json;                   // the object after the event (`cairn objects show`)
  std::vector<file::MapEdit> edits;   // map edits the event implies (for the mapper)
};

class ObjectsCore {
 public:
  /// The CLI's configuration; `database`: the SQLite file (created when missing, kept across
  /// runs). Throws ConfigError / InputError (a foreign or corrupt file is left untouched).
  ObjectsCore(const std::string& config_file, const std::vector<std::string>& overrides, const std::string& database);
  ~ObjectsCore();
  ObjectsCore(const ObjectsCore&) = delete;
  ObjectsCore& operator=(const ObjectsCore&) = delete;

  void set_map(const file::Cloud& map);
  /// The map merged with the registered drone cloud (cairn_registration, Sec. 4.4): segmented
  /// instead of the LiDAR map until the first grasp, and ignored once the database holds a grasp
  /// (the drone's survey shows the site as it was before anything moved; early LiDAR maps miss
  /// what the cabin has not swept yet).
  void set_merged_map(const file::Cloud& merged);
  [[nodiscard]] bool has_map() const;
  /// Segments the merged map while it holds, else the newest LiDAR map (Sec. 4.3), and associates the segments with the stored objects
  /// (created, matched, moved, vanished): the association JSON of `cairn objects update`, with
  /// "segmented": "merged" or "map".
  [[nodiscard]] std::string segment(double time);
  /// Status grasped, T_MG^grasp stored, the object's points removed from the map (the edit).
  [[nodiscard]] ObjectEventAnswer grasp(std::int64_t id, const file::Transform& T_map_gripper, double time);
  /// Eq. 3 applied to the object's cloud and centroid; status placed.
  [[nodiscard]] ObjectEventAnswer release(std::int64_t id, const file::Transform& T_map_gripper, double time);
  /// Every placed object re-aligned to the newest map (ICP, then a search when it fell or
  /// rolled); JSON per object: found, correction, reason.
  [[nodiscard]] std::string realign(double time);
  /// `cairn objects list`: {"objects": [{id, status, centroid, num_points, updates}]}.
  [[nodiscard]] std::string list_json() const;
  /// The stored objects, clouds thinned to `voxel` [m].
  [[nodiscard]] std::vector<ObjectView> objects(double voxel) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace cairn::bag
