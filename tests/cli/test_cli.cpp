// End-to-end tests of the `cairn` command line: file contracts, exit codes, bad input.
#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "cairn/core/io/io.hpp"
#include <iterator>
#include "support/shared_runs.hpp"
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

/// A small scene: flat ground and two boxes, written as a binary PLY (the second box moved by
/// `shift` in x).
std::filesystem::path small_scene(const std::filesystem::path& dir, bool with_nan = false, float shift = 0.0f,
                                  const std::string& name = "") {
  PointCloud c;
  for (int i = 0; i < 120; ++i)
    for (int j = 0; j < 120; ++j) c.points.emplace_back(i * 0.03f, j * 0.03f, 0.0f);
  for (const float cx : {1.0f, 2.5f + shift})
    for (int i = 0; i < 15; ++i)
      for (int j = 0; j < 15; ++j)
        for (int k = 0; k < 15; ++k)
          if (i == 0 || j == 0 || k == 14 || i == 14 || j == 14)  // box shell, open bottom
            c.points.emplace_back(cx + i * 0.03f, 1.5f + j * 0.03f, 0.03f + k * 0.03f);
  if (with_nan) c.points[5] = Vec3f(std::nanf(""), 0, 0);
  const auto f = dir / (!name.empty() ? name : with_nan ? "scene_nan.ply" : "scene.ply");
  io::write_ply(f, c);
  return f;
}

TEST(Cli, ScaleAndRegisterFollowTheContract) {
  const auto dir = test::temp_dir("cli_register");
  // exp1 seed 1, 8 s, mapped (the CLI's simulate and map are tested below on shorter runs).
  const auto shared = test::shared_run(test::kExp1Drone8s);
  const auto run_dir = shared / "run";
  const auto map = shared / "map.ply";
  const std::string drone = (run_dir / "drone" / "cloud.ply").string();
  const std::string sfm = " --sfm " + (run_dir / "drone" / "sparse").string() + " --metric " +
                          (run_dir / "drone" / "vins_trajectory.tum").string();

  // cairn scale: the similarity from the SfM frame to the metric one, applied to the cloud.
  const auto scaled = dir / "drone_metric.ply";
  const CmdResult s = run("scale" + sfm + " --cloud " + drone + " --out " + scaled.string());
  ASSERT_EQ(s.code, 0) << s.err;
  const auto sj = nlohmann::json::parse(s.out);
  std::ifstream truth_file(run_dir / "truth" / "drone.json");
  const double true_scale = nlohmann::json::parse(truth_file)["scale_map_per_sfm_unit"].get<double>();
  EXPECT_NEAR(sj["scale"].get<double>() / true_scale, 1.0, 2e-3);
  EXPECT_LT(sj["rms_m"].get<double>(), 0.1);
  EXPECT_TRUE(std::filesystem::exists(scaled));

  // cairn register with scale recovery: the JSON contract, errors against the truth, the files.
  const auto out = dir / "reg";
  const CmdResult r = run("register " + drone + " " + map.string() + sfm + " --truth " +
                          (run_dir / "truth" / "drone.json").string() + " --out " + out.string());
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_TRUE(j["success"].get<bool>());
  EXPECT_EQ(j["T_target_source"].size(), 4u);
  EXPECT_LT(j["rmse"].get<double>(), 0.03);
  EXPECT_GE(j["matched_segments"].get<int>(), 5);
  EXPECT_GT(j["candidates"].get<int>(), 0);
  for (const char* stage : {"segmentation_source", "segmentation_target", "keypoints", "descriptors", "matching",
                            "verification", "refinement", "total"})
    EXPECT_TRUE(j["timings_ms"].contains(stage)) << stage;
  EXPECT_LT(j["error"]["rotation_deg"].get<double>(), 1.0);
  EXPECT_LT(j["error"]["translation_m"].get<double>(), 0.06);
  EXPECT_NEAR(j["error"]["scale_ratio"].get<double>(), 1.0, 2e-3);
  for (const char* f : {"merged.ply", "merged_segments.json", "source_aligned.ply", "result.json"})
    EXPECT_TRUE(std::filesystem::exists(out / f)) << f;

  // The same cloud without scale recovery (SfM scale): no transform passes -> exit 3, a reason.
  const CmdResult unscaled = run("register " + drone + " " + map.string());
  EXPECT_EQ(unscaled.code, 3) << unscaled.err;
  const auto uj = nlohmann::json::parse(unscaled.out);
  EXPECT_FALSE(uj["success"].get<bool>());
  EXPECT_FALSE(uj["reason"].get<std::string>().empty());

  // Bad input: exit 2 naming the problem.
  const CmdResult missing = run("register " + (dir / "none.ply").string() + " " + map.string());
  EXPECT_EQ(missing.code, 2);
  EXPECT_NE(missing.err.find("none.ply"), std::string::npos) << missing.err;
  const CmdResult half = run("register " + drone + " " + map.string() + " --sfm " + (run_dir / "drone" / "sparse").string());
  EXPECT_EQ(half.code, 2);
  EXPECT_NE(half.err.find("--metric"), std::string::npos) << half.err;
}

TEST(Cli, ProtocolRegistersWhileMapping) {
  const auto dir = test::temp_dir("cli_protocol");
#if defined(__SANITIZE_ADDRESS__)
  // The sanitizers run the command's path once, on one trial; the figures are asserted in Release.
  const CmdResult once = run("protocol --seeds 1 --first-seed 3 --duration 5 --every 5 --out " + dir.string());
  ASSERT_EQ(once.code, 0) << once.err;
  EXPECT_EQ(nlohmann::json::parse(once.out)["all"]["trials"].get<int>(), 1);
  EXPECT_GT(nlohmann::json::parse(once.out)["all"]["reoptimize_ms_median"].get<double>(), 1.0);
  EXPECT_TRUE(std::filesystem::exists(dir / "protocol.json"));
  EXPECT_NE(once.err.find("t =  5.0 s"), std::string::npos);  // progress on stderr
  return;
#endif
  const CmdResult r = run("protocol --seeds 1 --first-seed 3 --duration 10 --every 5 --out " + dir.string());
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["all"]["trials"].get<int>(), 2);
  EXPECT_EQ(j["all"]["false_positives"].get<int>(), 0);
  // After 10 s of swinging the map covers the stones: the second trial succeeds.
  EXPECT_GE(j["all"]["success"].get<int>(), 1);
  EXPECT_FALSE(j["time_to_first_success_s"][0].is_null());
  EXPECT_LE(j["time_to_first_success_s"][0].get<double>(), 10.0);
  // Against the map as built (its own offset from the truth removed) the registration meets the
  // issue's 0.3 deg / 2 cm; against the truth it also carries the map's offset (seed 3: 3.7 cm at
  // 5 s, 1.7 cm at 10 s).
  EXPECT_LT(j["all"]["rotation_error_vs_map_deg"]["max"].get<double>(), 0.3);
  EXPECT_LT(j["all"]["translation_error_vs_map_m"]["max"].get<double>(), 0.02);
  // Each registration got a reoptimised map (full pose graph, map rebuilt), not the windowed one.
  EXPECT_FALSE(j["windowed_map"].get<bool>());
  EXPECT_GT(j["all"]["reoptimize_ms_median"].get<double>(), 1.0);  // a full solve + rebuild: tens of ms
  EXPECT_TRUE(std::filesystem::exists(dir / "protocol.json"));
  EXPECT_TRUE(std::filesystem::exists(dir / "trials.png"));
  EXPECT_NE(r.err.find("t = 10.0 s"), std::string::npos);  // progress on stderr
  // --windowed-map: the map as the windowed updates left it, no reoptimisation.
  const CmdResult w =
      run("protocol --seeds 1 --first-seed 3 --duration 5 --every 5 --windowed-map --out " + (dir / "windowed").string());
  ASSERT_EQ(w.code, 0) << w.err;
  const auto jw = nlohmann::json::parse(w.out);
  EXPECT_TRUE(jw["windowed_map"].get<bool>());
  EXPECT_EQ(jw["all"]["trials"].get<int>(), 1);
  EXPECT_EQ(jw["all"]["reoptimize_ms_median"].get<double>(), 0.0);
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

std::string file_bytes(const std::filesystem::path& f) {
  std::ifstream in(f, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

TEST(Cli, ObjectsUpdateListShowHistoryExport) {
  const auto dir = test::temp_dir("cli_objects");
  const std::string db = (dir / "objects.db").string();
  std::filesystem::remove(db);
  CmdResult r = run("objects update --db " + db + " --map " + small_scene(dir).string() + " --time 1");
  ASSERT_EQ(r.code, 0) << r.err;
  auto j = nlohmann::json::parse(r.out);
  ASSERT_EQ(j["created"].size(), 2u) << r.out;
  r = run("objects list --db " + db);
  ASSERT_EQ(r.code, 0) << r.err;
  j = nlohmann::json::parse(r.out);
  ASSERT_EQ(j["objects"].size(), 2u);
  const auto& first = j["objects"][0];
  for (const char* k : {"id", "status", "centroid", "num_points", "updates"}) EXPECT_TRUE(first.contains(k)) << k;
  EXPECT_EQ(first["status"], "on_ground");
  const std::string id = std::to_string(first["id"].get<int>());
  r = run("objects show " + id + " --db " + db);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(nlohmann::json::parse(r.out)["source"], "segmentation");
  r = run("objects export " + id + " --db " + db + " --out " + (dir / "obj.ply").string());
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(io::load_cloud(dir / "obj.ply").size(), first["num_points"].get<std::size_t>());
  // The same scene again: both matched, nothing new. The second box pushed 40 cm: moved, no duplicate.
  r = run("objects update --db " + db + " --map " + (dir / "scene.ply").string() + " --time 2");
  ASSERT_EQ(r.code, 0) << r.err;
  j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["matched"].size(), 2u) << r.out;
  EXPECT_EQ(j["op"], 0);  // nothing to store
  double x_before = 0;  // the second box: the larger centroid x
  const auto listed = nlohmann::json::parse(run("objects list --db " + db).out);
  for (const auto& o : listed["objects"]) x_before = std::max(x_before, o["centroid"][0].get<double>());
  r = run("objects update --db " + db + " --map " + small_scene(dir, false, 0.4f, "pushed.ply").string() + " --time 3");
  ASSERT_EQ(r.code, 0) << r.err;
  j = nlohmann::json::parse(r.out);
  ASSERT_EQ(j["moved"].size(), 1u) << r.out;
  EXPECT_EQ(j["created"].size(), 0u) << r.out;
  const std::string moved = std::to_string(j["moved"][0]["object"].get<int>());
  const auto after = nlohmann::json::parse(run("objects show " + moved + " --db " + db).out);
  EXPECT_NEAR(after["centroid"][0].get<double>() - x_before, 0.4, 0.01);
  EXPECT_NE(after["reason"].get<std::string>().find("bumped"), std::string::npos) << after;
  r = run("objects history " + moved + " --db " + db);
  ASSERT_EQ(r.code, 0) << r.err;
  j = nlohmann::json::parse(r.out);
  ASSERT_EQ(j["history"].size(), 2u);
  EXPECT_EQ(j["history"][0]["cause"], "created");
  EXPECT_EQ(j["history"][1]["cause"], "reassociated");
  EXPECT_EQ(nlohmann::json::parse(run("objects list --db " + db).out)["objects"].size(), 2u);
}

TEST(Cli, ObjectsRefusesMissingForeignAndCorruptDatabases) {
  const auto dir = test::temp_dir("cli_objects_bad");
  const auto ply = small_scene(dir);
  CmdResult r = run("objects list --db " + (dir / "missing.db").string());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("missing.db"), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(dir / "missing.db"));
  const std::string before = file_bytes(ply);
  for (const char* sub : {"list", "show 1", "history 1"}) {
    r = run(std::string("objects ") + sub + " --db " + ply.string());
    EXPECT_EQ(r.code, 2) << sub;
    EXPECT_NE(r.err.find("scene.ply"), std::string::npos) << r.err;
  }
  r = run("objects update --db " + ply.string() + " --map " + ply.string());  // the writer too
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(file_bytes(ply), before);
  std::ofstream(dir / "empty.db").close();
  r = run("objects update --db " + (dir / "empty.db").string() + " --map " + ply.string());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("empty file"), std::string::npos) << r.err;
  EXPECT_EQ(std::filesystem::file_size(dir / "empty.db"), 0u);
  const std::string db = (dir / "objects.db").string();
  std::filesystem::remove(db);
  ASSERT_EQ(run("objects update --db " + db + " --map " + ply.string()).code, 0);
  r = run("objects show 99 --db " + db);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("no object 99"), std::string::npos) << r.err;
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

TEST(Cli, PipelineSimulatesMapsRegistersAndSegmentsTheSite) {
  // A short run (8 s: half a swing cycle, enough to see the whole front) with the drone survey.
  const auto dir = test::temp_dir("cli_pipeline");
  const auto out = dir / "pipeline";
  const CmdResult r = run("pipeline --seed 1 --duration 8 --out " + out.string());
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  // The drone cloud lands on the map (the map's own georeferencing error is ~2 cm).
  const auto& reg = j["registration"];
  ASSERT_TRUE(reg["accepted"].get<bool>()) << reg.dump();
  EXPECT_LT(reg["rotation_error_deg"].get<double>(), 1.0);
  EXPECT_LT(reg["translation_error_m"].get<double>(), 0.06);
  EXPECT_LT(reg["error_vs_map"]["rotation_deg"].get<double>(), 0.3);
  EXPECT_LT(reg["error_vs_map"]["translation_m"].get<double>(), 0.02);
  EXPECT_LT(std::abs(reg["scale_error"].get<double>()), 2e-3);
  EXPECT_GE(reg["matched_segments"].get<int>(), 5);
  // Segmenting the merged map (LiDAR sides + drone tops): most stones whole, none is terrain.
  EXPECT_GE(j["score"]["found"].get<int>(), 5);
  EXPECT_EQ(j["score"]["terrain_segments"].get<int>(), 0);
  EXPECT_EQ(j["stones"].get<int>(), 7);
  EXPECT_GT(j["map_points"].get<int>(), 100000);
  EXPECT_GT(j["segmented_points"].get<int>(), j["map_points"].get<int>());
  EXPECT_LT(j["ate_mapped"]["rmse_m"].get<double>(), 0.05);
  for (const char* f : {"top_view.png", "map.ply", "merged_map.ply", "drone_aligned.ply", "trajectory.txt",
                        "segments.json", "summary.json", "run/run.json"})
    EXPECT_TRUE(std::filesystem::exists(out / f)) << f;
  EXPECT_GT(std::filesystem::file_size(out / "top_view.png"), 10000u);
  EXPECT_NE(r.err.find("[5/5]"), std::string::npos);  // progress on stderr
  EXPECT_NE(r.err.find("scan pairs"), std::string::npos);
}

TEST(Cli, PipelineWithoutDroneSegmentsTheMapAlone) {
  const auto dir = test::temp_dir("cli_pipeline_no_drone");
  const CmdResult r = run("pipeline --seed 2 --duration 4 --no-drone --out " + (dir / "demo").string());
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_TRUE(j["registration"].is_string());  // "skipped (no drone survey)"
  EXPECT_EQ(j["segmented_points"].get<int>(), j["map_points"].get<int>());
  EXPECT_GE(j["segments"].get<int>(), 3);
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
  EXPECT_EQ(run("map --out " + map.string()).code, 2);  // neither RUN_DIR nor --bag
}

// The run as a rosbag (docs/ros.md): `cairn simulate --bag` writes it beside the run directory,
// `cairn map --bag` maps straight from it; a cairn built without ROS refuses --bag with exit 2.
TEST(Cli, SimulateAndMapThroughARosbag) {
  const auto dir = test::temp_dir("cli_bag");
  const auto bag = dir / "run.bag";
#if defined(CAIRN_WITH_ROS)
  const CmdResult s = run("simulate --scenario exp1 --seed 1 --duration 2 --no-drone --out " + (dir / "run").string() +
                          " --bag " + bag.string());
  ASSERT_EQ(s.code, 0) << s.err;
  const auto sj = nlohmann::json::parse(s.out);
  EXPECT_EQ(sj["bag"]["messages"]["/state_estimate/odometry"].get<int>(), 201);  // 100 Hz over 2 s
  EXPECT_GT(sj["bag"]["messages"]["/lidar_h/velodyne_points"].get<int>(), 15);
  const CmdResult from_dir = run("map " + (dir / "run").string() + " --out " + (dir / "a.ply").string());
  const CmdResult from_bag = run("map --bag " + bag.string() + " --out " + (dir / "b.ply").string());
  ASSERT_EQ(from_dir.code, 0) << from_dir.err;
  ASSERT_EQ(from_bag.code, 0) << from_bag.err;
  const auto a = nlohmann::json::parse(from_dir.out), b = nlohmann::json::parse(from_bag.out);
  EXPECT_EQ(b["nodes"], a["nodes"]);
  EXPECT_NEAR(b["map_points"].get<double>() / a["map_points"].get<double>(), 1.0, 0.01);
  const CmdResult both = run("map " + (dir / "run").string() + " --bag " + bag.string() + " --out " + (dir / "c.ply").string());
  EXPECT_EQ(both.code, 2);
  const CmdResult missing = run("map --bag " + (dir / "none.bag").string() + " --out " + (dir / "c.ply").string());
  EXPECT_EQ(missing.code, 2);
  EXPECT_NE(missing.err.find("none.bag"), std::string::npos) << missing.err;
#else
  const CmdResult r = run("map --bag " + bag.string() + " --out " + (dir / "c.ply").string());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("without ROS"), std::string::npos) << r.err;
#endif
}

TEST(Cli, RegisterIndoorFragmentsWithThePreset) {
  // config/indoor_fragments.yaml: descriptor-only registration of two real 3DMatch fragments.
  CAIRN_REQUIRE_REAL_DATA("geotransformer-3dmatch-demo/src.xyz");
  const std::string d = test::real_data("geotransformer-3dmatch-demo").string();
  const std::string preset = std::string(CAIRN_SOURCE_DIR) + "/config/indoor_fragments.yaml";
  const CmdResult r = run("register " + d + "/src.xyz " + d + "/ref.xyz --config " + preset);
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_TRUE(j["success"].get<bool>());
  EXPECT_EQ(j["matched_segments"].get<int>(), 0);
  Eigen::Matrix3d R;
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b) R(a, b) = j["T_target_source"][a][b].get<double>();
  // gt.npy's rotation (tests/registration/test_real_3dmatch.cpp checks the full pose).
  Eigen::Matrix3d R_gt;
  R_gt << 0.955871, -0.153547, 0.250322, 0.174607, 0.982516, -0.064088, -0.236119, 0.104974, 0.966004;
  EXPECT_LT(Eigen::AngleAxisd(R * R_gt.transpose()).angle(), 2.0 * M_PI / 180.0);
  // Without the preset (Table 3 radii, segments on): nothing to segment indoors -> exit 3.
  const CmdResult plain = run("register " + d + "/src.xyz " + d + "/ref.xyz");
  EXPECT_EQ(plain.code, 3) << plain.err;
}

TEST(Cli, GraspTrialOnASettledScenarioSite) {
  // The contract of `cairn grasp-trial` (issue #15): success, failure_reasons, sim_time,
  // wall_time and initial_settle.stone_poses (each stone's pose relative to the generated site,
  // which is settled in the physics: the trial's settle-in moves no stone).
  const CmdResult r = run("grasp-trial --scenario exp1 --seed 1 --stone 3");
  ASSERT_TRUE(r.code == 0 || r.code == 3) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  for (const char* key : {"success", "failure_reasons", "sim_time", "wall_time", "trace", "free_stones", "site_settle"}) {
    EXPECT_TRUE(j.contains(key)) << key;
  }
  EXPECT_EQ(j["success"].get<bool>(), r.code == 0);
  EXPECT_GT(j["sim_time"].get<double>(), 0.0);
  EXPECT_TRUE(j["site_settle"]["settled"].get<bool>());
  const auto& poses = j["initial_settle"]["stone_poses"];
  ASSERT_EQ(poses.size(), 7u);
  for (const auto& T : poses) {  // about the world origin: 0.1 deg at 5 m is 9 mm
    for (int row = 0; row < 3; ++row) {
      EXPECT_NEAR(T[row][3].get<double>(), 0.0, 0.01);
      EXPECT_NEAR(T[row][row].get<double>(), 1.0, 1e-4);
    }
  }
  EXPECT_EQ(j["trace"]["time"].size(), j["trace"]["opening"].size());
  EXPECT_EQ(j["trace"]["time"].size(), j["trace"]["jaw_angle"].size());
  EXPECT_EQ(run("grasp-trial --scenario exp1 --seed 1 --stone 7").code, 2);  // no such stone
}

TEST(Cli, GraspBaselinePrintsTheTableAndWritesEveryTrial) {
#if defined(__SANITIZE_ADDRESS__)
  GTEST_SKIP() << "the baseline's path runs under the sanitizers in test_eval; this is its CLI in Release";
#endif
  const std::filesystem::path out = test::temp_dir("cli_grasp_baseline") / "baseline.json";
  const CmdResult r = run("grasp-baseline --scenarios exp1 --seeds 1 --out " + out.string());
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("success "), std::string::npos) << r.out;
  std::ifstream in(out);
  const auto j = nlohmann::json::parse(in);
  ASSERT_EQ(j["trials"].size(), 7u);
  int successes = 0;
  for (const auto& t : j["trials"]) successes += t["success"].get<bool>() ? 1 : 0;
  EXPECT_EQ(j["summary"]["successes"].get<int>(), successes);
  EXPECT_EQ(j["summary"]["trials"].get<int>(), 7);
  EXPECT_EQ(run("grasp-baseline --scenarios nope --seeds 1").code, 2);  // unknown scenario
}

TEST(Cli, GraspPlansForTheLargestObjectAndRefusesBadInput) {
  const auto dir = test::temp_dir("cli_grasp");
  const std::string db = (dir / "objects.db").string(), scene = small_scene(dir).string();
  ASSERT_EQ(run("objects update --db " + db + " --map " + scene).code, 0);
  CmdResult r = run("grasp --map " + scene + " --db " + db + " --out " + (dir / "out").string());
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  for (const char* k : {"object", "grasps", "counts", "timings_ms"}) EXPECT_TRUE(j.contains(k)) << k;
  ASSERT_FALSE(j["grasps"].empty());
  const auto& g = j["grasps"][0];
  EXPECT_EQ(g["rank"], 1);
  EXPECT_EQ(g["T_map_gripper"].size(), 4u);
  EXPECT_EQ(g["contacts"].size(), 2u);
  EXPECT_TRUE(g["force_closure"].get<bool>());
  ASSERT_EQ(g["parts"].size(), 3u);  // palm and two jaws, 8 corners each
  for (const auto& part : g["parts"]) EXPECT_EQ(part["vertices"].size(), 8u);
  for (const char* k : {"align_rad", "enclose_m", "dist_m"}) EXPECT_TRUE(g["costs"].contains(k)) << k;
  EXPECT_GE(j["counts"]["hypotheses"].get<int>(), j["counts"]["force_closure"].get<int>());
  for (const char* f : {"planning_cloud.ply", "grasp_1.ply", "costs.png"})
    EXPECT_TRUE(std::filesystem::exists(dir / "out" / f)) << f;
  EXPECT_EQ(io::read_ply_mesh(dir / "out" / "grasp_1.ply").triangles.size(), 36u);
  // Bad input: exit 2; nothing graspable (three points in the air): exit 3.
  EXPECT_EQ(run("grasp --map " + scene + " --object-cloud " + (dir / "missing.ply").string()).code, 2);
  EXPECT_EQ(run("grasp --map " + scene + " --db " + db + " --object-cloud " + scene).code, 2);
  EXPECT_EQ(run("grasp --map " + scene + " --db " + db + " --object 999").code, 2);
  PointCloud tiny;
  tiny.points = {{10.0f, 10.0f, 0.2f}, {10.01f, 10.0f, 0.2f}, {10.0f, 10.01f, 0.2f}};
  io::write_ply(dir / "tiny.ply", tiny);
  r = run("grasp --map " + (dir / "tiny.ply").string() + " --object-cloud " + (dir / "tiny.ply").string());
  EXPECT_EQ(r.code, 3) << r.err;
  EXPECT_TRUE(nlohmann::json::parse(r.out)["grasps"].empty());
}
