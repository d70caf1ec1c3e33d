#include "cairn/segmentation/output.hpp"

#include <fstream>

#include "cairn/core/error.hpp"
#include "cairn/core/io/io.hpp"

namespace cairn {
namespace {

nlohmann::json vec(const Vec3d& v) { return {v.x(), v.y(), v.z()}; }

}  // namespace

Rgb label_color(std::int32_t label) {
  if (label == kLabelGround) return {150, 150, 150};
  if (label < 0) return {60, 60, 60};
  // Golden-angle hue walk: neighbouring ids get well separated colours.
  const double h = std::fmod(double(label) * 137.508, 360.0) / 60.0;
  const double x = 1.0 - std::abs(std::fmod(h, 2.0) - 1.0);
  const int sector = int(h);
  const double rgb[6][3] = {{1, x, 0}, {x, 1, 0}, {0, 1, x}, {0, x, 1}, {x, 0, 1}, {1, 0, x}};
  const auto c = [&](int k) { return std::uint8_t(40 + 215 * rgb[sector % 6][k]); };
  return {c(0), c(1), c(2)};
}

nlohmann::json segments_json(const PointCloud& cloud, const SegmentationResult& r) {
  nlohmann::json j;
  // Plane in world coordinates: n·(p - o) + d = 0  →  n·p + (d - n·o) = 0
  const Vec3d n = r.ground_plane.normal.cast<double>();
  j["ground_plane"] = {n.x(), n.y(), n.z(), double(r.ground_plane.d) - n.dot(cloud.origin)};
  j["num_points"] = cloud.size();
  j["num_ground"] = r.num_ground;
  j["num_objects"] = r.num_objects();
  j["segments"] = nlohmann::json::array();
  for (const auto& s : r.segments) {
    j["segments"].push_back({{"id", s.id},
                             {"num_points", s.indices.size()},
                             {"centroid", vec(cloud.origin + s.centroid.cast<double>())},
                             {"bbox_min", vec(cloud.origin + s.box.min.cast<double>())},
                             {"bbox_max", vec(cloud.origin + s.box.max.cast<double>())},
                             {"planar", s.planar},
                             {"plane_inlier_ratio", s.plane_inlier_ratio},
                             {"stacked_fraction", s.stacked_fraction},
                             {"cluster", s.cluster},
                             {"split", s.split},
                             {"seam_depth", s.seam_depth}});
  }
  nlohmann::json t = nlohmann::json::object();
  for (const auto& [name, ms] : r.timings.stages) t[name] = ms;
  t["total"] = r.timings.total();
  j["timings_ms"] = t;
  return j;
}

void write_segmentation(const std::filesystem::path& dir, const PointCloud& cloud, const SegmentationResult& r,
                        const std::vector<std::int32_t>& input_labels) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw InputError(dir.string() + ": cannot create output directory: " + ec.message());
  {
    std::ofstream f(dir / "segments.json");
    f << segments_json(cloud, r).dump(2) << "\n";
    if (!f) throw InputError((dir / "segments.json").string() + ": write failed");
  }
  {
    std::ofstream f(dir / "labels.txt");
    std::string buf;
    buf.reserve(input_labels.size() * 3);
    for (auto l : input_labels) (buf += std::to_string(l)) += '\n';
    f << buf;
    if (!f) throw InputError((dir / "labels.txt").string() + ": write failed");
  }
  PointCloud colored;
  colored.points = cloud.points;
  colored.origin = cloud.origin;
  colored.labels = r.labels;
  colored.colors.resize(cloud.size());
  for (std::size_t i = 0; i < cloud.size(); ++i) colored.colors[i] = label_color(r.labels[i]);
  io::write_ply(dir / "segments.ply", colored);
}

}  // namespace cairn
