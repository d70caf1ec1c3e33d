// In-process fuzzing of every reader (issue #20 item 6): valid small files of each format (PLY
// ascii / binary LE / BE and its mesh, PCD ascii / binary / compressed, XYZ, CSV, KITTI, VTK,
// NPY, COLMAP text, TUM, and every file of a run directory) are mutated — bits flipped, bytes
// set, spans deleted, duplicated or cut, numbers replaced by huge, negative, NaN or Inf ones —
// and read. A reader may accept a mutated file (then every coordinate it returns is finite) or
// throw cairn::InputError; anything else is a failure (the first five inputs of each kept in
// $TMPDIR/cairn_fuzz_failures) (another exception here, a crash, a leak
// or undefined behaviour under the sanitizers). Deterministic: fixed seeds per format;
// CAIRN_FUZZ_INPUTS=N sets the inputs per format (default 4200: over 10^5 in all).
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "cairn/core/error.hpp"
#include "cairn/core/io/colmap.hpp"
#include "cairn/core/io/io.hpp"
#include "cairn/core/io/run_dir.hpp"
#include "cairn/core/io/trajectory.hpp"
#include "cairn/core/robot_model.hpp"
#include "support/test_data.hpp"

namespace cairn::io::fuzzing {  // named: the unity build joins this file's helpers with test_io's
namespace {

namespace fs = std::filesystem;

std::string bytes_of(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void write_bytes(const fs::path& p, const std::string& s) {
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out.write(s.data(), std::streamsize(s.size()));
}

/// Mutations of a valid file: 1-4 of bit flips, interesting bytes, inserted tokens, deleted or
/// duplicated spans, truncation and numbers swapped for hostile ones.
class Mutator {
 public:
  explicit Mutator(std::uint64_t seed) : rng_(seed) {}

  std::string operator()(std::string s) {
    const int n = 1 + int(rng_() % 4);
    for (int i = 0; i < n; ++i) mutate(s);
    return s;
  }

 private:
  std::size_t pos(const std::string& s) { return s.empty() ? 0 : std::size_t(rng_() % (s.size() + 1)); }
  template <class T, std::size_t N>
  const T& pick(const T (&a)[N]) { return a[rng_() % N]; }

  void mutate(std::string& s) {
    static const char kBytes[] = {'\0', '\xff', '\x80', '\n', ' ', '-', '9', '.', 'e', 'n', ',', '"', '#'};
    static const char* const kTokens[] = {"nan", "inf", "-inf", "-1", "0", "4294967295", "4294967296",
                                          "18446744073709551616", "99999999999999999999", "1e308", "-1e308",
                                          "1e-320", "2147483648", "\n", ",", " ", "\"", "{", "}", "[", "]",
                                          "element vertex 1000000000\n", "POINTS 99999999\n", "DATA binary\n"};
    switch (rng_() % 7) {
      case 0:
        if (!s.empty()) s[pos(s) % s.size()] ^= char(1u << (rng_() % 8));
        break;
      case 1:
        if (!s.empty()) s[pos(s) % s.size()] = pick(kBytes);
        break;
      case 2:
        s.insert(pos(s), pick(kTokens));
        break;
      case 3: {
        const std::size_t a = pos(s), len = std::min<std::size_t>(s.size() - a, 1 + rng_() % 16);
        s.erase(a, len);
        break;
      }
      case 4: {
        const std::size_t a = pos(s), len = std::min<std::size_t>(s.size() - a, 1 + rng_() % 64);
        s.insert(pos(s), s.substr(a, len));
        break;
      }
      case 5:
        s.resize(pos(s));
        break;
      default: {  // a number (a run of digits) replaced
        const std::size_t a = pos(s);
        std::size_t b = a;
        while (b < s.size() && !std::isdigit(static_cast<unsigned char>(s[b]))) ++b;
        std::size_t e = b;
        while (e < s.size() && (std::isdigit(static_cast<unsigned char>(s[e])) || s[e] == '.')) ++e;
        if (b < s.size()) s.replace(b, e - b, pick(kTokens));
        break;
      }
    }
  }

  std::mt19937_64 rng_;
};

std::size_t inputs_per_format() {
  const char* env = std::getenv("CAIRN_FUZZ_INPUTS");
  return env ? std::size_t(std::strtoull(env, nullptr, 10)) : 4200;  // 24 formats: 100,800 inputs
}

bool finite(const PointCloud& c) {
  for (const Vec3f& p : c.points)
    if (!p.allFinite()) return false;
  return c.origin.allFinite();
}

/// One format: its valid seed file, the file name the reader is given and the reader (which
/// returns false when what it accepted breaks an invariant).
struct Target {
  std::string name;
  fs::path file;  // written with the mutated bytes
  std::function<bool()> read;
};

/// Reads `inputs_per_format()` mutations of `file`'s current bytes; returns the failures.
std::vector<std::string> fuzz(const Target& t, std::uint64_t seed) {
  const std::string valid = bytes_of(t.file);
  EXPECT_FALSE(valid.empty()) << t.name;
  EXPECT_TRUE(t.read()) << t.name << ": the valid seed file must be read";
  Mutator mutate(seed);
  std::vector<std::string> failures;
  std::size_t accepted = 0;
  const std::size_t n = inputs_per_format();
  for (std::size_t i = 0; i < n; ++i) {
    const std::string input = mutate(valid);
    write_bytes(t.file, input);
    std::string why;
    try {
      if (t.read()) ++accepted;
      else why = "accepted with a non-finite coordinate or a broken invariant";
    } catch (const InputError&) {
    } catch (const std::exception& e) {
      why = std::string("threw a non-InputError: ") + e.what();
    }
    if (!why.empty() && failures.size() < 5) {
      const fs::path kept_dir = fs::temp_directory_path() / "cairn_fuzz_failures";  // kept after the run
      fs::create_directories(kept_dir);
      const fs::path kept = kept_dir / (t.name + "_" + std::to_string(i) + t.file.extension().string());
      write_bytes(kept, input);
      failures.push_back(t.name + " input " + std::to_string(i) + " (" + kept.string() + "): " + why);
    } else if (!why.empty()) {
      failures.push_back(why);
    }
  }
  write_bytes(t.file, valid);
  std::printf("%-22s %zu mutated inputs, %zu accepted, %zu failures\n", t.name.c_str(), n, accepted, failures.size());
  return failures;
}

PointCloud small_cloud(bool attributes) {
  PointCloud c;
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-5.0f, 5.0f);
  for (int i = 0; i < 12; ++i) {
    c.points.emplace_back(u(rng), u(rng), u(rng));
    if (!attributes) continue;
    c.normals.push_back(Vec3f(u(rng), u(rng), 1.0f).normalized());
    c.colors.push_back({std::uint8_t(i * 20), 100, 200});
    c.times.push_back(0.01 * i);
    c.labels.push_back(i % 3 - 1);
  }
  return c;
}

const auto cloud_reader = [](fs::path f, Format format = Format::Auto) {
  return std::function<bool()>([f, format] {
    const ReadResult r = read_cloud(f, {.format = format});
    return finite(r.cloud) && !r.cloud.empty() && r.num_input >= r.cloud.size();
  });
};

std::vector<Target> cloud_targets(const fs::path& dir) {
  std::vector<Target> t;
  const PointCloud rich = small_cloud(true), plain = small_cloud(false);
  write_ply(dir / "a.ply", rich, PlyEncoding::Ascii);
  write_ply(dir / "le.ply", rich, PlyEncoding::BinaryLittleEndian);
  write_ply(dir / "be.ply", rich, PlyEncoding::BinaryBigEndian);
  Mesh mesh{.vertices = plain, .triangles = {{0, 1, 2}, {2, 3, 4}, {5, 6, 7}}};
  write_ply_mesh(dir / "mesh.ply", mesh, PlyEncoding::Ascii);
  write_pcd(dir / "a.pcd", rich, PcdEncoding::Ascii);
  write_pcd(dir / "b.pcd", rich, PcdEncoding::Binary);
  write_pcd(dir / "c.pcd", rich, PcdEncoding::BinaryCompressed);
  write_xyz(dir / "a.xyz", plain);
  write_bytes(dir / "a.csv", "x,y,z,intensity\n1.5,2,3,0.5\n-1,0.25,4e1,1\n0,0,0,2\n");
  std::string kitti(4 * sizeof(float) * 5, '\0');
  for (std::size_t i = 0; i < kitti.size() / sizeof(float); ++i) {
    const float v = float(i) * 0.5f;
    std::memcpy(kitti.data() + i * sizeof(float), &v, sizeof v);
  }
  write_bytes(dir / "a.bin", kitti);
  write_bytes(dir / "a.vtk",
              "# vtk DataFile Version 3.0\nstones\nASCII\nDATASET POLYDATA\nPOINTS 4 float\n0 0 0 1 0 0\n0 1 0 0 0 1\n"
              "VERTICES 4 8\n1 0\n1 1\n1 2\n1 3\n");
  std::string npy = "\x93NUMPY\x01";
  npy += '\0';
  std::string header = "{'descr': '<f4', 'fortran_order': False, 'shape': (4, 3), }";
  header.resize(128 - 10 - 1, ' ');
  header += '\n';
  npy += char(header.size() & 0xff);
  npy += char(header.size() >> 8);
  npy += header;
  for (int i = 0; i < 12; ++i) {
    const float v = float(i) - 3.5f;
    npy.append(reinterpret_cast<const char*>(&v), sizeof v);
  }
  write_bytes(dir / "a.npy", npy);
  for (const char* f : {"a.ply", "le.ply", "be.ply", "a.pcd", "b.pcd", "c.pcd", "a.xyz", "a.csv", "a.bin", "a.vtk", "a.npy"})
    t.push_back({std::string("cloud_") + fs::path(f).stem().string() + fs::path(f).extension().string().substr(1),
                 dir / f, cloud_reader(dir / f)});
  t.push_back({"ply_mesh", dir / "mesh.ply", [f = dir / "mesh.ply"] {
                 const Mesh m = read_ply_mesh(f);
                 for (const auto& tri : m.triangles)
                   for (std::uint32_t v : tri)
                     if (v >= m.vertices.size()) return false;  // a face naming a vertex that is not there
                 return finite(m.vertices);
               }});
  return t;
}

std::vector<Target> text_targets(const fs::path& dir) {
  std::vector<Target> t;
  fs::create_directories(dir / "sparse");
  write_bytes(dir / "sparse" / "cameras.txt", "# Camera list\n1 PINHOLE 640 480 500 500 320 240\n");
  write_bytes(dir / "sparse" / "images.txt",
              "# Image list\n1 1 0 0 0 0.5 -1 2 1 img_0.jpg\n10.5 20.5 1 30 40 -1\n"
              "2 0.7071 0 0.7071 0 1 1 1 1 img_1.jpg\n11 21 1\n");
  write_bytes(dir / "sparse" / "points3D.txt", "# Points\n1 0.5 0.2 3 255 0 0 0.1 1 0 2 0\n");
  const auto colmap = [d = dir / "sparse"] {
    const ColmapModel m = read_colmap_text(d);
    return finite(colmap_points_cloud(m));
  };
  for (const char* f : {"cameras.txt", "images.txt", "points3D.txt"})
    t.push_back({std::string("colmap_") + fs::path(f).stem().string(), dir / "sparse" / f, colmap});
  write_bytes(dir / "a.tum", "0.0 1 2 3 0 0 0 1\n0.1 1.1 2 3 0 0 0.1 0.995\n# comment\n0.2 1.2 2 3 0 0 0 1\n");
  t.push_back({"tum", dir / "a.tum", [f = dir / "a.tum"] {
                 for (const TrajectoryPose& p : read_tum_trajectory(f))
                   if (!p.position.allFinite() || !p.orientation.coeffs().allFinite() || !std::isfinite(p.timestamp))
                     return false;
                 return true;
               }});
  write_npy_int32(dir / "labels.npy", {-1, 0, 3, 7});
  t.push_back({"npy_int32", dir / "labels.npy", [f = dir / "labels.npy"] { return !read_npy_int32(f).empty() || true; }});
  return t;
}

/// A minimal valid run directory: one H sweep of 12 points.
void write_run(const fs::path& root) {
  fs::create_directories(root / "scans" / "H");
  fs::create_directories(root / "state");
  write_bytes(root / "run.json", R"({"format_version": 1, "scenario": "exp1", "seed": 3, "duration": 0.2})");
  RobotModel robot{.name = "machine"};
  robot.links.push_back({.name = "base"});
  Link cabin{.name = "cabin", .parent = 0, .joint = Link::Joint::Revolute, .joint_name = "swing"};
  cabin.shapes.push_back({.kind = Shape::Kind::Box, .name = "body", .size = Eigen::Vector3d(2, 3, 1)});
  robot.links.push_back(cabin);
  write_bytes(root / "robot.json", to_json(robot).dump(1));
  const std::string I = "[[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]";
  write_bytes(root / "extrinsics.json", R"({"T_cabin_sensor": {"H": )" + I + R"(, "V": )" + I + "}}");
  PointCloud scan = small_cloud(false);
  for (std::size_t i = 0; i < scan.size(); ++i) scan.times.push_back(0.005 * double(i));
  scan.fields.push_back({.name = "ring", .values = std::vector<float>(scan.size(), 1.0f)});
  write_ply(root / "scans" / "H" / "000000.ply", scan);
  write_scan_index(root / "scans" / "index.csv", {{.sensor = "H", .index = 0, .t_start = 0.0, .t_end = 0.1,
                                                   .num_points = scan.size(), .file = "scans/H/000000.ply"}});
  write_bytes(root / "state" / "cabin_poses.tum", "0.0 0 0 0 0 0 0 1\n0.1 0 0 0 0 0 0 1\n0.2 0 0 0 0 0 0 1\n");
  write_bytes(root / "state" / "joint_states.csv", "time,swing\n0.0,0.1\n0.1,0.2\n0.2,0.3\n");
}

std::vector<Target> run_targets(const fs::path& root) {
  write_run(root);
  const auto open = [root] {
    const RunDirectory run = open_run_directory(root);
    for (const ScanInfo& s : run.scans) {
      const PointCloud c = run.read_scan(s);
      if (!finite(c) || c.size() != s.num_points) return false;
    }
    for (const auto& [_, T] : run.T_cabin_sensor)
      if (!T.matrix().allFinite()) return false;
    return !run.state_estimate.empty();
  };
  std::vector<Target> t;
  for (const char* f : {"run.json", "robot.json", "extrinsics.json", "scans/index.csv", "scans/H/000000.ply",
                        "state/cabin_poses.tum", "state/joint_states.csv"})
    t.push_back({"run_" + fs::path(f).filename().string(), root / f, open});
  return t;
}

/// Every target fuzzed; the failures listed (the first five of each kept as files beside it).
void fuzz_all(const std::vector<Target>& targets, std::uint64_t seed) {
  std::vector<std::string> failures;
  for (std::size_t i = 0; i < targets.size(); ++i) {
    const std::vector<std::string> f = fuzz(targets[i], seed + i);
    failures.insert(failures.end(), f.begin(), f.end());
  }
  for (std::size_t i = 0; i < failures.size() && i < 20; ++i) ADD_FAILURE() << failures[i];
  EXPECT_TRUE(failures.empty()) << failures.size() << " failures";
}

/// Opening (and reading every sweep of) a run directory fails with an InputError whose message
/// names `file` and contains `says`.
void expect_refused(const fs::path& root, const std::string& file, const std::string& says) {
  try {
    const RunDirectory run = open_run_directory(root);
    for (const ScanInfo& s : run.scans) (void)run.read_scan(s), (void)run.read_scan_truth(s);
    ADD_FAILURE() << file << ": accepted, expected '" << says << "'";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(file), std::string::npos) << what;
    EXPECT_NE(what.find(says), std::string::npos) << what;
  }
}

// Each error a run directory can hold, named with its file (issue #20 item 6).
TEST(RunDirectoryErrors, EachIsNamedWithItsFile) {
  const fs::path root = test::temp_dir("run_errors") / "run";
  const auto with = [&](const std::string& file, const std::string& bytes) {
    fs::remove_all(root);
    write_run(root);
    fs::create_directories(root / "truth" / "scans" / "H");
    write_npy_int32(root / "truth" / "scans" / "H" / "000000.npy", std::vector<std::int32_t>(12, -1));
    if (!file.empty()) write_bytes(root / file, bytes);
  };
  with("", "");
  EXPECT_NO_THROW((void)open_run_directory(root));
  with("run.json", R"({"format_version": 1, "scenario": )");
  expect_refused(root, "run.json", "invalid JSON");
  with("run.json", R"({"format_version": 2})");
  expect_refused(root, "run.json", "format_version 2");
  with("run.json", R"({"scenario": "exp1"})");
  expect_refused(root, "run.json", "format_version");
  with("state/cabin_poses.tum", "0.0 0 0 0 0 0 0 1\n0.1 0 0 0 0 0 0 1\n0.1 0 0 0 0 0 0 1\n");
  expect_refused(root, "cabin_poses.tum", "timestamps must increase");
  with("state/cabin_poses.tum", "# no poses\n");
  expect_refused(root, "cabin_poses.tum", "no poses");
  with("state/joint_states.csv", "time,swing\n0.2,0.1\n0.1,0.2\n");
  expect_refused(root, "joint_states.csv", "time goes backwards");
  with("state/joint_states.csv", "time,swing\n0.0,0.1,7\n");
  expect_refused(root, "joint_states.csv", "expected 2 values");
  with("scans/index.csv", "sensor,index,t_start,t_end,num_points,file\nH,0,0,0.1,13,scans/H/000000.ply\n");
  expect_refused(root, "000000.ply", "the scan index says 13");
  with("scans/index.csv", "sensor,index,t_start,t_end,num_points,file\nX,0,0,0.1,12,scans/H/000000.ply\n");
  expect_refused(root, "index.csv", "sensor 'X' has no extrinsics");
  with("scans/index.csv", "sensor,index,t_start,t_end,num_points,file\nH,0,0.2,0.1,12,scans/H/000000.ply\n");
  expect_refused(root, "index.csv", "t_end before t_start");
  with("extrinsics.json", R"({"T_cabin_sensor": {"H": [[1,0,0,0],[0,1,0,0],[0,0,1,0]]}})");
  expect_refused(root, "extrinsics.json", "T_cabin_sensor");
  with("extrinsics.json", R"({"T_cabin_sensor": {"H": [[2,0,0,0],[0,2,0,0],[0,0,2,0],[0,0,0,1]]}})");
  expect_refused(root, "extrinsics.json", "not a rigid transform");
  with("extrinsics.json", R"({"sensors": {}})");
  expect_refused(root, "extrinsics.json", "T_cabin_sensor");
  with("truth/scans/H/000000.npy", "");
  write_npy_int32(root / "truth" / "scans" / "H" / "000000.npy", std::vector<std::int32_t>(5, -1));
  expect_refused(root, "000000.npy", "5 labels for 12 points");
  fs::remove_all(root);
  write_run(root);
  fs::remove(root / "robot.json");
  expect_refused(root, "robot.json", "robot.json");
}

TEST(Fuzz, PointCloudReadersAcceptOrRefuseEveryMutatedFile) {
  fuzz_all(cloud_targets(test::temp_dir("fuzz_clouds")), 1000);
}

TEST(Fuzz, TrajectoryColmapAndNpyReadersAcceptOrRefuseEveryMutatedFile) {
  fuzz_all(text_targets(test::temp_dir("fuzz_text")), 2000);
}

TEST(Fuzz, RunDirectoriesOpenOrAreRefusedWhateverFileIsMutated) {
  fuzz_all(run_targets(test::temp_dir("fuzz_run") / "run"), 3000);
}

}  // namespace
}  // namespace cairn::io::fuzzing
