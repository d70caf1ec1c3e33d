// The experiment's report (report/report.hpp, issue #18): chart and encoding helpers against
// known answers, and a report of a small hand-made experiment written, complete, and opened in
// headless Chromium (no console error, the viewer drew). The report of a real run is opened by
// tests/eval/test_experiment.cpp.
#include "cairn/report/report.hpp"

#include <gtest/gtest.h>

#include <unistd.h>

#include <fstream>
#include <iterator>

#include "cairn/report/svg.hpp"
#include "support/browser.hpp"

namespace cairn::report {
namespace {

std::size_t count(const std::string& s, const std::string& what) {
  std::size_t n = 0;
  for (auto p = s.find(what); p != std::string::npos; p = s.find(what, p + 1)) ++n;
  return n;
}

void expect_ticks(const std::vector<double>& got, const std::vector<double>& expected) {
  ASSERT_EQ(got.size(), expected.size());
  for (std::size_t i = 0; i < got.size(); ++i) EXPECT_NEAR(got[i], expected[i], 1e-12) << i;
}

TEST(ReportHelpers, NiceTicksBase64AndColors) {
  expect_ticks(nice_ticks(0.0, 1.0), {0.0, 0.2, 0.4, 0.6, 0.8, 1.0});
  expect_ticks(nice_ticks(0.0, 230.0), {0.0, 50.0, 100.0, 150.0, 200.0});
  expect_ticks(nice_ticks(-3.0, 3.0), {-2.0, 0.0, 2.0});  // step 1.2 rounds up to 2
  EXPECT_EQ(base64("Man"), "TWFu");
  EXPECT_EQ(base64("Ma"), "TWE=");
  EXPECT_EQ(base64("M"), "TQ==");
  EXPECT_EQ(base64(""), "");
  const Rgb red = object_color(0);  // hue 0, HSL(0, 0.65, 0.5)
  EXPECT_EQ(int(red.r), 210);
  EXPECT_EQ(int(red.g), 45);
  EXPECT_EQ(int(red.b), 45);
  const Rgb a = object_color(1), b = object_color(2);
  EXPECT_NE(std::tie(a.r, a.g, a.b), std::tie(b.r, b.g, b.b));
  EXPECT_EQ(xml_escape("a<b & \"c\">"), "a&lt;b &amp; &quot;c&quot;&gt;");
}

TEST(ReportHelpers, CloudsEncodeAsCentimetreInt16) {
  PointCloud c;
  c.origin = Vec3d(100.0, 200.0, 10.0);
  c.points = {Vec3f(1.234f, -2.5f, 0.0f), Vec3f(0.0f, 0.0f, 400.0f)};  // the second beyond +-327 m: clamped
  const nlohmann::json j = encode_cloud(c, Vec3d(100.0, 200.0, 0.0));
  EXPECT_EQ(j["n"], 2);
  // 123 cm, -250 cm, 1000 cm; 0, 0, 32767 (clamped), little-endian int16.
  const std::string expected_bytes = std::string("\x7b\x00\x06\xff\xe8\x03\x00\x00\x00\x00\xff\x7f", 12);
  EXPECT_EQ(j["xyz"], base64(expected_bytes));
}

TEST(ReportCharts, EveryPointDrawnAndClippedValuesCounted) {
  const Series s{.name = "a", .x = {1, 2, 3, 4}, .y = {0.1, 0.2, 5.0, 0.3}};
  const std::string svg = line_chart({.title = "t", .x_label = "x", .y_label = "y", .y_max = 1.0}, {s});
  EXPECT_EQ(count(svg, "<circle"), 4u);
  EXPECT_NE(svg.find("(1 clipped)"), std::string::npos);
  EXPECT_EQ(count(svg, "<polyline"), 1u);
  const std::string bars = bar_chart({.title = "b"}, {{"x", 1.0}, {"y", 2.0}, {"z", 3.0}});
  EXPECT_EQ(count(bars, "<rect x="), 3u);
  const std::string strips = strip_chart({.title = "s"}, {{"c", {1.0, 0.5, 2.0}, {0.4}}});
  EXPECT_EQ(count(strips, "<circle"), 4u);
  EXPECT_EQ(count(strips, "#d62728"), 1u);  // the one selected grasp
}

/// A stone (a ball of points) on a plane, moved once; one grasp.
eval::ExperimentResult small_experiment() {
  eval::ExperimentResult r;
  r.experiment = "exp1";
  r.seed = 7;
  r.stones = r.stones_tracked = 1;
  PointCloud ground, stone;
  for (int i = -40; i <= 40; ++i)
    for (int j = -40; j <= 40; ++j) ground.points.emplace_back(0.1f * i, 0.1f * j, 0.0f);
  for (int k = 0; k < 2000; ++k) {
    const double u = 2.0 * std::numbers::pi * k / 2000.0 * 37.0, v = std::acos(1.0 - 2.0 * (k + 0.5) / 2000.0);
    stone.points.emplace_back(float(0.4 * std::sin(v) * std::cos(u)), float(0.4 * std::sin(v) * std::sin(u)),
                              float(0.4 + 0.4 * std::cos(v)));
  }
  for (int round = 0; round <= 1; ++round) {
    eval::SceneSnapshot s{.label = round == 0 ? "before moving" : "after round 1", .round = round, .time = 10.0 * round};
    s.map = ground;
    PointCloud moved = stone;
    moved.origin = Vec3d(round * 1.5, 0.0, 0.0);
    s.objects.emplace_back(3, moved);
    s.map_points = ground.size() + stone.size();
    s.true_centroids = {Vec3d(round * 1.5, 0.0, 0.4)};
    r.scene.snapshots.push_back(s);
  }
  r.scene.drone = ground;
  r.scene.drone_points = ground.size();
  r.scene.voxel = 0.08;
  r.scene.trajectory = {{0.0, 0.01, 0.1}, {10.0, 0.02, 0.2}};
  eval::GraspRecord g{.round = 1, .stone = 0, .attempt = 1, .object = 3, .success = true};
  g.T_map_gripper.translation() = Vec3d(0.0, 0.0, 0.4);
  g.opening = 1.0;
  g.target = Eigen::Vector2d(1.5, 0.0);
  g.target_error_m = 0.04;
  g.normalized_costs.all = {{{1.0, 0.5, 2.0}, {1.0, 1.2}, {0.9, 1.1}}};
  g.normalized_costs.selected = {{{0.5}, {1.0}, {0.9}}};
  r.grasps.push_back(g);
  r.rounds.push_back({.round = 1, .objects = {{.object = 3, .stone = 0, .translation_error_m = 0.01,
                                                .rotation_error_deg = 0.5, .target_error_m = 0.04}}});
  r.registration.tries.push_back({.time = 5.0, .accepted = true, .map_points = 5000});
  r.registration.timings.add("segmentation", 50.0);
  r.registration.timings.add("matching", 20.0);
  r.moves = r.placed = r.first_attempt_success = r.within_attempts = 1;
  return r;
}

TEST(Report, WritesEveryFigureAndOpensInChromium) {
  const auto dir = std::filesystem::temp_directory_path() / ("cairn_test_report_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  const ReportFiles files = write_report(dir, small_experiment());
  ASSERT_TRUE(std::filesystem::exists(files.html));
  EXPECT_EQ(files.figures.size(), 9u);
  std::ifstream f(files.html);
  const std::string html{std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
  for (const auto& fig : files.figures) {
    ASSERT_TRUE(std::filesystem::exists(fig)) << fig;
    EXPECT_GT(std::filesystem::file_size(fig), 200u) << fig;
  }
  EXPECT_EQ(count(html, "<svg "), 8u);  // every SVG figure inlined
  EXPECT_EQ(count(html, "data:image/png;base64,"), 1u);
  EXPECT_NE(html.find("Clouds thinned to 8 cm voxels."), std::string::npos);
  EXPECT_EQ(html.find("http://", html.find("<script")), html.find("http://www.w3.org/2000/svg", html.find("<script")))
      << "no network reference besides SVG's namespace";
  test::expect_report_opens(files.html, dir / "screenshot.png");
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace cairn::report
