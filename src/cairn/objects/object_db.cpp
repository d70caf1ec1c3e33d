#include "cairn/objects/object_db.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <array>
#include <bit>
#include <cmath>
#include <cstdio>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <set>

#include "cairn/core/error.hpp"

namespace cairn {

static_assert(std::endian::native == std::endian::little, "the database stores little-endian floats");

namespace {

constexpr std::array<ObjectStatus, 4> kStatuses = {ObjectStatus::on_ground, ObjectStatus::grasped,
                                                   ObjectStatus::placed, ObjectStatus::lost};
constexpr std::array<PoseCause, 6> kCauses = {PoseCause::created, PoseCause::grasp,   PoseCause::release,
                                              PoseCause::realign, PoseCause::reassociated, PoseCause::lost};

// Schema steps: kMigrations[v] takes a database from version v to v + 1 (docs/objects.md).
const std::array<const char*, ObjectDatabase::kSchemaVersion> kMigrations = {
    // 0 -> 1: objects, their history, the operations (one per transaction) and the map edits.
    R"sql(
CREATE TABLE operations(
  id INTEGER PRIMARY KEY, time REAL NOT NULL, kind TEXT NOT NULL);
CREATE TABLE objects(
  id INTEGER PRIMARY KEY,
  status TEXT NOT NULL CHECK (status IN ('on_ground', 'grasped', 'placed', 'lost')),
  reason TEXT NOT NULL DEFAULT '',
  cx REAL NOT NULL, cy REAL NOT NULL, cz REAL NOT NULL,
  ox REAL NOT NULL, oy REAL NOT NULL, oz REAL NOT NULL,
  num_points INTEGER NOT NULL,
  points BLOB NOT NULL,
  grasp BLOB,
  created_op INTEGER NOT NULL REFERENCES operations(id),
  updated_op INTEGER NOT NULL REFERENCES operations(id));
CREATE TABLE history(
  id INTEGER PRIMARY KEY,
  object_id INTEGER NOT NULL REFERENCES objects(id),
  op INTEGER NOT NULL REFERENCES operations(id),
  time REAL NOT NULL, cause TEXT NOT NULL, transform BLOB NOT NULL,
  status TEXT NOT NULL, reason TEXT NOT NULL DEFAULT '');
CREATE TABLE map_edits(
  id INTEGER PRIMARY KEY,
  op INTEGER NOT NULL REFERENCES operations(id),
  kind TEXT NOT NULL,
  cx REAL NOT NULL, cy REAL NOT NULL, cz REAL NOT NULL, radius REAL NOT NULL, distance REAL NOT NULL,
  ox REAL NOT NULL, oy REAL NOT NULL, oz REAL NOT NULL, points BLOB NOT NULL);
)sql",
    // 1 -> 2: where each model came from; indexes for per-object history and per-operation edits.
    R"sql(
ALTER TABLE objects ADD COLUMN source TEXT NOT NULL DEFAULT 'unknown';
CREATE INDEX history_by_object ON history(object_id, id);
CREATE INDEX history_by_op ON history(op);
CREATE INDEX map_edits_by_op ON map_edits(op, id);
)sql",
};

template <class T>
std::span<const std::byte> bytes_of(const std::vector<T>& v) {
  return std::as_bytes(std::span(v));
}

std::vector<std::byte> transform_blob(const Eigen::Isometry3d& T) {
  std::vector<std::byte> b(16 * sizeof(double));
  const Eigen::Matrix4d m = T.matrix();
  std::memcpy(b.data(), m.data(), b.size());
  return b;
}

Eigen::Isometry3d transform_from_blob(const std::vector<std::byte>& b, const std::string& file) {
  if (b.size() != 16 * sizeof(double)) throw InputError(file + ": corrupt object database: bad transform");
  Eigen::Matrix4d m;
  std::memcpy(m.data(), b.data(), b.size());
  if (!m.allFinite() || !m.row(3).isApprox(Eigen::RowVector4d(0, 0, 0, 1)) ||
      !(m.topLeftCorner<3, 3>().transpose() * m.topLeftCorner<3, 3>()).isIdentity(1e-6))
    throw InputError(file + ": corrupt object database: a stored transform is not rigid");
  Eigen::Isometry3d T;
  T.matrix() = m;
  return T;
}

std::vector<Vec3f> points_from_blob(const std::vector<std::byte>& b, std::int64_t n, const std::string& file) {
  if (n < 0 || b.size() % sizeof(Vec3f) != 0 || b.size() / sizeof(Vec3f) != std::uint64_t(n))
    throw InputError(file + ": corrupt object database: point blob size");
  std::vector<Vec3f> pts(n);
  std::memcpy(static_cast<void*>(pts.data()), b.data(), b.size());
  return pts;
}

Vec3d mean_world(const PointCloud& c) { return c.origin + centroid(c.points).cast<double>(); }

/// The first 100 bytes of an SQLite file: magic, and cairn's application_id at offset 68.
void check_header(const std::filesystem::path& file) {
  std::error_code ec;
  if (std::filesystem::is_directory(file, ec))
    throw InputError(file.string() + ": is a directory, not an object database");
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError(file.string() + ": cannot read the object database");
  std::array<unsigned char, 100> h{};
  in.read(reinterpret_cast<char*>(h.data()), h.size());
  if (in.gcount() == 0) throw InputError(file.string() + ": empty file, not an object database");
  if (in.gcount() < std::streamsize(h.size()) || std::memcmp(h.data(), "SQLite format 3\0", 16) != 0)
    throw InputError(file.string() + ": not an SQLite database (not a cairn object database)");
  const std::uint32_t app = (std::uint32_t(h[68]) << 24) | (std::uint32_t(h[69]) << 16) |
                            (std::uint32_t(h[70]) << 8) | std::uint32_t(h[71]);
  if (app != std::uint32_t(ObjectDatabase::kApplicationId))
    throw InputError(file.string() + ": an SQLite database of another application (application_id " +
                     std::to_string(app) + "), not a cairn object database");
}

/// A stored value that does not parse (a status, a cause, an edit kind): the file is corrupt.
template <class F>
auto stored(const std::string& file, F&& parse) {
  try {
    return parse();
  } catch (const InputError& e) {
    throw InputError(file + ": corrupt object database: " + e.what());
  }
}

bool file_exists(const std::filesystem::path& f) {
  std::error_code ec;
  return std::filesystem::exists(f, ec);
}

/// quick_check and the schema version, read without writing anything. A file without a -wal (closed
/// cleanly: the main file is the whole database) is read through an immutable connection, which
/// takes no lock and creates no -wal or -shm, whatever the file holds; with a -wal (a writer is
/// running, or crashed) through a normal read-only connection, which reads the WAL too.
int check_contents(const std::filesystem::path& file) {
  const bool wal = file_exists(file.string() + "-wal");
  std::string uri = "file:";
  for (char ch : std::filesystem::absolute(file).string()) {
    if (ch == '?' || ch == '#' || ch == '%') {
      char hex[4];
      std::snprintf(hex, sizeof(hex), "%%%02X", unsigned(static_cast<unsigned char>(ch)));
      uri += hex;
    } else {
      uri += ch;
    }
  }
  if (!wal) uri += "?immutable=1";
  try {
    const sqlite::Connection c(uri, SQLITE_OPEN_READONLY | SQLITE_OPEN_URI);
    const std::string quick = c.scalar_text("PRAGMA quick_check");
    if (quick != "ok") throw InputError(quick);
    return int(c.scalar_int("PRAGMA user_version"));
  } catch (const InputError& e) {
    throw InputError(file.string() + ": corrupt object database (" + e.what() + ")");
  }
}

void fsync_directory(const std::filesystem::path& dir) {
  const int fd = ::open(dir.empty() ? "." : dir.c_str(), O_RDONLY | O_DIRECTORY);
  if (fd >= 0) {
    (void)::fsync(fd);
    ::close(fd);
  }
}

/// A new database is made under a temporary name and renamed into place, so a crash never
/// leaves a half-initialised file under the real name.
void create_database(const std::filesystem::path& file) {
  for (const char* side : {"-wal", "-shm", "-journal"})
    if (file_exists(file.string() + side))
      throw InputError(file.string() + side + ": left over from a database that is gone; remove it first (it would be "
                       "replayed into the new one)");
  const std::filesystem::path tmp = file.string() + ".creating-" + std::to_string(::getpid());
  auto remove_tmp = [&] {
    std::error_code ec;
    for (const char* side : {"", "-journal", "-wal", "-shm"}) std::filesystem::remove(tmp.string() + side, ec);
  };
  remove_tmp();
  try {
    sqlite::Connection db(tmp.string(), SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE);
    db.exec("PRAGMA journal_mode=DELETE; PRAGMA synchronous=FULL; PRAGMA application_id=" +
            std::to_string(ObjectDatabase::kApplicationId));
    sqlite::Transaction t(db);
    objects_detail::migrate(db, 0, ObjectDatabase::kSchemaVersion);
    t.commit();
    if (db.scalar_text("PRAGMA journal_mode=WAL") != "wal") db.fail("cannot switch to the WAL journal");
  } catch (...) {
    remove_tmp();
    throw;
  }
  // link() fails when the name exists: a database someone else created meanwhile is never replaced.
  const int linked = ::link(tmp.c_str(), file.c_str());
  const int err = errno;
  remove_tmp();
  if (linked != 0)
    throw InputError(file.string() + ": cannot create the object database: " + std::strerror(err));
  fsync_directory(file.parent_path());
}

}  // namespace

const char* to_string(ObjectStatus s) {
  switch (s) {
    case ObjectStatus::on_ground: return "on_ground";
    case ObjectStatus::grasped: return "grasped";
    case ObjectStatus::placed: return "placed";
    case ObjectStatus::lost: return "lost";
  }
  return "?";
}

const char* to_string(PoseCause c) {
  switch (c) {
    case PoseCause::created: return "created";
    case PoseCause::grasp: return "grasp";
    case PoseCause::release: return "release";
    case PoseCause::realign: return "realign";
    case PoseCause::reassociated: return "reassociated";
    case PoseCause::lost: return "lost";
  }
  return "?";
}

ObjectStatus object_status_from_string(const std::string& s) {
  for (ObjectStatus v : kStatuses)
    if (s == to_string(v)) return v;
  throw InputError("unknown object status '" + s + "'");
}

PoseCause pose_cause_from_string(const std::string& s) {
  for (PoseCause v : kCauses)
    if (s == to_string(v)) return v;
  throw InputError("unknown pose cause '" + s + "'");
}

namespace objects_detail {
void migrate(const sqlite::Connection& db, int from_version, int to_version) {
  for (int v = from_version; v < to_version; ++v) db.exec(kMigrations[std::size_t(v)]);
  db.exec("PRAGMA user_version=" + std::to_string(to_version));
}
}  // namespace objects_detail

ObjectDatabase::ObjectDatabase(const std::filesystem::path& file, Mode mode)
    : file_(file),
      read_only_(mode == Mode::read_only),
      db_([&] {
        if (!file_exists(file)) {
          if (mode != Mode::create) throw InputError(file.string() + ": no such object database");
          create_database(file);
        }
        check_header(file);
        // Everything that refuses the file is decided before a writable connection exists.
        const int version = check_contents(file);
        if (version > kSchemaVersion)
          throw InputError(file.string() + ": object database of schema version " + std::to_string(version) +
                           ", newer than this cairn's " + std::to_string(kSchemaVersion));
        if (version < 1) throw InputError(file.string() + ": object database without a schema");
        if (read_only_ && version < kSchemaVersion)
          throw InputError(file.string() + ": object database of schema version " + std::to_string(version) +
                           ": open it once read-write (any writing command) to migrate it to " +
                           std::to_string(kSchemaVersion));
        return sqlite::Connection(file.string(), read_only_ ? SQLITE_OPEN_READONLY : SQLITE_OPEN_READWRITE);
      }()) {
  const int version = schema_version();
  db_.exec("PRAGMA foreign_keys=ON");
  if (read_only_) return;
  if (db_.scalar_text("PRAGMA journal_mode=WAL") != "wal") db_.fail("cannot switch to the WAL journal");
  db_.exec("PRAGMA synchronous=FULL");
  if (version < kSchemaVersion) {
    sqlite::Transaction t(db_);
    objects_detail::migrate(db_, version, kSchemaVersion);
    t.commit();
  }
}

int ObjectDatabase::schema_version() const { return int(db_.scalar_int("PRAGMA user_version")); }

std::string ObjectDatabase::integrity_check() const { return db_.scalar_text("PRAGMA integrity_check"); }

std::vector<ObjectRecord> ObjectDatabase::objects(bool with_clouds) const {
  const std::string cols = with_clouds ? "points" : "NULL";
  sqlite::Statement s = db_.prepare(
      "SELECT id, status, reason, source, cx, cy, cz, ox, oy, oz, num_points, " + cols +
      ", grasp, (SELECT COUNT(*) FROM history h WHERE h.object_id = o.id) FROM objects o ORDER BY id");
  std::vector<ObjectRecord> out;
  const std::string f = file_.string();
  while (s.step()) {
    ObjectRecord r;
    r.id = s.column_int(0);
    r.status = stored(f, [&] { return object_status_from_string(s.column_text(1)); });
    r.reason = s.column_text(2);
    r.source = s.column_text(3);
    r.centroid = Vec3d(s.column_double(4), s.column_double(5), s.column_double(6));
    r.cloud.origin = Vec3d(s.column_double(7), s.column_double(8), s.column_double(9));
    if (s.column_int(10) < 0) throw InputError(f + ": corrupt object database: negative point count");
    r.num_points = std::size_t(s.column_int(10));
    if (with_clouds) r.cloud.points = points_from_blob(s.column_blob(11), s.column_int(10), f);
    if (!s.is_null(12)) r.T_map_gripper_grasp = transform_from_blob(s.column_blob(12), f);
    r.updates = std::size_t(s.column_int(13));
    out.push_back(std::move(r));
  }
  return out;
}

std::optional<ObjectRecord> ObjectDatabase::object(std::int64_t id) const {
  // Few objects per site (tens): filtering the full list keeps one reader of the table.
  for (ObjectRecord& r : objects(true))
    if (r.id == id) return std::move(r);
  return std::nullopt;
}

std::vector<PoseUpdate> ObjectDatabase::history(std::int64_t id) const {
  sqlite::Statement s = db_.prepare(
      "SELECT op, time, cause, transform, status, reason FROM history WHERE object_id = ? ORDER BY id");
  s.bind(1, id);
  std::vector<PoseUpdate> out;
  while (s.step())
    out.push_back({.op = s.column_int(0),
                   .time = s.column_double(1),
                   .cause = stored(file_.string(), [&] { return pose_cause_from_string(s.column_text(2)); }),
                   .transform = transform_from_blob(s.column_blob(3), file_.string()),
                   .status = stored(file_.string(), [&] { return object_status_from_string(s.column_text(4)); }),
                   .reason = s.column_text(5)});
  return out;
}

std::vector<OperationRecord> ObjectDatabase::operations() const {
  sqlite::Statement s = db_.prepare(
      "SELECT id, time, kind, (SELECT COUNT(*) FROM history h WHERE h.op = o.id), "
      "(SELECT COUNT(*) FROM map_edits e WHERE e.op = o.id) FROM operations o ORDER BY id");
  std::vector<OperationRecord> out;
  while (s.step())
    out.push_back({.id = s.column_int(0),
                   .time = s.column_double(1),
                   .kind = s.column_text(2),
                   .changes = std::size_t(s.column_int(3)),
                   .map_edits = std::size_t(s.column_int(4))});
  return out;
}

std::vector<StoredMapEdit> ObjectDatabase::map_edits() const {
  sqlite::Statement s = db_.prepare(
      "SELECT op, kind, cx, cy, cz, radius, distance, ox, oy, oz, points FROM map_edits ORDER BY id");
  std::vector<StoredMapEdit> out;
  while (s.step()) {
    StoredMapEdit e;
    e.op = s.column_int(0);
    e.edit.kind = stored(file_.string(), [&] { return map_edit_kind_from_string(s.column_text(1)); });
    e.edit.center = Vec3d(s.column_double(2), s.column_double(3), s.column_double(4));
    e.edit.radius = s.column_double(5);
    e.edit.distance = s.column_double(6);
    e.edit.points.origin = Vec3d(s.column_double(7), s.column_double(8), s.column_double(9));
    const std::vector<std::byte> blob = s.column_blob(10);
    e.edit.points.points = points_from_blob(blob, std::int64_t(blob.size() / sizeof(Vec3f)), file_.string());
    out.push_back(std::move(e));
  }
  return out;
}

void ObjectDatabase::validate(const Operation& op) const {
  const std::string what = file_.string() + ": operation '" + op.kind + "'";
  if (read_only_) throw InputError(what + ": the database is open read-only");
  if (!std::isfinite(op.time)) throw InputError(what + ": time is not finite");
  std::set<std::int64_t> ids;
  for (const ObjectRecord& r : objects(false)) ids.insert(r.id);
  for (const ObjectChange& c : op.changes) {
    if (c.id == 0 && !c.cloud) throw InputError(what + ": a new object needs a cloud");
    if (c.id != 0 && !ids.contains(c.id))
      throw InputError(what + ": no object " + std::to_string(c.id) + " in the database");
    if (c.cloud) {
      if (c.cloud->empty()) throw InputError(what + ": empty object cloud");
      if (!c.cloud->origin.allFinite()) throw InputError(what + ": object cloud origin is not finite");
      c.cloud->check_finite(what + ": object cloud");
    }
    if (!c.transform.matrix().allFinite() ||
        (c.T_map_gripper_grasp && !c.T_map_gripper_grasp->matrix().allFinite()))
      throw InputError(what + ": transform is not finite");
  }
  for (const MapEdit& e : op.map_edits) e.validate();
}

void ObjectDatabase::write_change(std::int64_t op, double time, const ObjectChange& c, std::int64_t& id) {
  const bool keep_grasp = c.status == ObjectStatus::grasped && c.T_map_gripper_grasp;
  if (c.id == 0) {
    const PointCloud& cloud = *c.cloud;
    const Vec3d m = mean_world(cloud);
    sqlite::Statement s = db_.prepare(
        "INSERT INTO objects(status, reason, source, cx, cy, cz, ox, oy, oz, num_points, points, grasp, "
        "created_op, updated_op) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)");
    s.bind(1, std::string(to_string(c.status))).bind(2, c.reason).bind(3, c.source.empty() ? "unknown" : c.source);
    s.bind(4, m.x()).bind(5, m.y()).bind(6, m.z());
    s.bind(7, cloud.origin.x()).bind(8, cloud.origin.y()).bind(9, cloud.origin.z());
    s.bind(10, std::int64_t(cloud.size())).bind_blob(11, bytes_of(cloud.points));
    if (keep_grasp) s.bind_blob(12, transform_blob(*c.T_map_gripper_grasp));
    else s.bind_null(12);
    s.bind(13, op).bind(14, op).run();
    id = db_.last_insert_id();
  } else {
    id = c.id;
    sqlite::Statement s = db_.prepare(
        "UPDATE objects SET status = ?, reason = ?, grasp = ?, updated_op = ? WHERE id = ?");
    s.bind(1, std::string(to_string(c.status))).bind(2, c.reason);
    if (keep_grasp) s.bind_blob(3, transform_blob(*c.T_map_gripper_grasp));
    else s.bind_null(3);
    s.bind(4, op).bind(5, id).run();
    if (c.cloud) {
      const Vec3d m = mean_world(*c.cloud);
      sqlite::Statement u = db_.prepare(
          "UPDATE objects SET cx = ?, cy = ?, cz = ?, ox = ?, oy = ?, oz = ?, num_points = ?, points = ? "
          "WHERE id = ?");
      u.bind(1, m.x()).bind(2, m.y()).bind(3, m.z());
      u.bind(4, c.cloud->origin.x()).bind(5, c.cloud->origin.y()).bind(6, c.cloud->origin.z());
      u.bind(7, std::int64_t(c.cloud->size())).bind_blob(8, bytes_of(c.cloud->points)).bind(9, id).run();
    }
  }
  sqlite::Statement h = db_.prepare(
      "INSERT INTO history(object_id, op, time, cause, transform, status, reason) VALUES (?, ?, ?, ?, ?, ?, ?)");
  h.bind(1, id).bind(2, op).bind(3, time).bind(4, std::string(to_string(c.cause)));
  h.bind_blob(5, transform_blob(c.transform)).bind(6, std::string(to_string(c.status))).bind(7, c.reason).run();
}

void ObjectDatabase::write_edit(std::int64_t op, const MapEdit& e) {
  sqlite::Statement s = db_.prepare(
      "INSERT INTO map_edits(op, kind, cx, cy, cz, radius, distance, ox, oy, oz, points) "
      "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)");
  s.bind(1, op).bind(2, std::string(to_string(e.kind)));
  s.bind(3, e.center.x()).bind(4, e.center.y()).bind(5, e.center.z()).bind(6, e.radius).bind(7, e.distance);
  s.bind(8, e.points.origin.x()).bind(9, e.points.origin.y()).bind(10, e.points.origin.z());
  s.bind_blob(11, bytes_of(e.points.points)).run();
}

CommitResult ObjectDatabase::commit(const Operation& op) {
  validate(op);
  sqlite::Transaction t(db_);
  sqlite::Statement s = db_.prepare("INSERT INTO operations(time, kind) VALUES (?, ?)");
  s.bind(1, op.time).bind(2, op.kind).run();
  CommitResult r{.op = db_.last_insert_id(), .ids = {}};
  for (const ObjectChange& c : op.changes) write_change(r.op, op.time, c, r.ids.emplace_back());
  for (const MapEdit& e : op.map_edits) write_edit(r.op, e);
  t.commit();
  return r;
}

}  // namespace cairn
