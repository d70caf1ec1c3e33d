// Text tables (XYZ / TXT / CSV / PTS), KITTI .bin, legacy VTK ASCII and NumPy .npy readers; the
// XYZ writer.
#include <algorithm>
#include <cmath>
#include <optional>
#include <utility>

#include "cairn/core/error.hpp"
#include "cairn/core/io/detail.hpp"

namespace cairn::io {
namespace {

using detail::fail;
using detail::Scalar;
using std::filesystem::path;

constexpr std::size_t kMinColumns = 3;          // x y z
constexpr std::size_t kColumnsWithNormals = 6;  // x y z nx ny nz
constexpr std::size_t kMaxQuotedToken = 40;     // longest token quoted in an error message
constexpr std::size_t kKittiValues = 4;         // float32 x y z intensity
constexpr std::size_t kKittiRecord = kKittiValues * sizeof(float);
constexpr std::string_view kVtkMagic = "# vtk DataFile";
constexpr std::string_view kNpyMagic = "\x93NUMPY";
constexpr std::size_t kNpyVersionOffset = kNpyMagic.size();      // major, minor byte
constexpr std::size_t kNpyLengthOffset = kNpyVersionOffset + 2;  // header length (LE)
constexpr std::size_t kNpyV1LengthBytes = 2;                     // v1: uint16; v2, v3: uint32
constexpr std::size_t kNpyV2LengthBytes = 4;

/// Next line of text (terminated by LF, CRLF or CR alone); false at the end.
bool next_line(std::string_view text, std::size_t& pos, std::string_view& line) {
  if (pos >= text.size()) return false;
  const auto end = std::min(text.find_first_of("\r\n", pos), text.size());
  line = text.substr(pos, end - pos);
  pos = end;
  if (pos < text.size() && text[pos] == '\r') ++pos;  // CR or CRLF
  if (pos < text.size() && text[pos] == '\n') ++pos;  // LF or CRLF
  return true;
}

/// Splits on whitespace, commas and semicolons (any run of them is one separator).
void split_values(std::string_view line, std::vector<std::string_view>& out) {
  out.clear();
  const auto sep = [](char c) { return c == ',' || c == ' ' || c == '\t' || c == ';'; };
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && sep(line[i])) ++i;
    const auto start = i;
    while (i < line.size() && !sep(line[i])) ++i;
    if (i > start) out.push_back(line.substr(start, i - start));
  }
}

std::string quoted(std::string_view token) {
  std::string q(1, '\'');
  return q.append(token.substr(0, kMaxQuotedToken)).append(1, '\'');
}

std::string at_line(std::size_t line) { return std::string("line ").append(std::to_string(line)).append(": "); }

/// x y z, then nx ny nz if `normals` and there are exactly 6 columns, else col3, col4, ...
std::vector<std::string> default_names(std::size_t columns, bool normals) {
  std::vector<std::string> names{"x", "y", "z"};
  const char* normal_names[] = {"nx", "ny", "nz"};
  const bool six_with_normals = normals && columns == kColumnsWithNormals;
  for (std::size_t c = kMinColumns; c < columns; ++c)
    names.push_back(six_with_normals ? normal_names[c - kMinColumns] : std::string("col").append(std::to_string(c)));
  return names;
}

struct Table {
  std::vector<std::string> names;  // from a header line, else empty
  std::vector<double> values;      // row-major
  std::size_t columns = 0;
  std::optional<Vec3d> origin;
};

/// Header names: "//X" (CloudCompare) and quotes are tolerated.
std::vector<std::string> header_names(const std::vector<std::string_view>& tokens) {
  std::vector<std::string> names;
  for (auto t : tokens) {
    if (names.empty() && t.starts_with("//")) t.remove_prefix(2);
    std::string name(t);
    std::erase(name, '"');
    names.push_back(name);
  }
  return names;
}

/// First row: a header (any non-numeric token) or a PTS point count (one integer) is consumed.
bool consume_first_row(const std::vector<std::string_view>& tokens, Table& t) {
  double v = 0;
  const bool numeric =
      std::all_of(tokens.begin(), tokens.end(), [&](auto s) { return detail::parse_number(s, v); });
  if (!numeric) {
    t.names = header_names(tokens);
    t.columns = t.names.size();
    return true;
  }
  return tokens.size() == 1 && v == std::floor(v);
}

void append_row(const std::vector<std::string_view>& tokens, std::size_t line, Table& t,
                const path& file) {
  if (tokens.size() < kMinColumns)
    fail(file, at_line(line) + "expected at least 3 numbers (x y z), found " +
                   std::to_string(tokens.size()));
  if (t.columns == 0) t.columns = tokens.size();
  if (tokens.size() != t.columns)
    fail(file, at_line(line) + std::to_string(tokens.size()) + " values, but " +
                   std::to_string(t.columns) + " columns are expected");
  for (const auto token : tokens) {
    double v = 0;
    if (!detail::parse_number(token, v))
      fail(file, at_line(line) + quoted(token) + " is not a number");
    t.values.push_back(v);
  }
}

Table parse_table(std::string_view text, const path& file) {
  Table t;
  std::vector<std::string_view> tokens;
  std::string_view line;
  bool first = true;
  for (std::size_t pos = 0, line_no = 1; next_line(text, pos, line); ++line_no) {
    split_values(line, tokens);
    if (tokens.empty()) continue;
    if (tokens[0].starts_with('#')) {
      if (auto origin = detail::parse_origin_comment(line)) t.origin = origin;
      continue;
    }
    if (std::exchange(first, false) && consume_first_row(tokens, t)) continue;
    append_row(tokens, line_no, t, file);
  }
  return t;
}

/// A raw cloud with n points from columns of width `stride` (column c starts at values + c).
detail::RawCloud raw_from_columns(const std::vector<std::string>& names, const double* values,
                                  std::size_t n, const path& file) {
  detail::require_xyz(names, file);
  detail::RawCloud raw;
  raw.xyz.assign(n, Vec3d::Zero());
  for (std::size_t c = 0; c < names.size(); ++c)
    detail::store_column(raw, names[c], values, c, names.size(), detail::ColorScale::Byte);
  return raw;
}

// ---- NumPy header dictionary, e.g. {'descr': '<f8', 'fortran_order': False, 'shape': (15953, 3),
// }

std::string_view dict_value(std::string_view dict, std::string_view key, const path& file) {
  const auto k = dict.find(key);
  const auto colon = k == std::string_view::npos ? k : dict.find(':', k + key.size());
  if (colon == std::string_view::npos) fail(file, "NumPy header has no '" + std::string(key) + "'");
  const auto start = dict.find_first_not_of(" \t", colon + 1);
  return start == std::string_view::npos ? std::string_view{} : dict.substr(start);
}

std::vector<std::size_t> parse_shape(std::string_view value, const path& file) {
  const auto close = value.find(')');
  if (!value.starts_with('(') || close == std::string_view::npos) fail(file, "bad NumPy shape");
  std::vector<std::string_view> parts;
  split_values(value.substr(1, close - 1), parts);
  std::vector<std::size_t> shape;
  for (const auto p : parts) {
    shape.push_back(detail::parse_count(p, file, "NumPy shape"));
  }
  return shape;
}

Scalar npy_type(std::string_view descr, const path& file) {
  if (descr == "<f8") return Scalar::Float64;
  if (descr == "<f4") return Scalar::Float32;
  fail(file, "unsupported NumPy dtype '" + std::string(descr) +
                 "' (only little-endian float32 '<f4' or float64 '<f8')");
}

}  // namespace

namespace detail {

RawCloud read_text(std::string_view bytes, const path& file) {
  const auto t = parse_table(bytes, file);
  auto names = t.names.empty() ? default_names(t.columns, true) : t.names;
  const auto has_axis = [&](int axis) {
    return std::any_of(names.begin(), names.end(),
                       [&](const auto& s) { return is_coordinate(s, axis); });
  };
  if (names.size() >= kMinColumns && !(has_axis(0) && has_axis(1) && has_axis(2)))
    std::copy_n(default_names(kMinColumns, false).begin(), kMinColumns,
                names.begin());  // positional x y z
  const auto n = t.columns == 0 ? 0 : t.values.size() / t.columns;
  auto raw = raw_from_columns(names, t.values.data(), n, file);
  raw.origin = t.origin;
  return raw;
}

RawCloud read_kitti(std::string_view bytes, const path& file) {
  if (bytes.size() % kKittiRecord != 0)
    fail(file, "KITTI .bin size " + std::to_string(bytes.size()) +
                   " is not a multiple of 16 bytes (float32 x y z intensity records)");
  const auto n = bytes.size() / kKittiRecord;
  const std::vector<std::string> names{"x", "y", "z", "intensity"};
  std::vector<double> values(n * kKittiValues);
  for (std::size_t c = 0; c < kKittiValues; ++c)
    decode_column(bytes.data() + c * sizeof(float), kKittiRecord, n, Scalar::Float32,
                  !kHostLittleEndian, values.data() + c * n);
  RawCloud raw;
  raw.xyz.assign(n, Vec3d::Zero());
  for (std::size_t c = 0; c < kKittiValues; ++c)
    store_column(raw, names[c], values.data(), c * n, 1, ColorScale::Byte);
  return raw;
}

/// Legacy VTK: "# vtk DataFile Version x", title, ASCII|BINARY, DATASET kind, ..., POINTS n type,
/// then 3n numbers. Everything after the points (cells, point data) is ignored.
RawCloud read_vtk(std::string_view bytes, const path& file) {
  std::size_t pos = 0, line_no = 0;
  std::string_view line;
  const auto next = [&] {
    if (!next_line(bytes, pos, line)) fail(file, "VTK file has no POINTS section");
    ++line_no;
    return split_words(line);
  };
  if (!bytes.starts_with(kVtkMagic)) fail(file, "not a legacy VTK file (no '# vtk DataFile' line)");
  next();
  next();  // title
  const auto encoding = next();
  if (encoding.empty() || encoding[0] != "ASCII")
    fail(file, encoding.size() == 1 && encoding[0] == "BINARY"
                   ? "binary VTK not supported (only legacy ASCII)"
                   : "bad VTK encoding line (expected ASCII)");
  auto words = next();
  while (words.size() < 2 || words[0] != "POINTS") words = next();
  const std::size_t n = parse_count(words[1], file, at_line(line_no) + "POINTS count");
  Tokens tokens(bytes.substr(pos), file, line_no + 1);
  std::vector<double> values;
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t k = 0; k < kMinColumns; ++k) {
      double v = 0;
      if (!tokens.number(v)) fail_truncated(file, n, i);
      values.push_back(v);
    }
  return raw_from_columns({"x", "y", "z"}, values.data(), n, file);
}

NpyHeader parse_npy_header(std::string_view bytes, const path& file) {
  if (!bytes.starts_with(kNpyMagic) || bytes.size() < kNpyLengthOffset + kNpyV1LengthBytes)
    fail(file, "not a NumPy .npy file (bad magic)");
  const int major = static_cast<unsigned char>(bytes[kNpyVersionOffset]);
  if (major < 1 || major > 3) fail(file, "unsupported .npy version " + std::to_string(major));
  const auto length_bytes = major == 1 ? kNpyV1LengthBytes : kNpyV2LengthBytes;
  if (bytes.size() < kNpyLengthOffset + length_bytes) fail(file, "truncated .npy header");
  double length = 0;
  decode_column(bytes.data() + kNpyLengthOffset, 0, 1, major == 1 ? Scalar::UInt16 : Scalar::UInt32,
                !kHostLittleEndian, &length);
  NpyHeader h;
  h.data_start = kNpyLengthOffset + length_bytes + static_cast<std::size_t>(length);
  if (bytes.size() < h.data_start) fail(file, "truncated .npy header");
  const auto dict = bytes.substr(kNpyLengthOffset + length_bytes, static_cast<std::size_t>(length));
  const auto value = dict_value(dict, "descr", file);
  const auto quote = value.empty() ? '\'' : value.front();
  h.descr = std::string(value.substr(1, value.find(quote, 1) - 1));
  if (!dict_value(dict, "fortran_order", file).starts_with("False"))
    fail(file, "Fortran-ordered .npy arrays are not supported");
  h.shape = parse_shape(dict_value(dict, "shape", file), file);
  return h;
}

RawCloud read_npy(std::string_view bytes, const path& file) {
  const NpyHeader h = parse_npy_header(bytes, file);
  const auto type = npy_type(h.descr, file);
  const auto& shape = h.shape;
  const auto data_start = h.data_start;
  if (shape.size() != 2 || shape[1] < kMinColumns)
    fail(file, "NumPy array must have shape (N, C) with C >= 3");
  const auto [n, columns] = std::pair{shape[0], shape[1]};
  if (n == 0) fail(file, "cloud is empty (0 points)");
  if (columns > bytes.size()) fail(file, "NumPy shape has more columns than the file has bytes");
  const auto record = columns * scalar_size(type);
  const auto available = (bytes.size() - data_start) / record;
  if (available < n) fail_truncated(file, n, available);
  std::vector<double> values(n * columns);
  for (std::size_t c = 0; c < columns; ++c)
    decode_column(bytes.data() + data_start + c * scalar_size(type), record, n, type,
                  !kHostLittleEndian, values.data() + c * n);
  RawCloud raw;  // values are column-major here
  raw.xyz.assign(n, Vec3d::Zero());
  const auto names = default_names(columns, false);
  for (std::size_t c = 0; c < columns; ++c)
    store_column(raw, names[c], values.data(), c * n, 1, ColorScale::Byte);
  return raw;
}

void write_text(const path& file, const PointCloud& cloud, char separator) {
  const auto columns = columns_of(cloud, ColumnStyle::Ply, file);
  std::string out = "# generated by cairn\n";
  if (!cloud.origin.isZero()) out += "# " + origin_comment(cloud.origin) + "\n";
  for (std::size_t c = 0; c < columns.size(); ++c)
    out += (c > 0 ? std::string(1, separator) : "") + columns[c].name;
  out += '\n';
  append_rows(out, columns, separator);
  write_file(file, out);
}

}  // namespace detail

void write_xyz(const std::filesystem::path& path, const PointCloud& cloud) {
  detail::write_text(path, cloud, ' ');
}

}  // namespace cairn::io
