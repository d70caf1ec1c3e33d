// PCD reader / writer (headers v0.5 - v0.7; DATA ascii, binary, binary_compressed), with a small
// LZF codec for binary_compressed.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <optional>

#include "cairn/core/error.hpp"
#include "cairn/core/io/detail.hpp"

namespace cairn::io {
namespace {

using detail::fail;
using detail::Scalar;
using std::filesystem::path;

constexpr std::size_t kSizeBytes = 4;       // binary_compressed: uint32 sizes before the block
constexpr std::size_t kSizePrefix = 2 * kSizeBytes;
constexpr int kRedShift = 16;
constexpr int kGreenShift = 8;

// ---- LZF (the liblzf stream format used by PCL). A control byte c < 32 starts a run of c + 1
// literal bytes; otherwise its top 3 bits hold (match length - 2), 7 meaning "add the next byte",
// and its low 5 bits with the following byte hold (distance back - 1) of the copy source.
constexpr unsigned kLzfMaxLiteral = 32;
constexpr unsigned kLzfLengthShift = 5;
constexpr unsigned kLzfLongLength = 7;
constexpr unsigned kLzfDistanceHighMask = 0x1F;
constexpr std::size_t kLzfMinMatch = 3;
constexpr std::size_t kLzfMaxMatch = kLzfLongLength + 0xFF + 2;  // 264
constexpr std::size_t kLzfMaxDistance = std::size_t{1} << 13;
constexpr unsigned kLzfHashBits = 14;
constexpr std::uint32_t kLzfHashMultiplier = 2654435761u;  // Knuth's multiplicative hash
constexpr unsigned kBitsPerByte = 8;
constexpr unsigned kByteMask = 0xFF;

std::string lzf_decompress(std::string_view in, std::size_t out_size, const path& file) {
  std::string out(out_size, '\0');
  const auto corrupt = [&] { fail(file, "corrupt binary_compressed data (bad LZF stream)"); };
  std::size_t ip = 0, op = 0;
  while (ip < in.size()) {
    const unsigned ctrl = static_cast<unsigned char>(in[ip++]);
    if (ctrl < kLzfMaxLiteral) {
      const std::size_t len = ctrl + 1;
      if (in.size() - ip < len || out.size() - op < len) corrupt();
      std::memcpy(out.data() + op, in.data() + ip, len);
      ip += len;
      op += len;
      continue;
    }
    std::size_t len = ctrl >> kLzfLengthShift;
    if (len == kLzfLongLength && ip < in.size()) len += static_cast<unsigned char>(in[ip++]);
    if (ip >= in.size()) corrupt();
    const std::size_t distance =
        ((ctrl & kLzfDistanceHighMask) << kBitsPerByte) + static_cast<unsigned char>(in[ip++]) + 1;
    len += 2;
    if (distance > op || out.size() - op < len) corrupt();
    for (std::size_t k = 0; k < len; ++k, ++op) out[op] = out[op - distance];  // may overlap
  }
  if (op != out.size()) corrupt();
  return out;
}

class LzfWriter {
 public:
  explicit LzfWriter(std::string& out) : out_(out) {}
  void literal(char c) {
    if (run_ == 0) out_ += '\0';  // control byte, set when the run closes
    out_ += c;
    if (++run_ == kLzfMaxLiteral) close_run();
  }
  void match(std::size_t length, std::size_t distance) {
    close_run();
    const std::size_t len = length - 2, off = distance - 1;
    const auto high = static_cast<unsigned>(off >> kBitsPerByte);
    if (len < kLzfLongLength) {
      out_ += static_cast<char>(len << kLzfLengthShift | high);
    } else {
      out_ += static_cast<char>(kLzfLongLength << kLzfLengthShift | high);
      out_ += static_cast<char>(len - kLzfLongLength);
    }
    out_ += static_cast<char>(off & kByteMask);
  }
  void close_run() {
    if (run_ > 0) out_[out_.size() - run_ - 1] = static_cast<char>(run_ - 1);
    run_ = 0;
  }

 private:
  std::string& out_;
  std::size_t run_ = 0;
};

std::uint32_t lzf_hash(std::string_view in, std::size_t i) {
  const auto b = [&](std::size_t k) {
    return std::uint32_t{static_cast<unsigned char>(in[i + k])};
  };
  const std::uint32_t v = b(0) << (2 * kBitsPerByte) | b(1) << kBitsPerByte | b(2);
  return (v * kLzfHashMultiplier) >> (32 - kLzfHashBits);
}

/// Greedy LZF compression with a hash table of the last position of each 3-byte sequence.
std::string lzf_compress(std::string_view in) {
  std::string out;
  out.reserve(in.size() + in.size() / kLzfMaxLiteral + 1);
  LzfWriter writer(out);
  constexpr auto kNone = std::numeric_limits<std::size_t>::max();
  std::vector<std::size_t> last(std::size_t{1} << kLzfHashBits, kNone);
  std::size_t ip = 0;
  while (ip < in.size()) {
    if (ip + kLzfMinMatch > in.size()) {
      writer.literal(in[ip++]);
      continue;
    }
    const auto h = lzf_hash(in, ip);
    const auto ref = last[h];
    last[h] = ip;
    if (ref == kNone || ip - ref > kLzfMaxDistance ||
        in.compare(ref, kLzfMinMatch, in.substr(ip, kLzfMinMatch)) != 0) {
      writer.literal(in[ip++]);
      continue;
    }
    const auto max_len = std::min(kLzfMaxMatch, in.size() - ip);
    std::size_t len = kLzfMinMatch;
    while (len < max_len && in[ref + len] == in[ip + len]) ++len;
    writer.match(len, ip - ref);
    for (std::size_t p = ip + 1; p < ip + len && p + kLzfMinMatch <= in.size(); ++p)
      last[lzf_hash(in, p)] = p;
    ip += len;
  }
  writer.close_run();
  return out;
}

// ---- Header

enum class Data { Ascii, Binary, Compressed };

struct Field {
  std::string name;
  char kind = 'F';        // F (float), I (signed), U (unsigned)
  std::size_t size = 4;   // bytes per element
  std::size_t count = 1;  // elements per point; only the first is read
  Scalar type = Scalar::Float32;

  [[nodiscard]] std::size_t bytes() const { return size * count; }
  [[nodiscard]] bool skipped() const { return name == "_" || count == 0; }  // "_": padding
  /// rgb (float holding the bits of 0x00RRGGBB) or rgba (uint32).
  [[nodiscard]] bool packed_color() const { return (name == "rgb" || name == "rgba") && size == 4; }
};

constexpr std::size_t kMaxFieldCount = std::size_t{1} << 20;  // elements per field (histograms: hundreds)
/// binary_compressed (LZF) expands at most ~100× in practice; a header claiming more data is corrupt.
constexpr std::size_t kMaxCompression = 1024;

struct Header {
  std::vector<Field> fields;
  std::size_t points = 0;
  Data data = Data::Ascii;
  std::size_t data_offset = 0;
  std::size_t lines = 0;  // header lines, DATA included
  std::optional<Vec3d> origin;

  [[nodiscard]] std::size_t record_size() const {
    std::size_t size = 0;
    for (const auto& f : fields) size += f.bytes();
    return size;
  }
};

struct HeaderWords {
  std::vector<std::string_view> fields, sizes, types, counts;
};

Scalar scalar_of(char kind, std::size_t size, const path& file) {
  struct Rule {
    char kind;
    std::size_t size;
    Scalar type;
  };
  static constexpr Rule kRules[] = {
      {'F', 4, Scalar::Float32}, {'F', 8, Scalar::Float64}, {'I', 1, Scalar::Int8},
      {'I', 2, Scalar::Int16},   {'I', 4, Scalar::Int32},   {'I', 8, Scalar::Int64},
      {'U', 1, Scalar::UInt8},   {'U', 2, Scalar::UInt16},  {'U', 4, Scalar::UInt32},
      {'U', 8, Scalar::UInt64},
  };
  for (const auto& r : kRules)
    if (r.kind == kind && r.size == size) return r.type;
  fail(file,
       std::string("unsupported PCD field type '") + kind + "' of size " + std::to_string(size));
}

std::size_t to_size(const std::vector<std::string_view>& words, std::size_t i, const path& file) {
  if (i >= words.size()) fail(file, "bad number in PCD header");
  return detail::parse_count(words[i], file, "number in PCD header");
}

Data parse_data(const std::vector<std::string_view>& words, const path& file) {
  const auto word = words.size() > 1 ? words[1] : std::string_view{};
  if (word == "ascii") return Data::Ascii;
  if (word == "binary") return Data::Binary;
  if (word == "binary_compressed") return Data::Compressed;
  fail(file, "unknown PCD DATA type '" + std::string(word) + "'");
}

std::vector<Field> make_fields(const HeaderWords& w, const path& file) {
  const auto n = w.fields.size();
  if (n == 0) fail(file, "PCD header has no FIELDS line");
  const auto check = [&](const std::vector<std::string_view>& v, const char* key) {
    if (!v.empty() && v.size() != n)
      fail(file, std::string("PCD header: ") + key + " has " + std::to_string(v.size()) +
                     " entries for " + std::to_string(n) + " fields");
  };
  check(w.sizes, "SIZE");
  check(w.types, "TYPE");
  check(w.counts, "COUNT");
  std::vector<Field> fields(n);
  std::vector<std::string> names;
  for (std::size_t i = 0; i < n; ++i) {
    auto& f = fields[i];
    f.name = w.fields[i];
    if (!w.sizes.empty()) f.size = to_size(w.sizes, i, file);
    if (!w.types.empty()) f.kind = w.types[i].size() == 1 ? w.types[i][0] : '?';
    if (!w.counts.empty()) f.count = to_size(w.counts, i, file);
    if (f.count < 1 || f.count > kMaxFieldCount)
      fail(file, "PCD field '" + f.name + "' has COUNT " + std::to_string(f.count) + " (1 to " +
                     std::to_string(kMaxFieldCount) + ")");
    f.type = scalar_of(f.kind, f.size, file);
    names.push_back(f.name);
  }
  detail::require_xyz(names, file);
  return fields;
}

Header parse_header(std::string_view bytes, const path& file) {
  const auto eol = detail::line_ending(bytes);
  Header h;
  HeaderWords w;
  std::optional<std::size_t> width, height, points;
  std::size_t pos = 0;
  for (h.lines = 1;; ++h.lines) {
    const auto end = bytes.find(eol, pos);
    if (end == std::string_view::npos) fail(file, "not a PCD file (no DATA line in the header)");
    const auto line = bytes.substr(pos, end - pos);
    pos = end + eol.size();
    const auto words = detail::split_words(line);
    if (words.empty()) continue;
    const auto key = words[0];
    const std::vector<std::string_view> values(words.begin() + 1, words.end());
    if (key.starts_with('#')) {
      if (auto origin = detail::parse_origin_comment(line)) h.origin = origin;
    } else if (key == "FIELDS" || key == "COLUMNS") {
      w.fields = values;
    } else if (key == "SIZE") {
      w.sizes = values;
    } else if (key == "TYPE") {
      w.types = values;
    } else if (key == "COUNT") {
      w.counts = values;
    } else if (key == "WIDTH") {
      width = to_size(values, 0, file);
    } else if (key == "HEIGHT") {
      height = to_size(values, 0, file);
    } else if (key == "POINTS") {
      points = to_size(values, 0, file);
    } else if (key == "DATA") {
      h.data = parse_data(words, file);
      break;
    } else if (key != "VERSION" && key != "VIEWPOINT") {
      fail(file, "not a PCD file (unexpected header line '" +
                     std::string(line.substr(0, detail::kMaxQuotedLine)) + "')");
    }
  }
  h.data_offset = pos;
  h.fields = make_fields(w, file);
  std::size_t size = 0;  // points × record bytes must fit (a wrapped product would pass the size checks)
  if (!points && __builtin_mul_overflow(width.value_or(0), height.value_or(1), &h.points))
    fail(file, "PCD WIDTH × HEIGHT overflows");
  if (points) h.points = *points;
  if (__builtin_mul_overflow(h.points, h.record_size(), &size) || size > bytes.size() * kMaxCompression)
    fail(file, std::to_string(h.points) + " points of " + std::to_string(h.record_size()) +
                   " bytes cannot be in a file of " + std::to_string(bytes.size()) + " bytes");
  return h;
}

// ---- Data

/// Point i's value of field f is values[first + i * stride].
void store_field(detail::RawCloud& raw, const Field& f, const double* values, std::size_t first,
                 std::size_t stride) {
  if (!f.packed_color()) {
    const auto scale =
        detail::is_floating(f.type) ? detail::ColorScale::Unit : detail::ColorScale::Byte;
    detail::store_column(raw, f.name, values, first, stride, scale);
    return;
  }
  auto& colors = raw.attributes.colors;
  colors.resize(raw.xyz.size());
  for (std::size_t i = 0; i < colors.size(); ++i) {
    const auto v = static_cast<std::uint32_t>(values[first + i * stride]);
    colors[i] = {static_cast<std::uint8_t>(v >> kRedShift & kByteMask),
                 static_cast<std::uint8_t>(v >> kGreenShift & kByteMask),
                 static_cast<std::uint8_t>(v & kByteMask)};
  }
}

/// Decodes the fields of little-endian binary data: point-major (binary: x y z x y z ...) or
/// field-major (binary_compressed after unpacking: all x, then all y, ...).
detail::RawCloud decode_binary(const Header& h, const char* data, bool field_major) {
  const auto n = h.points;
  detail::RawCloud raw;
  raw.xyz.assign(n, Vec3d::Zero());
  std::vector<double> column(n);
  std::size_t offset = 0;
  for (const auto& f : h.fields) {
    const auto start = field_major ? offset * n : offset;
    const auto stride = field_major ? f.bytes() : h.record_size();
    offset += f.bytes();
    if (f.skipped()) continue;
    // Packed colours are read as their uint32 bits, whatever the declared type.
    const auto type = f.packed_color() ? Scalar::UInt32 : f.type;
    detail::decode_column(data + start, stride, n, type, !detail::kHostLittleEndian, column.data());
    store_field(raw, f, column.data(), 0, 1);
  }
  return raw;
}

detail::RawCloud read_binary(const Header& h, std::string_view data, const path& file) {
  const auto record = h.record_size();
  const auto available = record == 0 ? h.points : data.size() / record;
  if (available < h.points) detail::fail_truncated(file, h.points, available);
  return decode_binary(h, data.data(), false);
}

detail::RawCloud read_compressed(const Header& h, std::string_view data, const path& file) {
  if (data.size() < kSizePrefix) detail::fail_truncated(file, h.points, 0);
  double sizes[2];
  detail::decode_column(data.data(), kSizeBytes, 2, Scalar::UInt32, !detail::kHostLittleEndian,
                        sizes);
  const auto packed = static_cast<std::size_t>(sizes[0]);
  const auto unpacked = static_cast<std::size_t>(sizes[1]);
  if (unpacked != h.points * h.record_size())
    fail(file, "binary_compressed data unpacks to " + std::to_string(unpacked) + " bytes, but " +
                   std::to_string(h.points) + " points need " +
                   std::to_string(h.points * h.record_size()));
  if (data.size() - kSizePrefix < packed)
    fail(file, "truncated data: expected " + std::to_string(h.points) +
                   " points, read 0 (compressed block has " +
                   std::to_string(data.size() - kSizePrefix) + " of " + std::to_string(packed) +
                   " bytes)");
  const auto bytes = lzf_decompress(data.substr(kSizePrefix, packed), unpacked, file);
  return decode_binary(h, bytes.data(), true);
}

bool is_digits(std::string_view token) {
  return !token.empty() &&
         std::all_of(token.begin(), token.end(), [](char c) { return c >= '0' && c <= '9'; });
}

/// One ascii value. Packed colours become their uint32 bits: PCL writes an "rgb" field of type
/// F as an unsigned integer, older writers print the float itself.
double ascii_value(std::string_view token, const Field& f, std::size_t line, const path& file) {
  double v = 0;
  if (!detail::parse_number(token, v))
    fail(file, "line " + std::to_string(line) + ": '" +
                   std::string(token.substr(0, detail::kMaxQuotedLine)) + "' is not a number");
  if (!f.packed_color()) return v;
  if (f.kind == 'F' && !is_digits(token))
    return std::bit_cast<std::uint32_t>(static_cast<float>(v));
  // A packed colour is a 32-bit pattern (as unsigned or signed integer): anything else is no colour.
  constexpr double kLow = -2147483648.0, kHigh = 4294967295.0;
  if (!(v >= kLow && v <= kHigh))
    fail(file, "line " + std::to_string(line) + ": packed colour " + std::string(token.substr(0, detail::kMaxQuotedLine)) +
                   " is not a 32-bit value");
  return static_cast<std::uint32_t>(static_cast<std::int64_t>(v));
}

detail::RawCloud read_ascii(const Header& h, std::string_view data, const path& file) {
  detail::Tokens tokens(data, file, h.lines + 1);
  std::vector<const Field*> kept;
  for (const auto& f : h.fields)
    if (!f.skipped()) kept.push_back(&f);
  std::vector<double> rows;
  for (std::size_t i = 0; i < h.points; ++i)
    for (const auto& f : h.fields)
      for (std::size_t j = 0; j < f.count; ++j) {
        const auto token = tokens.next();
        if (token.empty()) detail::fail_truncated(file, h.points, i);
        if (j == 0 && !f.skipped()) rows.push_back(ascii_value(token, f, tokens.line(), file));
      }
  detail::RawCloud raw;
  raw.xyz.assign(h.points, Vec3d::Zero());
  for (std::size_t k = 0; k < kept.size(); ++k)
    store_field(raw, *kept[k], rows.data(), k, kept.size());
  return raw;
}

// ---- Writer

/// F, I or U. The packed "rgb" column is a uint32 and declared U, as PCL 1.13 writes it: with
/// F, PCL would read the ascii integer form as a float value.
char kind_of(const detail::Column& c) {
  if (detail::is_floating(c.type)) return 'F';
  const bool is_signed = c.type == Scalar::Int8 || c.type == Scalar::Int16 ||
                         c.type == Scalar::Int32 || c.type == Scalar::Int64;
  return is_signed ? 'I' : 'U';
}

std::string header_text(const std::vector<detail::Column>& columns, const PointCloud& cloud,
                        PcdEncoding encoding) {
  constexpr std::string_view kData[] = {"ascii", "binary", "binary_compressed"};
  std::string fields = "FIELDS", sizes = "SIZE", types = "TYPE", counts = "COUNT";
  for (const auto& c : columns) {
    (fields += ' ') += c.name;
    (sizes += ' ') += std::to_string(detail::scalar_size(c.type));
    (types += ' ') += kind_of(c);
    counts += " 1";
  }
  const auto n = std::to_string(cloud.size());
  std::string h = "# .PCD v0.7 - Point Cloud Data file format\n# generated by cairn\n";
  if (!cloud.origin.isZero()) h += "# " + detail::origin_comment(cloud.origin) + "\n";
  h += "VERSION 0.7\n" + fields + "\n" + sizes + "\n" + types + "\n" + counts + "\n";
  h += "WIDTH " + n + "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " + n + "\n";
  return h + "DATA " + std::string(kData[static_cast<int>(encoding)]) + "\n";
}

/// binary_compressed block: uint32 compressed size, uint32 raw size, LZF of the field-major data.
std::string compressed_block(const std::vector<detail::Column>& columns, const path& file) {
  const bool swap = !detail::kHostLittleEndian;
  std::size_t record = 0;
  for (const auto& c : columns) record += detail::scalar_size(c.type);
  const auto n = columns.front().values.size();
  std::string raw(n * record, '\0');
  std::size_t offset = 0;
  for (const auto& c : columns) {
    const auto size = detail::scalar_size(c.type);
    detail::encode_column(c.values.data(), n, c.type, swap, raw.data() + offset, size);
    offset += n * size;
  }
  auto packed = lzf_compress(raw);
  if (raw.size() > std::numeric_limits<std::uint32_t>::max())
    fail(file, "cloud too large for PCD binary_compressed (use binary)");
  const double sizes[] = {double(packed.size()), double(raw.size())};
  std::string block(kSizePrefix, '\0');
  detail::encode_column(sizes, 2, Scalar::UInt32, swap, block.data(), kSizeBytes);
  return block + packed;
}

}  // namespace

namespace detail {

RawCloud read_pcd(std::string_view bytes, const path& file) {
  const auto header = parse_header(bytes, file);
  const auto data = bytes.substr(header.data_offset);
  RawCloud raw = header.data == Data::Ascii    ? read_ascii(header, data, file)
                 : header.data == Data::Binary ? read_binary(header, data, file)
                                               : read_compressed(header, data, file);
  raw.origin = header.origin;
  return raw;
}

}  // namespace detail

void write_pcd(const std::filesystem::path& path, const PointCloud& cloud, PcdEncoding encoding) {
  const auto columns = detail::columns_of(cloud, detail::ColumnStyle::Pcd, path);
  std::string out = header_text(columns, cloud, encoding);
  switch (encoding) {
    case PcdEncoding::Ascii:
      detail::append_rows(out, columns, ' ');
      break;
    case PcdEncoding::Binary:
      out += detail::encode_records(columns, !detail::kHostLittleEndian);
      break;
    case PcdEncoding::BinaryCompressed:
      out += compressed_block(columns, path);
      break;
  }
  detail::write_file(path, out);
}

}  // namespace cairn::io
