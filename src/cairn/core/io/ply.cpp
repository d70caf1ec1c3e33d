// PLY reader / writer (ascii, binary_little_endian, binary_big_endian; vertex and face elements).
#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <type_traits>

#include "cairn/core/error.hpp"
#include "cairn/core/io/detail.hpp"

namespace cairn::io {
namespace {

using detail::fail;
using detail::Scalar;
using detail::Triangles;
using std::filesystem::path;

constexpr std::string_view kMagic = "ply";
constexpr std::string_view kEndHeader = "end_header";
constexpr std::size_t kMaxListLength = 1u << 20;  // longer lists mean a corrupt file
constexpr std::uint8_t kTriangleCorners = 3;

struct TypeName {
  std::string_view name;
  Scalar type;
};
// Classic names first: the writer uses the first name of a type.
constexpr TypeName kTypeNames[] = {
    {"char", Scalar::Int8},       {"uchar", Scalar::UInt8},    {"short", Scalar::Int16},
    {"ushort", Scalar::UInt16},   {"int", Scalar::Int32},      {"uint", Scalar::UInt32},
    {"float", Scalar::Float32},   {"double", Scalar::Float64}, {"int8", Scalar::Int8},
    {"uint8", Scalar::UInt8},     {"int16", Scalar::Int16},    {"uint16", Scalar::UInt16},
    {"int32", Scalar::Int32},     {"uint32", Scalar::UInt32},  {"float32", Scalar::Float32},
    {"float64", Scalar::Float64},
};

struct Property {
  std::string name;
  Scalar type = Scalar::Float32;     // value type; for a list, the item type
  std::optional<Scalar> count_type;  // set for list properties
};

struct Element {
  std::string name;
  std::size_t count = 0;
  std::vector<Property> props;

  [[nodiscard]] bool fixed_size() const {
    return std::none_of(props.begin(), props.end(), [](const auto& p) { return p.count_type; });
  }
  [[nodiscard]] std::size_t record_size() const {  // fixed-size elements only
    std::size_t size = 0;
    for (const auto& p : props) size += detail::scalar_size(p.type);
    return size;
  }
};

enum class Encoding { Ascii, BinaryLittle, BinaryBig };

struct Header {
  std::optional<Encoding> encoding;
  std::vector<Element> elements;
  std::optional<Vec3d> origin;
  std::size_t data_offset = 0;
  std::size_t lines = 0;
};

Scalar parse_type(std::string_view name, const path& file) {
  for (const auto& t : kTypeNames)
    if (t.name == name) return t.type;
  fail(file, "unsupported PLY property type '" + std::string(name) + "'");
}

std::string_view type_name(Scalar type) {
  return std::find_if(std::begin(kTypeNames), std::end(kTypeNames),
                      [&](const auto& t) { return t.type == type; })
      ->name;
}

Encoding parse_encoding(std::string_view word, const path& file) {
  if (word == "ascii") return Encoding::Ascii;
  if (word == "binary_little_endian") return Encoding::BinaryLittle;
  if (word == "binary_big_endian") return Encoding::BinaryBig;
  fail(file, "unknown PLY format '" + std::string(word) + "'");
}

Property parse_property(const std::vector<std::string_view>& w, const path& file) {
  if (w.size() == 3) return {std::string(w[2]), parse_type(w[1], file), std::nullopt};
  if (w.size() == 5 && w[1] == "list") {
    const auto count_type = parse_type(w[2], file);
    if (detail::is_floating(count_type)) fail(file, "PLY list count type must be an integer type");
    return {std::string(w[4]), parse_type(w[3], file), count_type};
  }
  fail(file, "malformed PLY property line");
}

void parse_header_line(std::string_view line, Header& h, const path& file) {
  const auto w = detail::split_words(line);
  if (w.empty() || w[0] == "obj_info") return;
  if (w[0] == "comment") {
    if (auto origin = detail::parse_origin_comment(line)) h.origin = origin;
  } else if (w[0] == "format" && w.size() >= 2) {
    h.encoding = parse_encoding(w[1], file);
  } else if (w[0] == "element" && w.size() == 3) {
    h.elements.push_back({std::string(w[1]), detail::parse_count(w[2], file, "PLY element count"), {}});
  } else if (w[0] == "property" && !h.elements.empty()) {
    h.elements.back().props.push_back(parse_property(w, file));
  } else {
    fail(file, "unexpected PLY header line '" + std::string(line.substr(0, detail::kMaxQuotedLine)) + "'");
  }
}

/// Header lines end with the terminator of the magic line: LF, CRLF or CR alone (Rhino). Using
/// that exact terminator matters after end_header: binary data may start with a '\n' byte.
Header parse_header(std::string_view bytes, const path& file) {
  const auto eol = detail::line_ending(bytes);
  if (!bytes.starts_with(kMagic) || bytes.substr(kMagic.size(), eol.size()) != eol)
    fail(file, "not a PLY file (missing 'ply' magic line)");
  Header h;
  std::size_t pos = kMagic.size() + eol.size();
  for (h.lines = 2;; ++h.lines) {
    const auto end = bytes.find(eol, pos);
    if (end == std::string_view::npos) fail(file, "PLY header has no end_header line");
    const auto line = bytes.substr(pos, end - pos);
    pos = end + eol.size();
    if (detail::split_words(line) == std::vector<std::string_view>{kEndHeader}) break;
    parse_header_line(line, h, file);
  }
  if (!h.encoding) fail(file, "PLY header has no format line");
  for (const auto& e : h.elements)  // records of no bytes: a count nothing in the file can bound
    if (e.props.empty() && e.count > 0) fail(file, "PLY element '" + e.name + "' has no properties");
  h.data_offset = pos;
  return h;
}

// ---- Element readers, generic over the encoding. An input provides
//      bool value(Scalar, double&) and bool skip(count, Scalar); both return false at the end.

class BinaryIn {
 public:
  BinaryIn(std::string_view data, bool swap) : data_(data), swap_(swap) {}
  bool value(Scalar type, double& v) {
    const auto size = detail::scalar_size(type);
    if (data_.size() - pos_ < size) return false;
    detail::decode_column(data_.data() + pos_, 0, 1, type, swap_, &v);
    pos_ += size;
    return true;
  }
  bool skip(std::size_t count, Scalar type) {
    return skip_bytes(count * detail::scalar_size(type));
  }
  bool skip_bytes(std::size_t bytes) {
    if (data_.size() - pos_ < bytes) return false;
    pos_ += bytes;
    return true;
  }
  [[nodiscard]] std::string_view rest() const { return data_.substr(pos_); }
  [[nodiscard]] bool swap() const { return swap_; }

 private:
  std::string_view data_;
  bool swap_;
  std::size_t pos_ = 0;
};

class AsciiIn {
 public:
  explicit AsciiIn(detail::Tokens tokens) : tokens_(tokens) {}
  bool value(Scalar /*type*/, double& v) { return tokens_.number(v); }
  bool skip(std::size_t count, Scalar type) {
    double v = 0;
    for (std::size_t i = 0; i < count; ++i)
      if (!value(type, v)) return false;
    return true;
  }

 private:
  detail::Tokens tokens_;
};

/// Reads one record: scalar k to scalars[k]; the items of list property `wanted_list` to items
/// (other lists are skipped). False if the data ends first.
template <class In>
bool read_record(In& in, const Element& e, double* scalars, std::size_t wanted_list,
                 std::vector<double>& items, const path& file) {
  for (std::size_t k = 0; k < e.props.size(); ++k) {
    const auto& p = e.props[k];
    if (!p.count_type) {
      if (!in.value(p.type, scalars[k])) return false;
      continue;
    }
    double count = 0;
    if (!in.value(*p.count_type, count)) return false;
    if (!(count >= 0 && count <= double(kMaxListLength)) || count != std::floor(count))  // NaN too
      fail(file, "bad PLY list length " + std::to_string(count));
    const auto length = static_cast<std::size_t>(count);
    if (k != wanted_list) {
      if (!in.skip(length, p.type)) return false;
      continue;
    }
    items.resize(length);
    for (auto& item : items)
      if (!in.value(p.type, item)) return false;
  }
  return true;
}

detail::ColorScale color_scale(Scalar type) {
  return detail::is_floating(type) ? detail::ColorScale::Unit : detail::ColorScale::Byte;
}

/// Fast path: fixed-size binary records, decoded column by column.
detail::RawCloud read_vertex_columns(BinaryIn& in, const Element& e, const path& file) {
  const auto record = e.record_size();
  const auto available = in.rest().size() / record;
  if (available < e.count) detail::fail_truncated(file, e.count, available);
  detail::RawCloud raw;
  raw.xyz.assign(e.count, Vec3d::Zero());
  std::vector<double> column(e.count);
  std::size_t offset = 0;
  for (const auto& p : e.props) {
    detail::decode_column(in.rest().data() + offset, record, e.count, p.type, in.swap(),
                          column.data());
    detail::store_column(raw, p.name, column.data(), 0, 1, color_scale(p.type));
    offset += detail::scalar_size(p.type);
  }
  in.skip_bytes(record * e.count);
  return raw;
}

template <class In>
detail::RawCloud read_vertices(In& in, const Element& e, const path& file) {
  if constexpr (std::is_same_v<In, BinaryIn>)
    if (e.fixed_size()) return read_vertex_columns(in, e, file);
  const auto width = e.props.size();
  std::vector<double> rows, row(width), unused;
  for (std::size_t i = 0; i < e.count; ++i) {
    if (!read_record(in, e, row.data(), width, unused, file))
      detail::fail_truncated(file, e.count, i);
    rows.insert(rows.end(), row.begin(), row.end());
  }
  detail::RawCloud raw;
  raw.xyz.assign(e.count, Vec3d::Zero());
  for (std::size_t k = 0; k < width; ++k)
    if (!e.props[k].count_type)
      detail::store_column(raw, e.props[k].name, rows.data(), k, width,
                           color_scale(e.props[k].type));
  return raw;
}

/// Appends the polygon as a triangle fan (v0, vk, vk+1); polygons with < 3 corners are skipped.
void add_fan(const std::vector<double>& corners, std::size_t face, Triangles& out,
             const path& file) {
  const auto index = [&](std::size_t k) {
    const double c = corners[k];
    if (c < 0 || c != std::floor(c) || c > std::numeric_limits<std::uint32_t>::max())
      fail(file,
           "face " + std::to_string(face) + " has an invalid vertex index " + std::to_string(c));
    return static_cast<std::uint32_t>(c);
  };
  for (std::size_t k = 1; k + 1 < corners.size(); ++k)
    out.push_back({index(0), index(k), index(k + 1)});
}

template <class In>
void read_faces(In& in, const Element& e, Triangles& out, const path& file) {
  const auto list = std::find_if(e.props.begin(), e.props.end(), [](const Property& p) {
    return p.count_type && (p.name == "vertex_indices" || p.name == "vertex_index");
  });
  if (list == e.props.end()) fail(file, "PLY face element has no vertex_indices list");
  const auto wanted = static_cast<std::size_t>(list - e.props.begin());
  std::vector<double> scalars(e.props.size()), corners;
  for (std::size_t f = 0; f < e.count; ++f) {
    if (!read_record(in, e, scalars.data(), wanted, corners, file))
      detail::fail_truncated(file, e.count, f, "faces");
    add_fan(corners, f, out, file);
  }
}

template <class In>
void skip_element(In& in, const Element& e, const path& file) {
  const auto items = "'" + e.name + "' elements";
  if constexpr (std::is_same_v<In, BinaryIn>) {
    if (e.fixed_size()) {
      const auto available = in.rest().size() / std::max<std::size_t>(e.record_size(), 1);
      if (!in.skip_bytes(e.record_size() * e.count))
        detail::fail_truncated(file, e.count, available, items);
      return;
    }
  }
  std::vector<double> scalars(e.props.size()), unused;
  for (std::size_t i = 0; i < e.count; ++i)
    if (!read_record(in, e, scalars.data(), e.props.size(), unused, file))
      detail::fail_truncated(file, e.count, i, items);
}

void check_indices(const Triangles& triangles, std::size_t vertices, const path& file) {
  for (std::size_t t = 0; t < triangles.size(); ++t)
    for (const auto v : triangles[t])
      if (v >= vertices)
        fail(file, "triangle " + std::to_string(t) + " references vertex " + std::to_string(v) +
                       ", but there are only " + std::to_string(vertices) + " vertices");
}

/// Reads the elements in file order; stops once the vertices (and faces, if wanted) are read.
template <class In>
detail::RawCloud read_elements(In& in, const Header& h, const path& file, Triangles* faces) {
  const auto vertex = std::find_if(h.elements.begin(), h.elements.end(),
                                   [](const Element& e) { return e.name == "vertex"; });
  if (vertex == h.elements.end()) fail(file, "PLY file has no vertex element");
  std::vector<std::string> names;
  for (const auto& p : vertex->props) names.push_back(p.name);
  detail::require_xyz(names, file);

  detail::RawCloud raw;
  bool have_vertices = false, have_faces = faces == nullptr;
  for (auto e = h.elements.begin(); e != h.elements.end() && !(have_vertices && have_faces); ++e) {
    if (e == vertex) {
      raw = read_vertices(in, *e, file);
      have_vertices = true;
    } else if (faces && !have_faces && e->name == "face") {
      read_faces(in, *e, *faces, file);
      have_faces = true;
    } else {
      skip_element(in, *e, file);
    }
  }
  if (faces) check_indices(*faces, raw.xyz.size(), file);
  raw.origin = h.origin;
  return raw;
}

// ---- Writer

std::string header_text(const std::vector<detail::Column>& columns, const PointCloud& cloud,
                        std::size_t faces, PlyEncoding encoding) {
  constexpr std::string_view kFormats[] = {"binary_little_endian", "binary_big_endian", "ascii"};
  std::string h = "ply\nformat " + std::string(kFormats[static_cast<int>(encoding)]) + " 1.0\n";
  h += "comment generated by cairn\n";
  if (!cloud.origin.isZero()) h += "comment " + detail::origin_comment(cloud.origin) + "\n";
  h += "element vertex " + std::to_string(cloud.size()) + "\n";
  for (const auto& c : columns)
    h += "property " + std::string(type_name(c.type)) + " " + c.name + "\n";
  if (faces > 0)
    h += "element face " + std::to_string(faces) + "\nproperty list uchar int vertex_indices\n";
  return h + std::string(kEndHeader) + "\n";
}

void append_faces(std::string& out, const Triangles& triangles, PlyEncoding encoding) {
  if (encoding == PlyEncoding::Ascii) {
    for (const auto& t : triangles)
      out += "3 " + std::to_string(t[0]) + " " + std::to_string(t[1]) + " " + std::to_string(t[2]) +
             "\n";
    return;
  }
  const bool swap = (encoding == PlyEncoding::BinaryBigEndian) == detail::kHostLittleEndian;
  constexpr std::size_t kIndexBytes = 4;
  constexpr std::size_t kRecord = 1 + kTriangleCorners * kIndexBytes;  // uchar count + 3 int
  const auto start = out.size();
  out.resize(start + triangles.size() * kRecord);
  for (std::size_t f = 0; f < triangles.size(); ++f) {
    char* record = out.data() + start + f * kRecord;
    record[0] = static_cast<char>(kTriangleCorners);
    const double corners[] = {double(triangles[f][0]), double(triangles[f][1]),
                              double(triangles[f][2])};
    detail::encode_column(corners, kTriangleCorners, Scalar::Int32, swap, record + 1, kIndexBytes);
  }
}

void write_ply_file(const path& file, const PointCloud& cloud, const Triangles& triangles,
                    PlyEncoding encoding) {
  check_indices(triangles, cloud.size(), file);
  const auto columns = detail::columns_of(cloud, detail::ColumnStyle::Ply, file);
  std::string out = header_text(columns, cloud, triangles.size(), encoding);
  if (encoding == PlyEncoding::Ascii)
    detail::append_rows(out, columns, ' ');
  else
    out += detail::encode_records(
        columns, (encoding == PlyEncoding::BinaryBigEndian) == detail::kHostLittleEndian);
  append_faces(out, triangles, encoding);
  detail::write_file(file, out);
}

}  // namespace

namespace detail {

RawCloud read_ply(std::string_view bytes, const path& file, Triangles* faces) {
  const auto header = parse_header(bytes, file);
  const auto data = bytes.substr(header.data_offset);
  if (*header.encoding == Encoding::Ascii) {
    AsciiIn in{Tokens(data, file, header.lines + 1)};
    return read_elements(in, header, file, faces);
  }
  const bool big = *header.encoding == Encoding::BinaryBig;
  BinaryIn in(data, big == kHostLittleEndian);
  return read_elements(in, header, file, faces);
}

}  // namespace detail

Mesh read_ply_mesh(const std::filesystem::path& path, const ReadOptions& options) {
  const auto bytes = detail::read_file(path);
  Triangles triangles;
  auto result = detail::finish(detail::read_ply(bytes, path, &triangles), path, options);
  if (!result.kept_indices.empty()) {  // drop triangles of dropped vertices, renumber the rest
    constexpr auto kDropped = std::numeric_limits<std::uint32_t>::max();
    std::vector<std::uint32_t> new_index(result.num_input, kDropped);
    for (std::uint32_t i = 0; i < result.kept_indices.size(); ++i)
      new_index[result.kept_indices[i]] = i;
    Triangles kept;
    for (const auto& t : triangles) {
      const std::array<std::uint32_t, 3> u{new_index[t[0]], new_index[t[1]], new_index[t[2]]};
      if (std::find(u.begin(), u.end(), kDropped) == u.end()) kept.push_back(u);
    }
    triangles = std::move(kept);
  }
  return {std::move(result.cloud), std::move(triangles)};
}

void write_ply(const std::filesystem::path& path, const PointCloud& cloud, PlyEncoding encoding) {
  write_ply_file(path, cloud, {}, encoding);
}

void write_ply_mesh(const std::filesystem::path& path, const Mesh& mesh, PlyEncoding encoding) {
  write_ply_file(path, mesh.vertices, mesh.triangles, encoding);
}

}  // namespace cairn::io
