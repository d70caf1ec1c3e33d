#pragma once
// Helpers shared by the IO translation units (ply.cpp, pcd.cpp, text.cpp, io.cpp); not part of
// the public API.
#include <cstring>
#include <string>
#include <string_view>

#include "cairn/core/io/io.hpp"

namespace cairn::io {

// Internal helpers shared by the format implementations (io.cpp, ply.cpp, pcd.cpp, text.cpp).
// Not part of the public API: they may change at any time.
namespace detail {

using std::filesystem::path;

inline constexpr std::size_t kMaxQuotedLine = 60;  // longest header line quoted in an error message

inline constexpr bool kHostLittleEndian = std::endian::native == std::endian::little;

/// A cloud as decoded from a file, before the common post-processing of read_cloud
/// (non-finite policy, recentering, empty check).
struct RawCloud {
  std::vector<Vec3d> xyz;       // coordinates as stored in the file (world frame)
  PointCloud attributes;        // normals, colours, ... (attributes.points stays empty)
  std::optional<Vec3d> origin;  // origin recorded by a cairn writer ("cairn_origin" comment)
};

/// Binary scalar types of PLY / PCD / NumPy data.
enum class Scalar : std::uint8_t {
  Int8,
  UInt8,
  Int16,
  UInt16,
  Int32,
  UInt32,
  Int64,
  UInt64,
  Float32,
  Float64
};
std::size_t scalar_size(Scalar type);
bool is_floating(Scalar type);

[[noreturn]] void fail(const path& file, const std::string& problem);
[[noreturn]] void fail_truncated(const path& file, std::size_t expected, std::size_t read,
                                 const std::string& items = "points");
std::string read_file(const path& file);
void write_file(const path& file, std::string_view bytes);

/// "\r\n", "\n" or "\r": the terminator of the first line of `text` ("\n" if none).
std::string_view line_ending(std::string_view text);
/// Whitespace-separated words of a line.
std::vector<std::string_view> split_words(std::string_view line);
/// Number parsing (std::from_chars, also accepts a leading '+'); false if not entirely a number.
bool parse_number(std::string_view token, double& value);
/// Largest count a header may give: more than any file a reader is handed holds, and small
/// enough that the count times a record size cannot overflow.
inline constexpr double kMaxCount = 1099511627776.0;  // 2^40
/// A count from a header or an index: a whole number in [0, kMaxCount], else InputError naming
/// `what` (the cast of a larger or non-finite double to an integer is undefined behaviour).
std::size_t parse_count(std::string_view token, const path& file, std::string_view what);

/// Whitespace-separated tokens of a text buffer, tracking line numbers (LF, CRLF or CR).
/// `file` (named in errors) must outlive the Tokens.
class Tokens {
 public:
  Tokens(std::string_view text, const path& file, std::size_t first_line = 1);
  /// Next token; empty at the end of the text.
  std::string_view next();
  /// Next token as a number: false at the end, InputError (naming the line) if not numeric.
  bool number(double& value);
  [[nodiscard]] std::size_t line() const { return line_; }

 private:
  std::string_view text_;
  const path& file_;
  std::size_t pos_ = 0;
  std::size_t line_;
};

/// Decodes n values of `type` found at data, data + stride, ... (byte-swapped if swap).
void decode_column(const char* data, std::size_t stride, std::size_t n, Scalar type, bool swap,
                   double* out);
/// Encodes n values as `type` to out, out + stride, ... (byte-swapped if swap).
void encode_column(const double* values, std::size_t n, Scalar type, bool swap, char* out,
                   std::size_t stride);
/// Appends a value as text: shortest round-trip form for floats, integer form otherwise.
void append_value(std::string& out, double value, Scalar type);

/// How colour channels are stored: bytes 0..255 or floats 0..1.
enum class ColorScale { Byte, Unit };
/// Stores a decoded column (values[first], values[first + stride], ...; one per point of
/// raw.xyz) into the slot its name selects: x y z, nx/normal_x..., red/r/diffuse_red...,
/// time/timestamp/t, label, anything else a ScalarField. Names are matched case-insensitively.
/// `first` is an offset, not a pointer moved by it: an empty table's data() may be null.
void store_column(RawCloud& raw, std::string_view name, const double* values, std::size_t first,
                  std::size_t stride, ColorScale scale);
/// True if the name selects coordinate `axis` (0..2).
bool is_coordinate(std::string_view name, int axis);
/// InputError unless the names contain x, y and z.
void require_xyz(const std::vector<std::string>& names, const path& file);

/// One column of a cloud to write.
struct Column {
  std::string name;
  Scalar type;
  std::vector<double> values;
};
enum class ColumnStyle { Ply, Pcd };  // Pcd: normal_x..., packed "rgb"
/// The columns of a cloud: coordinates (float, or double world coordinates when the origin is
/// non-zero), normals, colours, time, label, then every scalar field.
/// Throws InputError (naming `file`) if a scalar field's name cannot be written and read back.
std::vector<Column> columns_of(const PointCloud& cloud, ColumnStyle style, const path& file);
/// Binary records, one per point, the columns in order (byte-swapped if swap).
std::string encode_records(const std::vector<Column>& columns, bool swap);
/// Text rows, one per point, values separated by `separator`.
void append_rows(std::string& out, const std::vector<Column>& columns, char separator);

/// Header comment recording a non-zero origin ("cairn_origin x y z"), and its parser.
std::string origin_comment(const Vec3d& origin);
std::optional<Vec3d> parse_origin_comment(std::string_view comment);

using Triangles = std::vector<std::array<std::uint32_t, 3>>;
RawCloud read_ply(std::string_view bytes, const path& file, Triangles* faces);
RawCloud read_pcd(std::string_view bytes, const path& file);
RawCloud read_text(std::string_view bytes, const path& file);
RawCloud read_kitti(std::string_view bytes, const path& file);
RawCloud read_vtk(std::string_view bytes, const path& file);
/// A NumPy .npy header (versions 1-3, C order only; throws InputError otherwise): the dtype
/// string (e.g. "<f4"), the shape, and where the data starts.
struct NpyHeader {
  std::string descr;
  std::vector<std::size_t> shape;
  std::size_t data_start = 0;
};
NpyHeader parse_npy_header(std::string_view bytes, const path& file);
RawCloud read_npy(std::string_view bytes, const path& file);
void write_text(const path& file, const PointCloud& cloud, char separator);

/// Common post-processing: empty check, non-finite policy, recentering.
ReadResult finish(RawCloud raw, const path& file, const ReadOptions& options);

}  // namespace detail

}  // namespace cairn::io
