// The object database (Sec. 4.5): round trips, schema migration, refusal of foreign, empty,
// truncated and corrupt files (left untouched), and crash safety under SIGKILL.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <sstream>

#include "cairn/core/error.hpp"
#include "cairn/core/transform.hpp"
#include "cairn/objects/object_db.hpp"
#include "cairn/objects/updates.hpp"
#include "scene.hpp"
#include "support/poses.hpp"

namespace cairn {
namespace {

namespace fs = std::filesystem;

fs::path fresh_dir(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / ("cairn_objects_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

std::string read_bytes(const fs::path& f) {
  std::ifstream in(f, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

Operation populate(const std::vector<PointCloud>& clouds, double time) {
  Operation op{.time = time, .kind = "populate", .changes = {}, .map_edits = {}};
  for (const PointCloud& c : clouds) {
    ObjectChange ch;
    ch.source = "segmentation";
    ch.cloud = c;
    op.changes.push_back(ch);
  }
  return op;
}

using test::pose;

TEST(ObjectDatabase, StoresObjectsHistoryAndMapEditsExactly) {
  const fs::path dir = fresh_dir("roundtrip");
  const fs::path file = dir / "objects.db";
  const PointCloud a = test::stone(Vec3d(1000.3, 2000.1, 0.3), 0.3);
  const PointCloud b = test::stone(Vec3d(1002.0, 2000.5, 0.25), 0.25);
  std::int64_t ida = 0;
  {
    ObjectDatabase db(file, ObjectDatabase::Mode::create);
    EXPECT_EQ(db.schema_version(), ObjectDatabase::kSchemaVersion);
    const CommitResult r = db.commit(populate({a, b}, 1.0));
    ASSERT_EQ(r.ids.size(), 2u);
    ida = r.ids[0];
    const ObjectRecord oa = *db.object(ida);
    const Eigen::Isometry3d g = pose(1000.3, 2000.1, 1.2, 0.4);
    (void)db.commit(grasp_operation(oa, g, 2.0, GraspRemovalConfig{}));
    (void)db.commit(release_operation(*db.object(ida), pose(1004.0, 2001.0, 1.2, 1.0), 3.0));
  }
  const ObjectDatabase db(file, ObjectDatabase::Mode::read_only);
  const std::vector<ObjectRecord> all = db.objects();
  ASSERT_EQ(all.size(), 2u);
  // b untouched, bit-exact.
  EXPECT_EQ(all[1].cloud.points, b.points);
  EXPECT_EQ(all[1].cloud.origin, b.origin);
  EXPECT_EQ(all[1].status, ObjectStatus::on_ground);
  EXPECT_EQ(all[1].source, "segmentation");
  // a moved by Eq. 3: its centroid where the release put it.
  const Eigen::Isometry3d T = release_transform(pose(1000.3, 2000.1, 1.2, 0.4), pose(1004.0, 2001.0, 1.2, 1.0));
  const Vec3d c0 = a.origin + centroid(a.points).cast<double>();
  EXPECT_LT((all[0].centroid - T * c0).norm(), 1e-5);
  EXPECT_EQ(all[0].status, ObjectStatus::placed);
  EXPECT_FALSE(all[0].T_map_gripper_grasp.has_value());
  const std::vector<PoseUpdate> h = db.history(ida);
  ASSERT_EQ(h.size(), 3u);
  EXPECT_EQ(h[0].cause, PoseCause::created);
  EXPECT_EQ(h[1].cause, PoseCause::grasp);
  EXPECT_EQ(h[2].cause, PoseCause::release);
  EXPECT_TRUE(h[2].transform.isApprox(T, 1e-12));
  const std::vector<StoredMapEdit> edits = db.map_edits();
  ASSERT_EQ(edits.size(), 1u);
  EXPECT_EQ(edits[0].edit.kind, MapEdit::Kind::remove_near);
  EXPECT_EQ(edits[0].edit.points.points, a.points);
  EXPECT_EQ(edits[0].op, h[1].op);
  EXPECT_EQ(db.operations().size(), 3u);
  EXPECT_EQ(db.integrity_check(), "ok");
  fs::remove_all(dir);
}

TEST(ObjectDatabase, RejectsBadOperationsAndStoresNothing) {
  const fs::path dir = fresh_dir("badop");
  ObjectDatabase db(dir / "objects.db", ObjectDatabase::Mode::create);
  (void)db.commit(populate({test::stone(Vec3d(0, 0, 0.3), 0.3)}, 0.0));
  Operation bad = populate({test::stone(Vec3d(2, 0, 0.3), 0.3)}, 1.0);
  bad.changes.push_back({.id = 99});  // unknown object
  EXPECT_THROW((void)db.commit(bad), InputError);
  PointCloud nan_cloud = test::stone(Vec3d(3, 0, 0.3), 0.3);
  nan_cloud.points[5].x() = std::nanf("");
  EXPECT_THROW((void)db.commit(populate({nan_cloud}, 2.0)), InputError);
  EXPECT_THROW((void)db.commit(populate({PointCloud{}}, 2.0)), InputError);
  EXPECT_EQ(db.objects().size(), 1u);
  EXPECT_EQ(db.operations().size(), 1u);
  // A grasp of a grasped object, a release of an object on the ground: refused.
  const ObjectRecord o = db.objects()[0];
  EXPECT_THROW((void)release_operation(o, pose(0, 0, 1, 0), 3.0), InputError);
  (void)db.commit(grasp_operation(o, pose(0, 0, 1, 0), 3.0, {}));
  EXPECT_THROW((void)grasp_operation(*db.object(o.id), pose(0, 0, 1, 0), 4.0, {}), InputError);
  fs::remove_all(dir);
}

TEST(ObjectDatabase, MigratesAVersionOneDatabase) {
  const fs::path dir = fresh_dir("migrate");
  const fs::path file = dir / "old.db";
  {  // A database as schema version 1 wrote it (no `source` column, no indexes).
    sqlite::Connection c(file.string(), SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE);
    c.exec("PRAGMA application_id=" + std::to_string(ObjectDatabase::kApplicationId));
    objects_detail::migrate(c, 0, 1);
    c.exec("INSERT INTO operations(time, kind) VALUES (5.0, 'populate')");
    const std::vector<float> pts = {1, 2, 3, 4, 5, 6};
    sqlite::Statement s = c.prepare(
        "INSERT INTO objects(status, cx, cy, cz, ox, oy, oz, num_points, points, created_op, updated_op) "
        "VALUES ('on_ground', 2.5, 3.5, 4.5, 0, 0, 0, 2, ?, 1, 1)");
    s.bind_blob(1, std::as_bytes(std::span(pts))).run();
    EXPECT_EQ(c.scalar_int("PRAGMA user_version"), 1);
  }
  // Read-only access to an old schema is refused with the way out, and changes nothing.
  const std::string before = read_bytes(file);
  try {
    const ObjectDatabase ro(file, ObjectDatabase::Mode::read_only);
    ADD_FAILURE() << "opened an old schema read-only";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("schema version 1"), std::string::npos) << e.what();
  }
  EXPECT_EQ(read_bytes(file), before);
  {
    const ObjectDatabase db(file, ObjectDatabase::Mode::read_write);
    EXPECT_EQ(db.schema_version(), 2);
    const std::vector<ObjectRecord> all = db.objects();
    ASSERT_EQ(all.size(), 1u);
    EXPECT_EQ(all[0].source, "unknown");
    EXPECT_EQ(all[0].cloud.points[1], Vec3f(4, 5, 6));
    EXPECT_EQ(all[0].centroid, Vec3d(2.5, 3.5, 4.5));
    EXPECT_EQ(db.integrity_check(), "ok");
  }
  fs::remove_all(dir);
}

/// Opening `file` in every mode fails with an InputError naming it, and leaves it byte-identical.
void expect_refused(const fs::path& file, const std::string& expected) {
  const std::string before = read_bytes(file);
  for (auto mode : {ObjectDatabase::Mode::read_only, ObjectDatabase::Mode::read_write, ObjectDatabase::Mode::create}) {
    try {
      const ObjectDatabase db(file, mode);
      ADD_FAILURE() << file << " was opened";
    } catch (const InputError& e) {
      const std::string msg = e.what();
      EXPECT_NE(msg.find(file.string()), std::string::npos) << msg;
      EXPECT_NE(msg.find(expected), std::string::npos) << msg;
    }
    EXPECT_EQ(read_bytes(file), before) << file << " was modified";
    EXPECT_FALSE(fs::exists(file.string() + "-wal"));
    EXPECT_FALSE(fs::exists(file.string() + "-shm"));
  }
}

TEST(ObjectDatabase, RefusesForeignEmptyTruncatedAndCorruptFilesWithoutTouchingThem) {
  const fs::path dir = fresh_dir("refuse");
  EXPECT_THROW(ObjectDatabase(dir / "missing.db", ObjectDatabase::Mode::read_only), InputError);
  EXPECT_FALSE(fs::exists(dir / "missing.db"));
  std::ofstream(dir / "empty.db").close();
  expect_refused(dir / "empty.db", "empty file");
  std::ofstream(dir / "cloud.ply") << "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n";
  expect_refused(dir / "cloud.ply", "not an SQLite database");
  {
    sqlite::Connection c((dir / "other.db").string(), SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE);
    c.exec("CREATE TABLE objects(id INTEGER PRIMARY KEY, name TEXT); INSERT INTO objects(name) VALUES ('x')");
  }
  expect_refused(dir / "other.db", "another application");
  // A real database, truncated, and one with a page overwritten.
  const fs::path good = dir / "good.db";
  {
    ObjectDatabase db(good, ObjectDatabase::Mode::create);
    for (int k = 0; k < 6; ++k) (void)db.commit(populate({test::stone(Vec3d(k, 0, 0.3), 0.3, 6000)}, k));
  }
  ASSERT_FALSE(fs::exists(good.string() + "-wal"));  // checkpointed on close
  const std::string bytes = read_bytes(good);
  ASSERT_GT(bytes.size(), 8 * 4096u);
  std::ofstream(dir / "truncated.db", std::ios::binary).write(bytes.data(), std::streamsize(bytes.size() / 2));
  expect_refused(dir / "truncated.db", "corrupt");
  std::string damaged = bytes;
  for (std::size_t i = 2 * 4096; i < 3 * 4096; ++i) damaged[i] = char(0xA5);
  std::ofstream(dir / "damaged.db", std::ios::binary).write(damaged.data(), std::streamsize(damaged.size()));
  expect_refused(dir / "damaged.db", "corrupt");
  // A newer schema: refused in every mode, untouched.
  const fs::path newer = dir / "newer.db";
  fs::copy_file(good, newer);
  {
    sqlite::Connection c(newer.string(), SQLITE_OPEN_READWRITE);
    c.exec("PRAGMA user_version=" + std::to_string(ObjectDatabase::kSchemaVersion + 1));
  }
  expect_refused(newer, "newer than");
  // A leftover -wal of a database that is gone would be replayed into a new one: refused.
  std::ofstream(dir / "gone.db-wal") << "old frames";
  EXPECT_THROW(ObjectDatabase(dir / "gone.db", ObjectDatabase::Mode::create), InputError);
  EXPECT_FALSE(fs::exists(dir / "gone.db"));
  fs::remove_all(dir);
}

// ---- crash safety ----------------------------------------------------------------------------

/// The writer: populate / grasp / release cycles, each committed op id reported on the pipe.
[[noreturn]] void writer(const fs::path& file, int fd, unsigned seed) {
  try {
    ObjectDatabase db(file, ObjectDatabase::Mode::read_write);
    std::mt19937 rng(seed);
    for (int k = 0;; ++k) {
      const std::vector<ObjectRecord> all = db.objects();
      Operation op;
      const ObjectRecord* grasped = nullptr;
      const ObjectRecord* ground = nullptr;
      for (const ObjectRecord& r : all) {
        if (r.status == ObjectStatus::grasped) grasped = &r;
        if (r.status != ObjectStatus::grasped) ground = &r;
      }
      const double x = std::uniform_real_distribution<double>(0, 20)(rng);
      if (grasped) op = release_operation(*grasped, pose(x, 0, 1, 0.3), k);
      else if (ground && all.size() > 3) op = grasp_operation(*ground, pose(x, 0, 1, 0), k, {});
      else op = populate({test::stone(Vec3d(x, 1, 0.3), 0.3, 400)}, k);
      const std::int64_t id = db.commit(op).op;
      if (::write(fd, &id, sizeof(id)) != sizeof(id)) break;
    }
  } catch (...) {
  }
  ::_exit(0);
}

TEST(ObjectDatabase, SurvivesSigkillAtRandomMoments) {
  const fs::path dir = fresh_dir("crash");
  const fs::path file = dir / "objects.db";
  { ObjectDatabase db(file, ObjectDatabase::Mode::create); }
  std::mt19937 rng(7);
  std::map<std::int64_t, bool> reported;
  const int kills = 200;
  int killed_with_progress = 0;
  for (int round = 0; round < kills; ++round) {
    int fds[2];
    ASSERT_EQ(::pipe(fds), 0);
    const pid_t pid = ::fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
      ::close(fds[0]);
      writer(file, fds[1], unsigned(round));
    }
    ::close(fds[1]);
    // Kill at a random moment after the writer's first commit (whatever the build's speed), so
    // every kill lands in a stream of commits, often inside one.
    std::int64_t id = 0;
    std::size_t n = 0;
    if (::read(fds[0], &id, sizeof(id)) == sizeof(id)) reported[id] = true, ++n;
    ::usleep(useconds_t(std::uniform_int_distribution<int>(0, 20000)(rng)));
    ::kill(pid, SIGKILL);
    int status = 0;
    ::waitpid(pid, &status, 0);
    while (::read(fds[0], &id, sizeof(id)) == sizeof(id)) reported[id] = true, ++n;
    ::close(fds[0]);
    killed_with_progress += n > 0;

    const ObjectDatabase db(file, ObjectDatabase::Mode::read_write);
    ASSERT_EQ(db.integrity_check(), "ok") << "after kill " << round;
    std::map<std::int64_t, OperationRecord> ops;
    for (const OperationRecord& o : db.operations()) ops[o.id] = o;
    for (const auto& [op, _] : reported) ASSERT_TRUE(ops.contains(op)) << "committed op " << op << " lost";
    // Each operation whole: a grasp has its object update and its map edit, the others one edit less.
    for (const auto& [op, o] : ops) {
      const std::size_t want_edits = o.kind == "grasp" ? 1 : 0;
      ASSERT_EQ(o.map_edits, want_edits) << o.kind << " op " << op;
      ASSERT_GE(o.changes, 1u) << o.kind << " op " << op;
    }
  }
  EXPECT_EQ(killed_with_progress, kills);  // every kill hit a writer that was committing
  const ObjectDatabase db(file, ObjectDatabase::Mode::read_only);
  EXPECT_GT(db.operations().size(), std::size_t(kills));
  for (const ObjectRecord& r : db.objects()) {  // status and stored grasp agree with the history
    const std::vector<PoseUpdate> h = db.history(r.id);
    ASSERT_FALSE(h.empty());
    EXPECT_EQ(h.back().status, r.status);
    EXPECT_EQ(r.T_map_gripper_grasp.has_value(), r.status == ObjectStatus::grasped);
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace cairn
