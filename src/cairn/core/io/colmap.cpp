// COLMAP text model reader and writer (cameras.txt, images.txt, points3D.txt).
#include "cairn/core/io/colmap.hpp"

#include <charconv>
#include <cmath>
#include <limits>
#include <map>
#include <set>
#include <string_view>
#include <system_error>

#include "cairn/core/error.hpp"
#include "cairn/core/io/detail.hpp"

namespace cairn::io {
namespace {

using detail::fail;
using std::filesystem::path;

constexpr std::size_t kMaxQuoted = 40;  // longest token quoted in an error message

// ---- writing

void put(std::string& out, double v) {
  char buf[32];
  const auto [end, ec] = std::to_chars(buf, buf + sizeof(buf), v);  // shortest round-trip form
  out.append(buf, end);
}
template <std::integral I>
void put(std::string& out, I v) {
  char buf[24];
  const auto [end, ec] = std::to_chars(buf, buf + sizeof(buf), v);
  out.append(buf, end);
}
void sep(std::string& out) { out.push_back(' '); }

// ---- reading

/// One line of a text file with its 1-based number; errors name file and line.
struct Line {
  const path& file;
  std::size_t number;
  std::vector<std::string_view> words;

  [[noreturn]] void error(const std::string& problem) const {
    fail(file, "line " + std::to_string(number) + ": " + problem);
  }
  double real(std::size_t i, const char* what) const {
    double v = 0.0;
    if (!detail::parse_number(words[i], v) || !std::isfinite(v))
      error(std::string(what) + " '" + std::string(words[i].substr(0, kMaxQuoted)) + "' is not a finite number");
    return v;
  }
  template <std::integral I>
  I integer(std::size_t i, const char* what) const {
    std::string_view t = words[i];
    if (!t.empty() && t.front() == '+') t.remove_prefix(1);
    I v{};
    const auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
    if (t.empty() || ec != std::errc{} || end != t.data() + t.size())
      error(std::string(what) + " '" + std::string(words[i].substr(0, kMaxQuoted)) +
            "' is not an integer in range");
    return v;
  }
};

/// Splits text into lines (LF, CRLF or CR); the line number of lines[i] is i + 1.
std::vector<std::string_view> split_lines(std::string_view text) {
  std::vector<std::string_view> lines;
  std::size_t pos = 0;
  while (pos < text.size()) {
    const auto end = std::min(text.find_first_of("\r\n", pos), text.size());
    lines.push_back(text.substr(pos, end - pos));
    pos = end;
    if (pos < text.size() && text[pos] == '\r') ++pos;
    if (pos < text.size() && text[pos] == '\n') ++pos;
  }
  return lines;
}

bool is_blank_or_comment(const std::vector<std::string_view>& words) {
  return words.empty() || words.front().front() == '#';
}

void check_params(const ColmapCamera& c, const auto& on_error) {
  const int n = colmap_model_num_params(c.model);
  if (n < 0) on_error("unknown camera model '" + c.model.substr(0, kMaxQuoted) + "'");
  if (static_cast<int>(c.params.size()) != n)
    on_error("camera model " + c.model + " needs " + std::to_string(n) + " parameters, got " +
             std::to_string(c.params.size()));
  if (!(c.width > 0 && c.height > 0)) on_error("camera size must be positive");
}

bool has_space(const std::string& s) {
  return s.find_first_of(" \t\r\n\v\f") != std::string::npos;
}

}  // namespace

Eigen::Isometry3d ColmapImage::T_world_cam() const {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = rotation_cam_world().transpose();
  T.translation() = center();
  return T;
}

int colmap_model_num_params(const std::string& model) {
  static const std::map<std::string, int, std::less<>> kModels = {
      {"SIMPLE_PINHOLE", 3}, {"PINHOLE", 4},        {"SIMPLE_RADIAL", 4},          {"RADIAL", 5},
      {"OPENCV", 8},         {"OPENCV_FISHEYE", 8}, {"FULL_OPENCV", 12},           {"FOV", 5},
      {"SIMPLE_RADIAL_FISHEYE", 4}, {"RADIAL_FISHEYE", 5}, {"THIN_PRISM_FISHEYE", 12}};
  const auto it = kModels.find(model);
  return it == kModels.end() ? -1 : it->second;
}

// ---- writers

void write_colmap_cameras(const path& file, const std::vector<ColmapCamera>& cameras) {
  std::string out = "# Camera list with one line of data per camera:\n"
                    "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
                    "# Number of cameras: " + std::to_string(cameras.size()) + "\n";
  for (const auto& c : cameras) {
    check_params(c, [&](const std::string& problem) { fail(file, "camera " + std::to_string(c.id) + ": " + problem); });
    put(out, c.id);
    out.append(" ").append(c.model);
    sep(out), put(out, c.width), sep(out), put(out, c.height);
    for (double p : c.params) sep(out), put(out, p);
    out.push_back('\n');
  }
  detail::write_file(file, out);
}

void write_colmap_images(const path& file, const std::vector<ColmapImage>& images) {
  std::size_t observations = 0;
  for (const auto& im : images) observations += im.points2d.size();
  std::string out = "# Image list with two lines of data per image:\n"
                    "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n"
                    "#   POINTS2D[] as (X, Y, POINT3D_ID)\n"
                    "# Number of images: " + std::to_string(images.size()) +
                    ", mean observations per image: " +
                    std::to_string(images.empty() ? 0.0 : double(observations) / double(images.size())) + "\n";
  for (const auto& im : images) {
    if (im.name.empty() || has_space(im.name))
      fail(file, "image " + std::to_string(im.id) + ": name '" + im.name + "' is empty or contains whitespace");
    put(out, im.id);
    const auto& q = im.q_cam_world;
    for (double v : {q.w(), q.x(), q.y(), q.z()}) sep(out), put(out, v);
    for (int k = 0; k < 3; ++k) sep(out), put(out, im.t_cam_world[k]);
    sep(out), put(out, im.camera_id);
    out.append(" ").append(im.name).append("\n");
    for (std::size_t i = 0; i < im.points2d.size(); ++i) {
      if (i > 0) sep(out);
      put(out, im.points2d[i].xy.x()), sep(out), put(out, im.points2d[i].xy.y()), sep(out);
      put(out, im.points2d[i].point3d_id);
    }
    out.push_back('\n');
  }
  detail::write_file(file, out);
}

void write_colmap_points3d(const path& file, const std::vector<ColmapPoint3D>& points) {
  std::size_t track = 0;
  for (const auto& p : points) track += p.track.size();
  std::string out = "# 3D point list with one line of data per point:\n"
                    "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n"
                    "# Number of points: " + std::to_string(points.size()) + ", mean track length: " +
                    std::to_string(points.empty() ? 0.0 : double(track) / double(points.size())) + "\n";
  out.reserve(out.size() + points.size() * 96);
  for (const auto& p : points) {
    put(out, p.id);
    for (int k = 0; k < 3; ++k) sep(out), put(out, p.xyz[k]);
    sep(out), put(out, unsigned{p.color.r}), sep(out), put(out, unsigned{p.color.g}), sep(out);
    put(out, unsigned{p.color.b}), sep(out), put(out, p.error);
    for (const auto& t : p.track) sep(out), put(out, t.image_id), sep(out), put(out, t.point2d_idx);
    out.push_back('\n');
  }
  detail::write_file(file, out);
}

void write_colmap_text(const path& dir, const ColmapModel& model) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) fail(dir, "cannot create directory: " + ec.message());
  write_colmap_cameras(dir / "cameras.txt", model.cameras);
  write_colmap_images(dir / "images.txt", model.images);
  write_colmap_points3d(dir / "points3D.txt", model.points);
}

// ---- readers

std::vector<ColmapCamera> read_colmap_cameras(const path& file) {
  const std::string text = detail::read_file(file);
  const auto lines = split_lines(text);
  std::vector<ColmapCamera> cameras;
  std::set<std::uint32_t> ids;
  for (std::size_t i = 0; i < lines.size(); ++i) {
    const Line line{file, i + 1, detail::split_words(lines[i])};
    if (is_blank_or_comment(line.words)) continue;
    if (line.words.size() < 4) line.error("expected CAMERA_ID MODEL WIDTH HEIGHT PARAMS[]");
    ColmapCamera c;
    c.id = line.integer<std::uint32_t>(0, "CAMERA_ID");
    c.model = std::string(line.words[1]);
    c.width = line.integer<int>(2, "WIDTH");
    c.height = line.integer<int>(3, "HEIGHT");
    for (std::size_t k = 4; k < line.words.size(); ++k) c.params.push_back(line.real(k, "camera parameter"));
    check_params(c, [&](const std::string& problem) { line.error(problem); });
    if (!ids.insert(c.id).second) line.error("duplicate CAMERA_ID " + std::to_string(c.id));
    cameras.push_back(std::move(c));
  }
  return cameras;
}

std::vector<ColmapImage> read_colmap_images(const path& file) {
  const std::string text = detail::read_file(file);
  const auto lines = split_lines(text);
  std::vector<ColmapImage> images;
  std::set<std::uint32_t> ids;
  for (std::size_t i = 0; i < lines.size(); ++i) {
    const Line line{file, i + 1, detail::split_words(lines[i])};
    if (is_blank_or_comment(line.words)) continue;
    if (line.words.size() != 10) line.error("expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME (10 fields), got " +
                                            std::to_string(line.words.size()));
    ColmapImage im;
    im.id = line.integer<std::uint32_t>(0, "IMAGE_ID");
    im.q_cam_world = Eigen::Quaterniond(line.real(1, "QW"), line.real(2, "QX"), line.real(3, "QY"), line.real(4, "QZ"));
    if (!(im.q_cam_world.norm() > 1e-12)) line.error("quaternion has zero length");
    for (int k = 0; k < 3; ++k) im.t_cam_world[k] = line.real(5 + static_cast<std::size_t>(k), "translation");
    im.camera_id = line.integer<std::uint32_t>(8, "CAMERA_ID");
    im.name = std::string(line.words[9]);
    if (!ids.insert(im.id).second) line.error("duplicate IMAGE_ID " + std::to_string(im.id));
    // As COLMAP: the line after an image line holds its 2-D points, even when empty.
    if (i + 1 < lines.size()) {
      ++i;
      const Line pts{file, i + 1, detail::split_words(lines[i])};
      if (pts.words.size() % 3 != 0)
        pts.error("POINTS2D line of image " + std::to_string(im.id) + " must hold triples X Y POINT3D_ID, got " +
                  std::to_string(pts.words.size()) + " fields");
      for (std::size_t k = 0; k < pts.words.size(); k += 3) {
        ColmapObservation o;
        o.xy = {pts.real(k, "X"), pts.real(k + 1, "Y")};
        o.point3d_id = pts.integer<std::int64_t>(k + 2, "POINT3D_ID");
        if (o.point3d_id < -1) pts.error("POINT3D_ID must be -1 or a point id");
        im.points2d.push_back(o);
      }
    }
    images.push_back(std::move(im));
  }
  return images;
}

std::vector<ColmapPoint3D> read_colmap_points3d(const path& file) {
  const std::string text = detail::read_file(file);
  const auto lines = split_lines(text);
  std::vector<ColmapPoint3D> points;
  std::set<std::uint64_t> ids;
  for (std::size_t i = 0; i < lines.size(); ++i) {
    const Line line{file, i + 1, detail::split_words(lines[i])};
    if (is_blank_or_comment(line.words)) continue;
    if (line.words.size() < 8 || (line.words.size() - 8) % 2 != 0)
      line.error("expected POINT3D_ID X Y Z R G B ERROR TRACK[] (IMAGE_ID POINT2D_IDX pairs)");
    ColmapPoint3D p;
    p.id = line.integer<std::uint64_t>(0, "POINT3D_ID");
    for (int k = 0; k < 3; ++k) p.xyz[k] = line.real(1 + static_cast<std::size_t>(k), "coordinate");
    p.color.r = line.integer<std::uint8_t>(4, "R");
    p.color.g = line.integer<std::uint8_t>(5, "G");
    p.color.b = line.integer<std::uint8_t>(6, "B");
    p.error = line.real(7, "ERROR");
    for (std::size_t k = 8; k < line.words.size(); k += 2)
      p.track.push_back({line.integer<std::uint32_t>(k, "IMAGE_ID"), line.integer<std::uint32_t>(k + 1, "POINT2D_IDX")});
    if (!ids.insert(p.id).second) line.error("duplicate POINT3D_ID " + std::to_string(p.id));
    points.push_back(std::move(p));
  }
  return points;
}

ColmapModel read_colmap_text(const path& dir) {
  ColmapModel model;
  model.cameras = read_colmap_cameras(dir / "cameras.txt");
  model.images = read_colmap_images(dir / "images.txt");
  model.points = read_colmap_points3d(dir / "points3D.txt");
  std::set<std::uint32_t> camera_ids;
  for (const auto& c : model.cameras) camera_ids.insert(c.id);
  for (const auto& im : model.images)
    if (!camera_ids.contains(im.camera_id))
      fail(dir / "images.txt", "image " + std::to_string(im.id) + " refers to unknown CAMERA_ID " +
                                   std::to_string(im.camera_id));
  return model;
}

PointCloud colmap_points_cloud(const ColmapModel& model) {
  PointCloud cloud;
  cloud.reserve(model.points.size());
  cloud.colors.reserve(model.points.size());
  // Georeferenced models (UTM, ~1e6 m) keep float precision relative to an origin, as read_cloud does.
  Vec3d lo = Vec3d::Constant(std::numeric_limits<double>::infinity());
  bool large = false;
  for (const auto& p : model.points) {
    lo = lo.cwiseMin(p.xyz);
    large = large || p.xyz.cwiseAbs().maxCoeff() > ReadOptions{}.recenter_threshold;
  }
  if (large) cloud.origin = lo.array().floor().matrix();
  for (const auto& p : model.points) {
    cloud.points.push_back((p.xyz - cloud.origin).cast<float>());
    if (!cloud.points.back().allFinite())
      throw InputError("COLMAP point " + std::to_string(p.id) + " lies too far from the others for float coordinates");
    cloud.colors.push_back(p.color);
  }
  return cloud;
}

}  // namespace cairn::io
