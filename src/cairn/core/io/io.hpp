#pragma once
// Point-cloud file IO. Readers: PLY (ascii / binary LE / binary BE, any scalar property types,
// float or double coordinates, faces skipped or read as a mesh), PCD (ascii / binary /
// binary_compressed), XYZ/TXT/CSV (x y z [more columns], optional header line), KITTI .bin
// (float32 x y z intensity), legacy VTK ASCII POLYDATA, NumPy .npy (N×3+ float32/float64).
// Writers: binary PLY (default), ascii PLY, PCD (ascii / binary / binary_compressed), XYZ.
// Writers record a non-zero origin in a header comment ("cairn_origin x y z"); readers restore
// it, so a write -> read round trip reproduces the origin and the float positions.
// Every failure throws cairn::InputError with a message naming the file and the problem.
#include <array>
#include <bit>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "cairn/core/point_cloud.hpp"

namespace cairn::io {

enum class Format { Auto, Ply, Pcd, Xyz, KittiBin, Vtk, Npy };

/// Format from the file extension (.ply .pcd .xyz .txt .csv .pts .bin .vtk .npy); Auto if unknown.
Format format_from_extension(const std::filesystem::path& path);

struct ReadOptions {
  Format format = Format::Auto;  // Auto: by extension, then by content sniffing
  bool drop_non_finite = false;  // false: NaN/Inf coordinates are an error; true: dropped
  /// When any |coordinate| exceeds this [m], positions are stored relative to an origin (the
  /// bounding-box minimum rounded down to whole metres) so that float positions keep precision.
  /// A file with a "cairn_origin" comment gets that origin instead.
  double recenter_threshold = 1.0e4;
};

struct ReadResult {
  PointCloud cloud;
  std::size_t num_input = 0;                // points in the file (incl. dropped ones)
  std::vector<std::uint32_t> kept_indices;  // input index of each kept point; empty = all kept
};

/// Reads a point cloud. Throws InputError (missing file, unknown/wrong format, truncated data,
/// unsupported property type, non-finite coordinates unless dropped, empty cloud).
ReadResult read_cloud(const std::filesystem::path& path, const ReadOptions& options = {});

/// Convenience: read_cloud(path, options).cloud
PointCloud load_cloud(const std::filesystem::path& path, const ReadOptions& options = {});

struct Mesh {
  PointCloud vertices;
  std::vector<std::array<std::uint32_t, 3>> triangles;  // polygons are fan-triangulated
};

/// Reads a PLY mesh (vertex + face elements). A PLY without faces gives an empty triangle list.
Mesh read_ply_mesh(const std::filesystem::path& path, const ReadOptions& options = {});

enum class PlyEncoding { BinaryLittleEndian, BinaryBigEndian, Ascii };
enum class PcdEncoding { Ascii, Binary, BinaryCompressed };

/// Writes all attributes of the cloud (normals nx ny nz, colours red green blue, time as double,
/// label as int, every scalar field as float). Coordinates are written as double in the world
/// frame when the cloud has a non-zero origin, as float otherwise. Throws InputError on failure.
void write_ply(const std::filesystem::path& path, const PointCloud& cloud,
               PlyEncoding encoding = PlyEncoding::BinaryLittleEndian);
void write_ply_mesh(const std::filesystem::path& path, const Mesh& mesh,
                    PlyEncoding encoding = PlyEncoding::BinaryLittleEndian);
void write_pcd(const std::filesystem::path& path, const PointCloud& cloud,
               PcdEncoding encoding = PcdEncoding::Binary);
void write_xyz(const std::filesystem::path& path, const PointCloud& cloud);

/// Writes by extension (.ply binary, .pcd binary, .xyz/.txt/.pts text, .csv comma-separated).
void save_cloud(const std::filesystem::path& path, const PointCloud& cloud);

// Internal helpers shared by the format implementations (io.cpp, ply.cpp, pcd.cpp, text.cpp).
// Not part of the public API: they may change at any time.
namespace detail {

using std::filesystem::path;

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
/// Stores a decoded column (values[0], values[stride], ...; one per point of raw.xyz) into the
/// slot its name selects: x y z, nx/normal_x..., red/r/diffuse_red..., time/timestamp/t, label,
/// anything else a ScalarField. Names are matched case-insensitively.
void store_column(RawCloud& raw, std::string_view name, const double* values, std::size_t stride,
                  ColorScale scale);
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
RawCloud read_npy(std::string_view bytes, const path& file);
void write_text(const path& file, const PointCloud& cloud, char separator);

/// Common post-processing: empty check, non-finite policy, recentering.
ReadResult finish(RawCloud raw, const path& file, const ReadOptions& options);

}  // namespace detail

}  // namespace cairn::io
