#pragma once
// The experiment's report (issue #18 item 4): DIR/report.html, one self-contained file that opens
// from the file system without network — a three.js viewer (the LiDAR map, the registered drone
// cloud, the database's objects coloured by id at each captured instant, the chosen grasps'
// gripper, targets and true stone centroids), the summary, the plots and the tables — and every
// figure also as a file under DIR/:
//   fig_registration_stages.svg   Table 1 analog: time per registration stage
//   fig_map_sizes.svg             Table 2 analog: LiDAR map size over time, the drone cloud's
//   fig_registration_tries.svg    registration over time: each trigger's error, accepted or not
//   fig_grasp_costs.svg           Fig. 9 analog: force-closure grasps' costs vs the selected
//   fig_pose_errors_m.svg, fig_pose_errors_deg.svg   per-round object pose errors
//   fig_target_errors.svg         per move: the stone's distance from its target
//   fig_trajectory.svg            the mapped trajectory against the truth
//   fig_map_instants.png          Fig. 11 analog: the map and objects at the captured instants
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "cairn/core/point_cloud.hpp"
#include "cairn/eval/experiment.hpp"

namespace cairn::report {

struct ReportConfig {
  double target_tolerance = 0.10;   // [m] issue #18: every stone within 10 cm of its target
  double pose_tolerance_m = 0.02;   // [m] issue #18: object poses within 2 cm ...
  double pose_tolerance_deg = 1.0;  // [deg] ... and 1 deg after every round
  double top_view_ppm = 24.0;       // [px/m] Fig. 11 analog
};

struct ReportFiles {
  std::filesystem::path html;
  std::vector<std::filesystem::path> figures;
};

/// Writes the report and its figures into `dir` (created). Throws InputError when a file cannot
/// be written.
ReportFiles write_report(const std::filesystem::path& dir, const eval::ExperimentResult& result,
                         const ReportConfig& config = {});

/// One colour per object id, the same in the viewer (viewer.js: objectColor) and the PNGs: hue by
/// the golden angle, HSL saturation 0.65, lightness 0.5.
[[nodiscard]] Rgb object_color(std::int64_t id);

/// Standard base64 (RFC 4648, with padding).
[[nodiscard]] std::string base64(std::string_view bytes);

/// A cloud as the viewer reads it: {"n": count, "xyz": base64 of little-endian int16 triples in
/// centimetres from `origin`} (clamped to +-327 m).
[[nodiscard]] nlohmann::json encode_cloud(const PointCloud& cloud, const Vec3d& origin);

}  // namespace cairn::report
