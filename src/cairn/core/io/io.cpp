// Format dispatch, the common post-processing of every reader, and the helpers shared by the
// format implementations (ply.cpp, pcd.cpp, text.cpp).
#include "cairn/core/io/detail.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <type_traits>

#include "cairn/core/error.hpp"

namespace cairn::io {
namespace detail {
namespace {

constexpr std::size_t kNumberChars = 64;     // enough for any shortest-form double
constexpr std::size_t kMaxQuotedToken = 40;  // longest token quoted in an error message
constexpr double kMaxByte = 255.0;
constexpr std::string_view kOriginKey = "cairn_origin";
constexpr std::uint32_t kOpaqueAlpha = 0xFF000000u;  // PCL's packed rgb carries alpha 255
constexpr int kRedShift = 16;
constexpr int kGreenShift = 8;

bool is_space(char c) {
  return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\v' || c == '\f';
}

/// Calls f(T{}) with T the C++ type of `type`.
template <class F>
void visit_scalar(Scalar type, F&& f) {
  switch (type) {
    case Scalar::Int8:
      return f(std::int8_t{});
    case Scalar::UInt8:
      return f(std::uint8_t{});
    case Scalar::Int16:
      return f(std::int16_t{});
    case Scalar::UInt16:
      return f(std::uint16_t{});
    case Scalar::Int32:
      return f(std::int32_t{});
    case Scalar::UInt32:
      return f(std::uint32_t{});
    case Scalar::Int64:
      return f(std::int64_t{});
    case Scalar::UInt64:
      return f(std::uint64_t{});
    case Scalar::Float32:
      return f(float{});
    case Scalar::Float64:
      return f(double{});
  }
}

template <class T>
T load(const char* p, bool swap) {
  std::array<char, sizeof(T)> bytes;
  std::memcpy(bytes.data(), p, sizeof(T));
  if (swap) std::reverse(bytes.begin(), bytes.end());
  return std::bit_cast<T>(bytes);
}

template <class T>
void save(char* p, T value, bool swap) {
  auto bytes = std::bit_cast<std::array<char, sizeof(T)>>(value);
  if (swap) std::reverse(bytes.begin(), bytes.end());
  std::memcpy(p, bytes.data(), sizeof(T));
}

/// double -> T; integers are rounded and clamped to T's range (NaN -> 0).
template <class T>
T to_scalar(double v) {
  if constexpr (std::is_floating_point_v<T>) {
    return static_cast<T>(v);
  } else {
    if (std::isnan(v)) return T{0};
    const double r = std::round(v);
    if (r >= static_cast<double>(std::numeric_limits<T>::max()))
      return std::numeric_limits<T>::max();
    if (r <= static_cast<double>(std::numeric_limits<T>::lowest()))
      return std::numeric_limits<T>::lowest();
    return static_cast<T>(r);
  }
}

bool iequals(std::string_view a, std::string_view b) {
  return std::equal(a.begin(), a.end(), b.begin(), b.end(), [](char x, char y) {
    return std::tolower(static_cast<unsigned char>(x)) ==
           std::tolower(static_cast<unsigned char>(y));
  });
}

// ---- Where a named column goes.
enum class Slot { Point, Normal, Color, Time, Label, Field };
struct NameRule {
  std::string_view name;
  Slot slot;
  int axis;
};
constexpr NameRule kNameRules[] = {
    {"x", Slot::Point, 0},
    {"y", Slot::Point, 1},
    {"z", Slot::Point, 2},
    {"nx", Slot::Normal, 0},
    {"ny", Slot::Normal, 1},
    {"nz", Slot::Normal, 2},
    {"normal_x", Slot::Normal, 0},
    {"normal_y", Slot::Normal, 1},
    {"normal_z", Slot::Normal, 2},
    {"red", Slot::Color, 0},
    {"green", Slot::Color, 1},
    {"blue", Slot::Color, 2},
    {"r", Slot::Color, 0},
    {"g", Slot::Color, 1},
    {"b", Slot::Color, 2},
    {"diffuse_red", Slot::Color, 0},
    {"diffuse_green", Slot::Color, 1},
    {"diffuse_blue", Slot::Color, 2},
    {"time", Slot::Time, 0},
    {"timestamp", Slot::Time, 0},
    {"t", Slot::Time, 0},
    {"label", Slot::Label, 0},
};
constexpr std::uint8_t Rgb::*kChannels[] = {&Rgb::r, &Rgb::g, &Rgb::b};

const NameRule* classify(std::string_view name) {
  for (const auto& rule : kNameRules)
    if (iequals(rule.name, name)) return &rule;
  return nullptr;
}

std::uint8_t to_byte(double v, ColorScale scale) {
  const double x = scale == ColorScale::Unit ? v * kMaxByte : v;
  return std::isnan(x) ? 0 : static_cast<std::uint8_t>(std::clamp(std::round(x), 0.0, kMaxByte));
}

std::uint32_t pack_rgb(const Rgb& c) {
  return kOpaqueAlpha | std::uint32_t{c.r} << kRedShift | std::uint32_t{c.g} << kGreenShift | c.b;
}

void check_field_name(const std::string& name, const path& file) {
  const bool bad_char = std::any_of(name.begin(), name.end(), [](char c) {
    return is_space(c) || c == ',' || c == '#' || c == '"';
  });
  if (name.empty() || bad_char || classify(name) || name == "rgb" || name == "rgba" || name == "_")
    fail(file,
         "cannot write scalar field '" + name +
             "': the name is empty, contains separators or is reserved for another attribute");
}

Vec3d recenter_origin(const std::vector<Vec3d>& xyz, double threshold) {
  Vec3d lo = Vec3d::Constant(std::numeric_limits<double>::infinity());
  bool large = false;
  for (const auto& p : xyz) {
    if (!p.allFinite()) continue;
    lo = lo.cwiseMin(p);
    large = large || p.cwiseAbs().maxCoeff() > threshold;
  }
  return large ? Vec3d(lo.array().floor()) : Vec3d::Zero();
}

}  // namespace

std::size_t scalar_size(Scalar type) {
  std::size_t size = 0;
  visit_scalar(type, [&](auto tag) { size = sizeof(tag); });
  return size;
}

bool is_floating(Scalar type) { return type == Scalar::Float32 || type == Scalar::Float64; }

void fail(const path& file, const std::string& problem) {
  throw InputError(file.string() + ": " + problem);
}

void fail_truncated(const path& file, std::size_t expected, std::size_t read,
                    const std::string& items) {
  fail(file, "truncated data: expected " + std::to_string(expected) + " " + items + ", read " +
                 std::to_string(read));
}

std::string read_file(const path& file) {
  std::error_code ec;
  const auto status = std::filesystem::status(file, ec);
  if (!std::filesystem::exists(status)) fail(file, "file not found");
  if (std::filesystem::is_directory(status)) fail(file, "is a directory, not a file");
  std::ifstream in(file, std::ios::binary | std::ios::ate);
  if (!in) fail(file, "cannot open file (permission denied?)");
  const auto size = static_cast<std::streamsize>(in.tellg());
  if (size < 0) fail(file, "cannot read file");
  std::string bytes(static_cast<std::size_t>(size), '\0');
  in.seekg(0);
  if (!in.read(bytes.data(), size)) fail(file, "read error");
  return bytes;
}

void write_file(const path& file, std::string_view bytes) {
  std::ofstream out(file, std::ios::binary | std::ios::trunc);
  if (!out) fail(file, "cannot open file for writing");
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  out.close();
  if (!out) fail(file, "write error (disk full?)");
}

std::string_view line_ending(std::string_view text) {
  const auto eol = text.find_first_of("\r\n");
  if (eol == std::string_view::npos || text[eol] == '\n') return "\n";
  return eol + 1 < text.size() && text[eol + 1] == '\n' ? "\r\n" : "\r";
}

std::vector<std::string_view> split_words(std::string_view line) {
  std::vector<std::string_view> words;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && is_space(line[i])) ++i;
    const auto start = i;
    while (i < line.size() && !is_space(line[i])) ++i;
    if (i > start) words.push_back(line.substr(start, i - start));
  }
  return words;
}

bool parse_number(std::string_view token, double& value) {
  if (!token.empty() && token.front() == '+') token.remove_prefix(1);
  if (token.empty()) return false;
  const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), value);
  return ec == std::errc{} && end == token.data() + token.size();
}

std::size_t parse_count(std::string_view token, const path& file, std::string_view what) {
  double v = 0;
  if (!parse_number(token, v) || !(v >= 0 && v <= kMaxCount) || v != std::floor(v))
    fail(file, "bad " + std::string(what) + " '" + std::string(token) + "'");
  return static_cast<std::size_t>(v);
}

// ---- Tokens

Tokens::Tokens(std::string_view text, const path& file, std::size_t first_line)
    : text_(text), file_(file), line_(first_line) {}

std::string_view Tokens::next() {
  for (; pos_ < text_.size() && is_space(text_[pos_]); ++pos_) {
    const char c = text_[pos_];
    const bool lone_cr = c == '\r' && (pos_ + 1 == text_.size() || text_[pos_ + 1] != '\n');
    if (c == '\n' || lone_cr) ++line_;
  }
  const auto start = pos_;
  while (pos_ < text_.size() && !is_space(text_[pos_])) ++pos_;
  return text_.substr(start, pos_ - start);
}

bool Tokens::number(double& value) {
  const auto token = next();
  if (token.empty()) return false;
  if (!parse_number(token, value))
    fail(file_, "line " + std::to_string(line_) + ": '" +
                    std::string(token.substr(0, kMaxQuotedToken)) + "' is not a number");
  return true;
}

// ---- Binary columns and text values

void decode_column(const char* data, std::size_t stride, std::size_t n, Scalar type, bool swap,
                   double* out) {
  visit_scalar(type, [&](auto tag) {
    using T = decltype(tag);
    for (std::size_t i = 0; i < n; ++i)
      out[i] = static_cast<double>(load<T>(data + i * stride, swap));
  });
}

void encode_column(const double* values, std::size_t n, Scalar type, bool swap, char* out,
                   std::size_t stride) {
  visit_scalar(type, [&](auto tag) {
    using T = decltype(tag);
    for (std::size_t i = 0; i < n; ++i) save<T>(out + i * stride, to_scalar<T>(values[i]), swap);
  });
}

void append_value(std::string& out, double value, Scalar type) {
  std::array<char, kNumberChars> buf{};
  char* end = buf.data();
  if (type == Scalar::Float32)
    end = std::to_chars(buf.data(), buf.data() + buf.size(), static_cast<float>(value)).ptr;
  else if (type == Scalar::Float64)
    end = std::to_chars(buf.data(), buf.data() + buf.size(), value).ptr;
  else if (type == Scalar::UInt64)
    end = std::to_chars(buf.data(), buf.data() + buf.size(), to_scalar<std::uint64_t>(value)).ptr;
  else
    end = std::to_chars(buf.data(), buf.data() + buf.size(), to_scalar<std::int64_t>(value)).ptr;
  out.append(buf.data(), end);
}

// ---- Named columns -> cloud attributes

void store_column(RawCloud& raw, std::string_view name, const double* values, std::size_t first,
                  std::size_t stride, ColorScale scale) {
  const auto n = raw.xyz.size();
  auto& a = raw.attributes;
  const auto at = [&](std::size_t i) { return values[first + i * stride]; };
  const NameRule* rule = classify(name);
  const auto slot = rule ? rule->slot : Slot::Field;
  const int axis = rule ? rule->axis : 0;
  switch (slot) {
    case Slot::Point:
      for (std::size_t i = 0; i < n; ++i) raw.xyz[i][axis] = at(i);
      break;
    case Slot::Normal:
      a.normals.resize(n, Vec3f::Zero());
      for (std::size_t i = 0; i < n; ++i) a.normals[i][axis] = static_cast<float>(at(i));
      break;
    case Slot::Color:
      a.colors.resize(n);
      for (std::size_t i = 0; i < n; ++i) a.colors[i].*kChannels[axis] = to_byte(at(i), scale);
      break;
    case Slot::Time:
      a.times.resize(n);
      for (std::size_t i = 0; i < n; ++i) a.times[i] = at(i);
      break;
    case Slot::Label:
      a.labels.resize(n);
      for (std::size_t i = 0; i < n; ++i) a.labels[i] = to_scalar<std::int32_t>(at(i));
      break;
    case Slot::Field: {
      ScalarField field{std::string(name), std::vector<float>(n)};
      for (std::size_t i = 0; i < n; ++i) field.values[i] = static_cast<float>(at(i));
      a.fields.push_back(std::move(field));
      break;
    }
  }
}

bool is_coordinate(std::string_view name, int axis) {
  const NameRule* rule = classify(name);
  return rule && rule->slot == Slot::Point && rule->axis == axis;
}

void require_xyz(const std::vector<std::string>& names, const path& file) {
  for (int axis = 0; axis < 3; ++axis)
    if (std::none_of(names.begin(), names.end(),
                     [&](const auto& n) { return is_coordinate(n, axis); }))
      fail(file, "no x, y and z coordinates among the properties / columns");
}

// ---- Cloud -> columns to write

std::vector<Column> columns_of(const PointCloud& cloud, ColumnStyle style, const path& file) {
  cloud.check_consistent(file.string());
  for (const auto& f : cloud.fields) check_field_name(f.name, file);
  const auto n = cloud.size();
  const bool pcd = style == ColumnStyle::Pcd;
  std::vector<Column> columns;
  const auto add = [&](std::string name, Scalar type, auto&& value) {
    Column c{std::move(name), type, std::vector<double>(n)};
    for (std::size_t i = 0; i < n; ++i) c.values[i] = value(i);
    columns.push_back(std::move(c));
  };
  // Non-zero origin: double world coordinates, so that no precision is lost.
  const auto xyz_type = cloud.origin.isZero() ? Scalar::Float32 : Scalar::Float64;
  const char* xyz[] = {"x", "y", "z"};
  const char* normal[] = {"nx", "ny", "nz", "normal_x", "normal_y", "normal_z"};
  const char* color[] = {"red", "green", "blue"};
  for (int k = 0; k < 3; ++k)
    add(xyz[k], xyz_type,
        [&](std::size_t i) { return cloud.origin[k] + double(cloud.points[i][k]); });
  for (int k = 0; k < 3 && cloud.has_normals(); ++k)
    add(normal[pcd ? k + 3 : k], Scalar::Float32,
        [&](std::size_t i) { return cloud.normals[i][k]; });
  if (cloud.has_colors() && pcd)
    add("rgb", Scalar::UInt32, [&](std::size_t i) { return pack_rgb(cloud.colors[i]); });
  for (int k = 0; k < 3 && cloud.has_colors() && !pcd; ++k)
    add(color[k], Scalar::UInt8, [&](std::size_t i) { return cloud.colors[i].*kChannels[k]; });
  if (cloud.has_times())
    add("time", Scalar::Float64, [&](std::size_t i) { return cloud.times[i]; });
  if (cloud.has_labels())
    add("label", Scalar::Int32, [&](std::size_t i) { return cloud.labels[i]; });
  for (const auto& f : cloud.fields)
    add(f.name, Scalar::Float32, [&](std::size_t i) { return f.values[i]; });
  return columns;
}

std::string encode_records(const std::vector<Column>& columns, bool swap) {
  std::size_t record = 0;
  for (const auto& c : columns) record += scalar_size(c.type);
  const auto n = columns.empty() ? 0 : columns.front().values.size();
  std::string out(n * record, '\0');
  std::size_t offset = 0;
  for (const auto& c : columns) {
    encode_column(c.values.data(), n, c.type, swap, out.data() + offset, record);
    offset += scalar_size(c.type);
  }
  return out;
}

void append_rows(std::string& out, const std::vector<Column>& columns, char separator) {
  const auto n = columns.empty() ? 0 : columns.front().values.size();
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t c = 0; c < columns.size(); ++c) {
      if (c > 0) out += separator;
      append_value(out, columns[c].values[i], columns[c].type);
    }
    out += '\n';
  }
}

std::string origin_comment(const Vec3d& origin) {
  std::string s(kOriginKey);
  for (int k = 0; k < 3; ++k) {
    s += ' ';
    append_value(s, origin[k], Scalar::Float64);
  }
  return s;
}

std::optional<Vec3d> parse_origin_comment(std::string_view comment) {
  const auto words = split_words(comment);
  const auto key = std::find(words.begin(), words.end(), kOriginKey);
  if (key == words.end() || words.end() - key != 4) return std::nullopt;
  Vec3d origin;
  for (int k = 0; k < 3; ++k)
    if (!parse_number(key[k + 1], origin[k])) return std::nullopt;
  return origin.allFinite() ? std::optional<Vec3d>(origin) : std::nullopt;
}

// ---- Common post-processing

ReadResult finish(RawCloud raw, const path& file, const ReadOptions& options) {
  const auto n = raw.xyz.size();
  if (n == 0) fail(file, "cloud is empty (0 points)");
  std::vector<std::uint32_t> kept;
  kept.reserve(n);
  std::size_t first_bad = n;
  for (std::size_t i = 0; i < n; ++i) {
    if (raw.xyz[i].allFinite())
      kept.push_back(static_cast<std::uint32_t>(i));
    else if (first_bad == n)
      first_bad = i;
  }
  const auto bad = n - kept.size();
  if (kept.empty())
    fail(file, "cloud is empty: all " + std::to_string(n) + " points have non-finite coordinates");
  if (bad > 0 && !options.drop_non_finite)
    fail(file, std::to_string(bad) + " of " + std::to_string(n) +
                   " points have non-finite coordinates (NaN/Inf; first at index " +
                   std::to_string(first_bad) + "); set ReadOptions::drop_non_finite to drop them");

  PointCloud& cloud = raw.attributes;
  cloud.origin = raw.origin ? *raw.origin : recenter_origin(raw.xyz, options.recenter_threshold);
  cloud.points.resize(n);
  for (std::size_t i = 0; i < n; ++i) cloud.points[i] = (raw.xyz[i] - cloud.origin).cast<float>();
  for (std::uint32_t i : kept)  // a finite double beyond a float's range (~3.4e38) from the origin
    if (!cloud.points[i].allFinite())
      fail(file, "point " + std::to_string(i) + " lies too far from the others to be held in float coordinates");
  cloud.check_consistent(file.string());

  ReadResult result;
  result.num_input = n;
  if (bad > 0) {
    result.cloud = select(cloud, kept);
    result.kept_indices = std::move(kept);
  } else {
    result.cloud = std::move(cloud);
  }
  return result;
}

}  // namespace detail

// ---- Public API

namespace {

struct ExtensionRule {
  std::string_view extension;
  Format format;
};
constexpr ExtensionRule kExtensions[] = {
    {".ply", Format::Ply},      {".pcd", Format::Pcd}, {".xyz", Format::Xyz},
    {".txt", Format::Xyz},      {".csv", Format::Xyz}, {".pts", Format::Xyz},
    {".bin", Format::KittiBin}, {".vtk", Format::Vtk}, {".npy", Format::Npy},
};

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

/// Format from the first bytes of a file whose extension says nothing.
Format sniff(std::string_view bytes) {
  const bool ply =
      bytes.starts_with("ply") && bytes.size() > 3 && (bytes[3] == '\n' || bytes[3] == '\r');
  if (ply) return Format::Ply;
  if (bytes.starts_with("# .PCD") || bytes.starts_with("VERSION") || bytes.starts_with("FIELDS"))
    return Format::Pcd;
  if (bytes.starts_with("\x93NUMPY")) return Format::Npy;
  if (bytes.starts_with("# vtk")) return Format::Vtk;
  return Format::Xyz;
}

detail::RawCloud decode(Format format, std::string_view bytes, const std::filesystem::path& path) {
  switch (format) {
    case Format::Ply:
      return detail::read_ply(bytes, path, nullptr);
    case Format::Pcd:
      return detail::read_pcd(bytes, path);
    case Format::Xyz:
      return detail::read_text(bytes, path);
    case Format::KittiBin:
      return detail::read_kitti(bytes, path);
    case Format::Vtk:
      return detail::read_vtk(bytes, path);
    case Format::Npy:
      return detail::read_npy(bytes, path);
    case Format::Auto:
      break;
  }
  detail::fail(path, "unknown point-cloud format");
}

}  // namespace

Format format_from_extension(const std::filesystem::path& path) {
  const auto ext = lower(path.extension().string());
  for (const auto& rule : kExtensions)
    if (rule.extension == ext) return rule.format;
  return Format::Auto;
}

ReadResult read_cloud(const std::filesystem::path& path, const ReadOptions& options) {
  const auto bytes = detail::read_file(path);
  auto format = options.format;
  if (format == Format::Auto) format = format_from_extension(path);
  if (format == Format::Auto) format = sniff(bytes);
  return detail::finish(decode(format, bytes, path), path, options);
}

PointCloud load_cloud(const std::filesystem::path& path, const ReadOptions& options) {
  return read_cloud(path, options).cloud;
}

void save_cloud(const std::filesystem::path& path, const PointCloud& cloud) {
  const auto ext = lower(path.extension().string());
  switch (format_from_extension(path)) {
    case Format::Ply:
      return write_ply(path, cloud);
    case Format::Pcd:
      return write_pcd(path, cloud);
    case Format::Xyz:
      return detail::write_text(path, cloud, ext == ".csv" ? ',' : ' ');
    default:
      break;
  }
  detail::fail(path,
               "cannot save: unknown extension '" + ext + "' (use .ply, .pcd, .xyz, .txt or .csv)");
}

}  // namespace cairn::io
