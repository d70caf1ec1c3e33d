#include "cairn/report/report.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "cairn/core/error.hpp"
#include "cairn/core/image.hpp"
#include "cairn/core/io/detail.hpp"
#include "cairn/report/assets.hpp"
#include "cairn/report/svg.hpp"

namespace cairn::report {
namespace {

using eval::ExperimentResult;
using eval::GraspRecord;
using eval::SceneSnapshot;
namespace fs = std::filesystem;
using nlohmann::json;

constexpr double kGoldenRatioConjugate = 0.6180339887498949;  // hue step per object id
constexpr double kCm = 100.0;                                 // viewer coordinates: int16 cm
constexpr double kObjectLift = 0.05;  // [m] objects drawn this far above the map in the top views
constexpr double kTopViewMargin = 3.0;  // [m] top views: the objects' and targets' extent grown by this
constexpr std::array<const char*, 6> kPalette = {"#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b"};

std::string hex(Rgb c) {
  char s[8];
  std::snprintf(s, sizeof s, "#%02x%02x%02x", c.r, c.g, c.b);
  return s;
}

/// The scene's origin: the first snapshot's map centre (viewer coordinates stay small).
Vec3d scene_origin(const ExperimentResult& r) {
  for (const SceneSnapshot& s : r.scene.snapshots)
    if (!s.map.empty()) {
      const Aabb b = bounds(s.map.points);
      return s.map.origin + (0.5 * (b.min + b.max)).cast<double>();
    }
  return Vec3d::Zero();
}

/// The gripper's boxes at the grasp, relative to `o`.
json parts_json(const GraspRecord& g, const GripperConfig& gripper, const Vec3d& o) {
  json parts = json::array();
  for (const ConvexPart& p : gripper_parts(gripper, g.opening)) {
    const Eigen::Matrix3d R = g.T_map_gripper.linear() * p.axes;
    const Vec3d c = g.T_map_gripper * p.center - o;
    parts.push_back({{"c", {c.x(), c.y(), c.z()}},
                     {"h", {p.half_extents.x(), p.half_extents.y(), p.half_extents.z()}},
                     {"R", {R(0, 0), R(0, 1), R(0, 2), R(1, 0), R(1, 1), R(1, 2), R(2, 0), R(2, 1), R(2, 2)}}});
  }
  return parts;
}

/// Everything the viewer draws, in coordinates relative to `o`.
json scene_json(const ExperimentResult& r, const Vec3d& o) {
  json snaps = json::array();
  for (const SceneSnapshot& s : r.scene.snapshots) {
    json objects = json::array();
    for (const auto& [id, cloud] : s.objects) {
      json c = encode_cloud(cloud, o);
      c["id"] = id;
      c["color"] = hex(object_color(id));
      objects.push_back(c);
    }
    json truth = json::array();
    for (const Vec3d& c : s.true_centroids) truth.push_back({c.x() - o.x(), c.y() - o.y(), c.z() - o.z()});
    snaps.push_back({{"label", s.label}, {"round", s.round}, {"move", s.move}, {"time", s.time},
                     {"map", encode_cloud(s.map, o)}, {"objects", objects}, {"truth", truth}});
  }
  json grasps = json::array();
  for (const GraspRecord& g : r.grasps) {
    const bool planned = g.opening > 0;
    const Vec3d t = g.T_map_gripper.translation() - o;
    grasps.push_back({{"round", g.round}, {"stone", g.stone}, {"object", g.object}, {"attempt", g.attempt},
                      {"success", g.success}, {"detected", g.detected}, {"color", hex(object_color(g.object))},
                      {"tcp", {t.x(), t.y(), t.z()}},
                      {"target", {g.target.x() - o.x(), g.target.y() - o.y()}},
                      {"parts", planned ? parts_json(g, r.scene.gripper, o) : json::array()}});
  }
  return {{"origin", {o.x(), o.y(), o.z()}}, {"scale", 1.0 / kCm}, {"drone", encode_cloud(r.scene.drone, o)},
          {"snapshots", snaps}, {"grasps", grasps}, {"experiment", r.experiment}, {"seed", r.seed}};
}

// ---- figures ---------------------------------------------------------------------------------

std::string fig_registration_stages(const ExperimentResult& r) {
  std::vector<Bar> bars;
  for (const auto& [stage, ms] : r.registration.timings.stages) bars.push_back({stage, ms});
  return bar_chart({.title = "Registration stages (Table 1 analog)", .x_label = "stage", .y_label = "time [ms]",
                    .width = std::max(560, 70 * int(bars.size()) + 100)},
                   bars);
}

std::string fig_map_sizes(const ExperimentResult& r) {
  Series lidar{.name = "LiDAR map", .color = kPalette[0]}, drone{.name = "drone cloud", .color = kPalette[1]};
  for (const auto& a : r.registration.tries) lidar.x.push_back(a.time), lidar.y.push_back(double(a.map_points));
  for (const SceneSnapshot& s : r.scene.snapshots) lidar.x.push_back(s.time), lidar.y.push_back(double(s.map_points));
  if (!lidar.x.empty()) drone.x = {lidar.x.front(), lidar.x.back()};
  drone.y.assign(drone.x.size(), double(r.scene.drone_points));
  return line_chart({.title = "Map sizes (Table 2 analog)", .x_label = "simulated time [s]", .y_label = "points"},
                    {lidar, drone});
}

std::string fig_registration_tries(const ExperimentResult& r) {
  Series rot{.name = "rotation [deg]", .color = kPalette[0]}, tra{.name = "translation [m]", .color = kPalette[1]};
  for (const auto& a : r.registration.tries) {
    rot.x.push_back(a.time), rot.y.push_back(a.rotation_error_deg), rot.filled.push_back(a.accepted);
    tra.x.push_back(a.time), tra.y.push_back(a.translation_error_m), tra.filled.push_back(a.accepted);
  }
  return line_chart({.title = "Registration triggers (filled: accepted)", .x_label = "triggered at [s]",
                     .y_label = "error vs truth", .y_max = 1.0},
                    {rot, tra});
}

std::string fig_grasp_costs(const ExperimentResult& r) {
  std::vector<Strip> strips(3);
  for (std::size_t k = 0; k < 3; ++k) strips[k].label = grasp::kCostNames[k];
  for (const GraspRecord& g : r.grasps)
    for (std::size_t k = 0; k < 3; ++k) {
      const auto& n = g.normalized_costs;
      strips[k].all.insert(strips[k].all.end(), n.all[k].begin(), n.all[k].end());
      strips[k].selected.insert(strips[k].selected.end(), n.selected[k].begin(), n.selected[k].end());
    }
  return strip_chart({.title = "Grasp costs / median (Fig. 9 analog)",
                      .x_label = "grey: every force-closure grasp, red: the selected", .y_label = "cost / median", .width = 620, .y_max = 3.0, .reference = 1.0,
                      .reference_label = "median"},
                     strips);
}

/// Per-round object pose errors, one series per object (its viewer colour).
std::string fig_pose_errors(const ExperimentResult& r, bool degrees, double tolerance) {
  std::map<std::int64_t, Series> by_object;
  for (const eval::ExperimentRound& round : r.rounds)
    for (const eval::ExperimentObject& o : round.objects) {
      Series& s = by_object[o.object];
      s.name = "object " + std::to_string(o.object);
      s.color = hex(object_color(o.object));
      s.x.push_back(round.round);
      s.y.push_back(degrees ? o.rotation_error_deg : o.translation_error_m);
    }
  std::vector<Series> series;
  for (auto& [_, s] : by_object) series.push_back(std::move(s));
  return line_chart({.title = degrees ? "Object rotation errors after each round" : "Object position errors after each round",
                     .x_label = "round", .y_label = degrees ? "error [deg]" : "error [m]",
                     .y_max = degrees ? 10.0 : 0.5, .x_min = 0.5, .x_max = double(r.rounds.size()) + 0.5,
                     .reference = tolerance, .reference_label = "target", .integer_x = true},
                    series);
}

std::string fig_target_errors(const ExperimentResult& r, double tolerance) {
  Series s{.name = "attempts", .color = kPalette[2], .lines = false};
  for (std::size_t i = 0; i < r.grasps.size(); ++i)
    if (r.grasps[i].target_error_m >= 0) {
      s.x.push_back(double(i + 1)), s.y.push_back(r.grasps[i].target_error_m);
      s.filled.push_back(r.grasps[i].success);
    }
  return line_chart({.title = "Stones vs their targets (filled: the grasp held)", .x_label = "attempt",
                     .y_label = "distance [m]", .y_max = 1.0, .reference = tolerance, .reference_label = "tolerance",
                     .integer_x = true},
                    {s});
}

std::string fig_trajectory(const ExperimentResult& r) {
  Series pos{.name = "position [m]", .color = kPalette[0], .lines = true},
      rot{.name = "rotation [deg]", .color = kPalette[3], .lines = true};
  for (const eval::TrajectorySample& t : r.scene.trajectory) {
    pos.x.push_back(t.time), pos.y.push_back(t.position_error_m);
    rot.x.push_back(t.time), rot.y.push_back(t.rotation_error_deg);
  }
  return line_chart({.title = "Mapped trajectory vs truth", .x_label = "time [s]", .y_label = "error"}, {pos, rot});
}

/// Fig. 11 analog: each captured instant from above, map grey, objects in their colours.
Image map_instants(const ExperimentResult& r, const Vec3d& o, double ppm) {
  Aabb work;  // where the stones are and go
  const auto extend = [&work](const Vec3d& p) {
    work.min = work.min.cwiseMin(p.cast<float>()), work.max = work.max.cwiseMax(p.cast<float>());
  };
  for (const SceneSnapshot& s : r.scene.snapshots)
    for (const auto& [id, cloud] : s.objects)
      for (std::size_t i = 0; i < cloud.size(); ++i) extend(cloud.world(i) - o);
  for (const GraspRecord& g : r.grasps) extend(Vec3d(g.target.x(), g.target.y(), o.z()) - o);
  Aabb box;
  std::vector<std::pair<PointCloud, std::vector<Rgb>>> views;
  for (const SceneSnapshot& s : r.scene.snapshots) {
    PointCloud c;
    std::vector<Rgb> colors;
    const auto add = [&](const PointCloud& p, Rgb col, double lift) {
      for (std::size_t i = 0; i < p.size(); ++i) {
        c.points.push_back((p.world(i) - o + Vec3d(0, 0, lift)).cast<float>());
        colors.push_back(col);
      }
    };
    add(s.map, {170, 170, 170}, 0.0);
    for (const auto& [id, cloud] : s.objects) add(cloud, object_color(id), kObjectLift);
    const Aabb b = bounds(c.points);
    box.min = box.min.cwiseMin(b.min), box.max = box.max.cwiseMax(b.max);
    views.emplace_back(std::move(c), std::move(colors));
  }
  if (views.empty()) return Image(1, 1);
  if (work.min.x() <= work.max.x()) {
    const Vec3f m{float(kTopViewMargin), float(kTopViewMargin), 0.0f};
    box.min.head<2>() = box.min.head<2>().cwiseMax((work.min - m).head<2>());
    box.max.head<2>() = box.max.head<2>().cwiseMin((work.max + m).head<2>());
  }
  Image out = render_top_view(views[0].first, views[0].second, ppm, box);
  for (std::size_t i = 1; i < views.size(); ++i)
    out = side_by_side(out, render_top_view(views[i].first, views[i].second, ppm, box));
  return out;
}

// ---- HTML --------------------------------------------------------------------------------------

std::string fmt(double v, int digits = 2) {
  std::ostringstream s;
  s.setf(std::ios::fixed);
  s.precision(digits);
  s << v;
  return s.str();
}

std::string summary_html(const ExperimentResult& r) {
  const eval::RegistrationOutcome& g = r.registration;
  std::ostringstream o;
  o << "<table class=\"summary\">"
    << "<tr><th>registration</th><td>" << (g.success ? "accepted at " + fmt(g.first_success_s, 0) + " s" : "not accepted")
    << " after " << g.attempts << " trigger(s); " << fmt(g.rotation_error_deg) << "&deg;, "
    << fmt(100.0 * g.translation_error_m, 1) << " cm from the truth</td></tr>"
    << "<tr><th>stones tracked</th><td>" << r.stones_tracked << " / " << r.stones << "</td></tr>"
    << "<tr><th>moves placed within tolerance</th><td>" << r.placed << " / " << r.moves << "</td></tr>"
    << "<tr><th>first-attempt success</th><td>" << r.first_attempt_success << " / " << r.moves << "</td></tr>"
    << "<tr><th>success within the attempts</th><td>" << r.within_attempts << " / " << r.moves << "</td></tr>"
    << "<tr><th>failed attempts detected</th><td>" << r.failures_detected << " / " << r.failures << ", "
    << r.false_alarms << " false alarm(s)</td></tr>"
    << "<tr><th>mapped trajectory</th><td>ATE " << fmt(r.scene.trajectory_error.ate_rmse, 3) << " m RMSE, "
    << fmt(r.scene.trajectory_error.rotation_rmse_deg) << "&deg;</td></tr>"
    << "<tr><th>wall time</th><td>" << fmt(r.timings.get("total") / 1000.0, 1) << " s</td></tr></table>";
  return o.str();
}

std::string grasps_html(const ExperimentResult& r) {
  std::ostringstream o;
  o << "<table class=\"data\"><tr><th>round</th><th>object</th><th>stone</th><th>attempt</th><th>truth</th>"
       "<th>reasons</th><th>detected</th><th>signs</th><th>target error [m]</th><th>planning [ms]</th></tr>";
  const auto join = [](const std::vector<std::string>& v) {
    std::string s;
    for (const std::string& x : v) s += (s.empty() ? "" : ", ") + x;
    return xml_escape(s);
  };
  for (const GraspRecord& g : r.grasps)
    o << "<tr><td>" << g.round << "</td><td><span class=\"sw\" style=\"background:" << hex(object_color(g.object))
      << "\"></span>" << g.object << "</td><td>" << g.stone << "</td><td>" << g.attempt << "</td><td>"
      << (g.success ? "held" : "failed") << "</td><td>" << join(g.failure_reasons) << "</td><td>"
      << (g.detected ? "yes" : "no") << "</td><td>" << join(g.detection.signs) << "</td><td>"
      << (g.target_error_m >= 0 ? fmt(g.target_error_m) : "&ndash;") << "</td><td>" << fmt(g.planning_ms, 0)
      << "</td></tr>";
  o << "</table>";
  return o.str();
}

std::string rounds_html(const ExperimentResult& r) {
  std::ostringstream o;
  o << "<table class=\"data\"><tr><th>round</th><th>object</th><th>stone</th><th>position error [m]</th>"
       "<th>rotation error [&deg;]</th><th>target error [m]</th></tr>";
  for (const eval::ExperimentRound& round : r.rounds) {
    for (const eval::ExperimentObject& x : round.objects)
      o << "<tr><td>" << round.round << "</td><td><span class=\"sw\" style=\"background:" << hex(object_color(x.object))
        << "\"></span>" << x.object << "</td><td>" << x.stone << "</td><td>" << fmt(x.translation_error_m, 3)
        << "</td><td>" << fmt(x.rotation_error_deg) << "</td><td>"
        << (x.target_error_m >= 0 ? fmt(x.target_error_m) : "&ndash;") << "</td></tr>";
    o << "<tr class=\"total\"><td>" << round.round << "</td><td colspan=\"5\">ghost points "
      << fmt(100.0 * round.ghost_fraction) << " %, lost " << round.lost << ", duplicated " << round.duplicated
      << "</td></tr>";
  }
  o << "</table>";
  return o.str();
}

std::string data_url(std::string_view js) { return "data:text/javascript;base64," + base64(js); }

}  // namespace

Rgb object_color(std::int64_t id) {
  const double h = std::fmod(double(id) * kGoldenRatioConjugate, 1.0), s = 0.65, l = 0.5;
  const double q = l < 0.5 ? l * (1 + s) : l + s - l * s, p = 2 * l - q;
  const auto channel = [&](double t) {
    t = t < 0 ? t + 1 : t > 1 ? t - 1 : t;
    const double v = t < 1.0 / 6 ? p + (q - p) * 6 * t : t < 0.5 ? q : t < 2.0 / 3 ? p + (q - p) * (2.0 / 3 - t) * 6 : p;
    return std::uint8_t(std::lround(255.0 * v));
  };
  return {channel(h + 1.0 / 3), channel(h), channel(h - 1.0 / 3)};
}

std::string base64(std::string_view in) {
  static constexpr char kTable[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve(4 * ((in.size() + 2) / 3));
  for (std::size_t i = 0; i < in.size(); i += 3) {
    const std::size_t n = std::min<std::size_t>(3, in.size() - i);
    std::uint32_t v = 0;
    for (std::size_t k = 0; k < 3; ++k) v = (v << 8) | (k < n ? std::uint8_t(in[i + k]) : 0u);
    for (std::size_t k = 0; k < 4; ++k) out += k <= n ? kTable[(v >> (18 - 6 * k)) & 63u] : '=';
  }
  return out;
}

json encode_cloud(const PointCloud& cloud, const Vec3d& origin) {
  std::string bytes;
  bytes.reserve(6 * cloud.size());
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const Vec3d p = (cloud.world(i) - origin) * kCm;
    for (int k = 0; k < 3; ++k) {
      const auto v = std::int16_t(std::lround(std::clamp(p[k], -32767.0, 32767.0)));
      bytes += char(std::uint16_t(v) & 0xff), bytes += char(std::uint16_t(v) >> 8);
    }
  }
  return {{"n", cloud.size()}, {"xyz", base64(bytes)}};
}

ReportFiles write_report(const fs::path& dir, const ExperimentResult& r, const ReportConfig& c) {
  fs::create_directories(dir);
  ReportFiles files{.html = dir / "report.html"};
  const Vec3d origin = scene_origin(r);
  const std::vector<std::pair<std::string, std::string>> svgs = {
      {"fig_registration_stages.svg", fig_registration_stages(r)},
      {"fig_map_sizes.svg", fig_map_sizes(r)},
      {"fig_registration_tries.svg", fig_registration_tries(r)},
      {"fig_grasp_costs.svg", fig_grasp_costs(r)},
      {"fig_target_errors.svg", fig_target_errors(r, c.target_tolerance)},
      {"fig_pose_errors_m.svg", fig_pose_errors(r, false, c.pose_tolerance_m)},
      {"fig_pose_errors_deg.svg", fig_pose_errors(r, true, c.pose_tolerance_deg)},
      {"fig_trajectory.svg", fig_trajectory(r)}};
  std::ostringstream figures;
  for (const auto& [name, svg] : svgs) {
    io::detail::write_file(dir / name, svg);
    files.figures.push_back(dir / name);
    figures << "<figure>" << svg << "</figure>\n";
  }
  const fs::path png = dir / "fig_map_instants.png";
  write_png(png, map_instants(r, origin, c.top_view_ppm));
  files.figures.push_back(png);
  std::string labels;
  for (const SceneSnapshot& s : r.scene.snapshots) labels += (labels.empty() ? "" : " | ") + s.label;
  const std::string title = "cairn " + r.experiment + ", seed " + std::to_string(r.seed);
  std::ostringstream h;
  h << "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>" << xml_escape(title) << "</title>\n"
    << "<style>" << assets::report_css() << "</style>\n"
    << "<script type=\"importmap\">" << json{{"imports", {{"three", data_url(assets::three_js())},
                                                           {"three/addons/controls/OrbitControls.js", data_url(assets::orbit_controls_js())}}}}.dump()
    << "</script>\n"
    << "<script>window.cairnErrors=[];const cairnErr=(m)=>{window.cairnErrors.push(String(m));"
       "const e=document.getElementById('errors');if(e)e.textContent=window.cairnErrors.join('\\n');};"
       "window.addEventListener('error',(e)=>cairnErr(e.message));"
       "window.addEventListener('unhandledrejection',(e)=>cairnErr(e.reason));"
       "const cairnConsoleError=console.error;console.error=(...a)=>{cairnErr(a.join(' '));cairnConsoleError(...a);};</script>\n"
    << "</head><body>\n<h1>" << xml_escape(title) << "</h1>\n"
    << "<p class=\"lead\">The paper's experiment " << (r.experiment == "exp1" ? "1" : "2")
    << " (Sec. 6) on cairn's simulated machine: what the machine sensed and did, scored against the simulator's truth.</p>\n"
    << summary_html(r) << "\n<h2>Scene</h2>\n<div id=\"controls\"></div><div id=\"viewer\"></div>\n"
    << "<p class=\"note\">Drag to orbit, right-drag to pan, scroll to zoom. Grey: the LiDAR map; coloured: the "
       "database's objects (one colour per object id, as in every figure); boxes: the chosen grasps' gripper "
       "(green held, red failed); rings: the targets; black dots: the stones' true centroids. Clouds thinned to "
    << std::lround(r.scene.voxel * kCm) << " cm voxels.</p>\n"
    << "<div id=\"status\">loading</div><pre id=\"errors\"></pre>\n"
    << "<h2>The map at captured instants (Fig. 11 analog)</h2><p class=\"note\">" << xml_escape(labels) << "</p>\n"
    << "<img class=\"wide\" alt=\"map at instants\" src=\"data:image/png;base64," << base64(io::detail::read_file(png)) << "\">\n"
    << "<h2>Figures</h2>\n<div class=\"figures\">" << figures.str() << "</div>\n"
    << "<h2>Grasps</h2>\n" << grasps_html(r) << "\n<h2>Rounds</h2>\n" << rounds_html(r) << "\n<h2>Notes</h2><ul>";
  for (const std::string& n : r.notes) h << "<li>" << xml_escape(n) << "</li>";
  h << "</ul>\n<script type=\"application/json\" id=\"scene\">" << scene_json(r, origin).dump() << "</script>\n"
    << "<script type=\"module\">" << assets::viewer_js() << "</script>\n</body></html>\n";
  io::detail::write_file(files.html, h.str());
  return files;
}

}  // namespace cairn::report
