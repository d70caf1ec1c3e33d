// End-to-end tests of the `cairn` command line: file contracts, exit codes, bad input.
#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "cairn/core/io/io.hpp"
#include "support/test_data.hpp"

using namespace cairn;

namespace {

struct CmdResult {
  int code = -1;
  std::string out;  // stdout
  std::string err;  // stderr
};

CmdResult run(const std::string& args) {
  const auto dir = std::filesystem::temp_directory_path();
  // One stderr file per test: ctest runs the tests of this file in parallel.
  const auto err_file = dir / ("cairn_cli_stderr_" +
                               std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()) + ".txt");
  const std::string cmd = std::string(CAIRN_EXE) + " " + args + " 2>" + err_file.string();
  CmdResult r;
  FILE* pipe = popen(cmd.c_str(), "r");
  std::array<char, 4096> buf{};
  while (std::fgets(buf.data(), int(buf.size()), pipe)) r.out += buf.data();
  const int status = pclose(pipe);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  std::ifstream e(err_file);
  r.err.assign(std::istreambuf_iterator<char>(e), {});
  return r;
}

std::vector<int> read_labels(const std::filesystem::path& f) {
  std::ifstream in(f);
  std::vector<int> v;
  for (int x; in >> x;) v.push_back(x);
  return v;
}

/// A small scene: flat ground and two boxes, written as a binary PLY.
std::filesystem::path small_scene(const std::filesystem::path& dir, bool with_nan = false) {
  PointCloud c;
  for (int i = 0; i < 120; ++i)
    for (int j = 0; j < 120; ++j) c.points.emplace_back(i * 0.03f, j * 0.03f, 0.0f);
  for (const float cx : {1.0f, 2.5f})
    for (int i = 0; i < 15; ++i)
      for (int j = 0; j < 15; ++j)
        for (int k = 0; k < 15; ++k)
          if (i == 0 || j == 0 || k == 14 || i == 14 || j == 14)  // box shell, open bottom
            c.points.emplace_back(cx + i * 0.03f, 1.5f + j * 0.03f, 0.03f + k * 0.03f);
  if (with_nan) c.points[5] = Vec3f(std::nanf(""), 0, 0);
  const auto f = dir / (with_nan ? "scene_nan.ply" : "scene.ply");
  io::write_ply(f, c);
  return f;
}

}  // namespace

TEST(Cli, SegmentWritesTheContractFiles) {
  const auto dir = test::temp_dir("cli_segment");
  const auto cloud = small_scene(dir);
  const CmdResult r = run("segment " + cloud.string() + " --out " + (dir / "out").string());
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["segments"].size(), 2u);
  EXPECT_EQ(j["ground_plane"].size(), 4u);
  for (const char* stage : {"ground", "clustering", "total"}) EXPECT_TRUE(j["timings_ms"].contains(stage)) << stage;
  const auto labels = read_labels(dir / "out" / "labels.txt");
  EXPECT_EQ(labels.size(), io::load_cloud(cloud).size());  // one label per input point
  EXPECT_EQ(labels[0], -1);                                // first point is ground
  EXPECT_EQ(nlohmann::json::parse(std::ifstream(dir / "out" / "segments.json"))["segments"].size(), 2u);
  const PointCloud seg = io::load_cloud(dir / "out" / "segments.ply");
  EXPECT_TRUE(seg.has_colors());
  EXPECT_EQ(seg.labels, labels);
}

TEST(Cli, BadInputExitsWithTwoAndNamesTheProblem) {
  const auto dir = test::temp_dir("cli_bad");
  CmdResult r = run("segment " + (dir / "missing.ply").string() + " --out " + (dir / "o").string());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("missing.ply"), std::string::npos) << r.err;
  std::ofstream(dir / "garbage.ply") << "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nend_header\n1\n";
  r = run("segment " + (dir / "garbage.ply").string() + " --out " + (dir / "o").string());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("garbage.ply"), std::string::npos) << r.err;
  r = run("segment");  // usage error
  EXPECT_EQ(r.code, 2);
  r = run("segment " + small_scene(dir).string() + " --out " + (dir / "o").string() +
          " --set segmentation.ground.d_plan=0.1");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("d_plan"), std::string::npos) << r.err;
}

TEST(Cli, NanPointsFailOrAreDroppedKeepingInputOrder) {
  const auto dir = test::temp_dir("cli_nan");
  const auto cloud = small_scene(dir, true);
  CmdResult r = run("segment " + cloud.string() + " --out " + (dir / "o").string());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("NaN"), std::string::npos) << r.err;
  r = run("segment " + cloud.string() + " --drop-invalid --out " + (dir / "o").string());
  ASSERT_EQ(r.code, 0) << r.err;
  const auto labels = read_labels(dir / "o" / "labels.txt");
  const auto n = io::read_cloud(cloud, {.drop_non_finite = true}).num_input;
  ASSERT_EQ(labels.size(), n);
  EXPECT_EQ(labels[5], -2);  // the NaN point: no object
  EXPECT_EQ(labels[4], -1);
}

TEST(Cli, ConfigDumpRoundTripsThroughAFile) {
  const auto dir = test::temp_dir("cli_config");
  const CmdResult a = run("config --dump --set segmentation.ground.d_plane=0.07 --set voxel.n_min=2");
  ASSERT_EQ(a.code, 0) << a.err;
  EXPECT_NE(a.out.find("d_plane: 0.07"), std::string::npos);
  std::ofstream(dir / "c.yaml") << a.out;
  const CmdResult b = run("config --dump --config " + (dir / "c.yaml").string());
  ASSERT_EQ(b.code, 0) << b.err;
  EXPECT_EQ(a.out, b.out);
  const CmdResult defaults = run("config --json");
  const auto j = nlohmann::json::parse(defaults.out);
  EXPECT_DOUBLE_EQ(j["voxel"]["res_voxel"].get<double>(), 0.03);              // Table 3
  EXPECT_DOUBLE_EQ(j["segmentation"]["ground"]["d_plane"].get<double>(), 0.10);  // Table 3
}

TEST(Cli, DemoSimulatesMapsAndSegmentsTheSite) {
  // A short run (8 s: half a swing cycle, enough to see the whole front) without the drone.
  const auto dir = test::temp_dir("cli_demo");
  const auto out = dir / "demo";
  const CmdResult r = run("demo --seed 1 --duration 8 --no-drone --out " + out.string());
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  // Stones seen from one side only (no drone yet): most are found whole, none is terrain.
  EXPECT_GE(j["score"]["found"].get<int>(), 5);
  EXPECT_EQ(j["score"]["terrain_segments"].get<int>(), 0);
  EXPECT_EQ(j["stones"].get<int>(), 7);
  EXPECT_GT(j["map_points"].get<int>(), 100000);
  EXPECT_LT(j["ate_mapped"]["rmse_m"].get<double>(), 0.05);
  for (const char* f : {"top_view.png", "map.ply", "trajectory.txt", "segments.json", "summary.json", "run/run.json"})
    EXPECT_TRUE(std::filesystem::exists(out / f)) << f;
  EXPECT_GT(std::filesystem::file_size(out / "top_view.png"), 10000u);
  EXPECT_NE(r.err.find("[4/4]"), std::string::npos);  // progress on stderr
  EXPECT_NE(r.err.find("scan pairs"), std::string::npos);
}

TEST(Cli, SimulateWritesARunDirectory) {
  const auto dir = test::temp_dir("cli_simulate");
  const auto out = dir / "run";
  const CmdResult r = run("simulate --scenario pile --seed 2 --duration 0.5 --no-drone --out " + out.string());
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_GE(j["sweeps"].get<int>(), 8);
  EXPECT_GT(j["points"].get<int>(), 50000);
  for (const char* f : {"run.json", "robot.json", "extrinsics.json", "scans/index.csv", "state/cabin_poses.tum",
                        "state/joint_states.csv", "truth/site.json", "truth/cabin_poses.tum", "preview.png"})
    EXPECT_TRUE(std::filesystem::exists(out / f)) << f;
  EXPECT_NE(r.err.find("LiDAR sweeps"), std::string::npos);  // progress on stderr
  // A second run into the same directory is refused (exit 2), --overwrite replaces it.
  const CmdResult again = run("simulate --scenario pile --seed 2 --duration 0.5 --no-drone --out " + out.string());
  EXPECT_EQ(again.code, 2);
  EXPECT_NE(again.err.find("not empty"), std::string::npos) << again.err;
  EXPECT_EQ(run("simulate --scenario pile --seed 3 --duration 0.5 --no-drone --overwrite --out " + out.string()).code, 0);
  // Unknown scenario and bad --set values: exit 2 with the reason.
  const CmdResult bad = run("simulate --scenario moon --out " + (dir / "x").string());
  EXPECT_EQ(bad.code, 2);
  EXPECT_NE(bad.err.find("unknown scenario 'moon'"), std::string::npos) << bad.err;
  const CmdResult bad_set =
      run("simulate --duration 0.5 --set simulation.lidar.rate=-3 --out " + (dir / "y").string());
  EXPECT_EQ(bad_set.code, 2);
  EXPECT_NE(bad_set.err.find("rate"), std::string::npos) << bad_set.err;
}

TEST(Cli, MapWritesAMapAndATrajectory) {
  const auto dir = test::temp_dir("cli_map");
  const auto run_dir = dir / "run";
  ASSERT_EQ(run("simulate --scenario exp1 --seed 1 --duration 2 --no-drone --out " + run_dir.string()).code, 0);
  const auto map = dir / "map.ply";
  const auto traj = dir / "traj.txt";
  const CmdResult r = run("map " + run_dir.string() + " --out " + map.string() + " --trajectory " + traj.string());
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_GT(j["nodes"].get<int>(), 5);
  EXPECT_GT(j["map_points"].get<int>(), 10000);
  EXPECT_TRUE(j["timings_ms"].contains("icp"));
  EXPECT_TRUE(j.contains("ate_raw") && j.contains("ate_mapped"));
  EXPECT_TRUE(std::filesystem::exists(map));
  EXPECT_TRUE(std::filesystem::exists(traj));
  EXPECT_NE(r.err.find("scan pairs"), std::string::npos);  // progress on stderr
  const CmdResult missing = run("map " + (dir / "nothing").string() + " --out " + map.string());
  EXPECT_EQ(missing.code, 2);
  EXPECT_NE(missing.err.find("nothing"), std::string::npos) << missing.err;
  const CmdResult bad_set = run("map " + run_dir.string() + " --out " + map.string() + " --set mapping.m=0");
  EXPECT_EQ(bad_set.code, 2);
  EXPECT_NE(bad_set.err.find("mapping.m"), std::string::npos) << bad_set.err;
}
