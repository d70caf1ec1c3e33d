#pragma once
// The object database of Sec. 4.5: every stone the robot knows, with its globally referenced
// point cloud P_i, centroid c_i, id i, status, and the history of every pose change (time, cause,
// transform) — persistent in SQLite and crash-safe:
//  - WAL journal with synchronous=FULL: a commit that returned survives a crash or power loss;
//  - one transaction per operation (an operation = object changes + the map edits they imply, so
//    a grasp's object update and its map edit are both stored or both absent);
//  - a new file is initialised under a temporary name and renamed into place (never half made);
//  - an existing file is checked before anything writes to it (SQLite header, cairn's
//    application_id, schema version, quick_check): a foreign, empty, truncated or corrupt file
//    is an InputError naming it, and is left untouched.
// Schema and migrations: docs/objects.md.
#include <Eigen/Geometry>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "cairn/core/point_cloud.hpp"
#include "cairn/mapping/map_edit.hpp"
#include "cairn/objects/sqlite.hpp"

namespace cairn {

enum class ObjectStatus { on_ground, grasped, placed, lost };
/// Why a pose or status changed (history entries).
enum class PoseCause { created, grasp, release, realign, reassociated, lost };

[[nodiscard]] const char* to_string(ObjectStatus s);
[[nodiscard]] const char* to_string(PoseCause c);
/// Throw InputError on an unknown name.
[[nodiscard]] ObjectStatus object_status_from_string(const std::string& s);
[[nodiscard]] PoseCause pose_cause_from_string(const std::string& s);

/// One entry of an object's history: the transform the object underwent (world frame, applied
/// to its cloud and centroid; identity for status-only changes) and the status it was left in.
struct PoseUpdate {
  std::int64_t op = 0;
  double time = 0.0;
  PoseCause cause = PoseCause::created;
  Eigen::Isometry3d transform = Eigen::Isometry3d::Identity();
  ObjectStatus status = ObjectStatus::on_ground;
  std::string reason;
};

struct ObjectRecord {
  std::int64_t id = 0;
  ObjectStatus status = ObjectStatus::on_ground;
  std::string reason;  // why the status is what it is (empty when nothing to report)
  std::string source;  // where the model came from: "segmentation", "registration", ...
  PointCloud cloud;    // world frame (cloud.origin + point); empty when loaded without clouds
  Vec3d centroid = Vec3d::Zero();  // mean of the cloud's points
  std::size_t num_points = 0;
  std::optional<Eigen::Isometry3d> T_map_gripper_grasp;  // set while grasped (Eq. 3)
  std::size_t updates = 0;  // history entries
};

/// A change of one object inside an operation.
struct ObjectChange {
  std::int64_t id = 0;  // 0: create a new object (the database assigns the id)
  ObjectStatus status = ObjectStatus::on_ground;
  std::string reason;
  std::string source;               // new objects only
  std::optional<PointCloud> cloud;  // the object's new cloud (required for new objects)
  std::optional<Eigen::Isometry3d> T_map_gripper_grasp;  // stored with status grasped, else cleared
  PoseCause cause = PoseCause::created;
  Eigen::Isometry3d transform = Eigen::Isometry3d::Identity();
};

/// What one transaction stores: object changes and the map edits that go with them.
struct Operation {
  double time = 0.0;
  std::string kind;  // "populate", "grasp", "release", "realign", "associate", ...
  std::vector<ObjectChange> changes;
  std::vector<MapEdit> map_edits;
};

struct CommitResult {
  std::int64_t op = 0;
  std::vector<std::int64_t> ids;  // per change (the new ids for created objects)
};

struct OperationRecord {
  std::int64_t id = 0;
  double time = 0.0;
  std::string kind;
  std::size_t changes = 0, map_edits = 0;
};

struct StoredMapEdit {
  std::int64_t op = 0;
  MapEdit edit;
};

class ObjectDatabase {
 public:
  static constexpr int kSchemaVersion = 2;
  static constexpr std::int32_t kApplicationId = 0x6361726e;  // "carn"

  enum class Mode {
    read_only,   // the file must exist and be a cairn object database
    read_write,  // same, writable (migrated to kSchemaVersion)
    create,      // read_write; a missing file is created
  };
  /// Throws InputError naming the file when it is missing (read_only, read_write), not an SQLite
  /// file, not a cairn object database, of a newer schema, or corrupt; the file is then unchanged.
  ObjectDatabase(const std::filesystem::path& file, Mode mode);

  [[nodiscard]] int schema_version() const;
  [[nodiscard]] std::vector<ObjectRecord> objects(bool with_clouds = true) const;
  [[nodiscard]] std::optional<ObjectRecord> object(std::int64_t id) const;
  [[nodiscard]] std::vector<PoseUpdate> history(std::int64_t id) const;
  [[nodiscard]] std::vector<OperationRecord> operations() const;
  /// Every stored map edit in commit order (replaying them reproduces the map's edits).
  [[nodiscard]] std::vector<StoredMapEdit> map_edits() const;
  /// "ok" or SQLite's list of problems (PRAGMA integrity_check).
  [[nodiscard]] std::string integrity_check() const;

  /// Stores the operation in one transaction. Throws InputError (nothing stored) when a change
  /// names an unknown object, a new object has no cloud, a cloud or transform is not finite, or
  /// a map edit is invalid.
  CommitResult commit(const Operation& op);

  [[nodiscard]] const std::filesystem::path& file() const { return file_; }

 private:
  void validate(const Operation& op) const;
  void write_change(std::int64_t op, double time, const ObjectChange& c, std::int64_t& id);
  void write_edit(std::int64_t op, const MapEdit& e);

  std::filesystem::path file_;
  bool read_only_ = true;
  sqlite::Connection db_;
};

namespace objects_detail {
/// Creates the schema up to `version` in an open, empty connection (tests use it to build old
/// databases for the migration test).
void migrate(const sqlite::Connection& db, int from_version, int to_version);
}  // namespace objects_detail

}  // namespace cairn
