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


}  // namespace cairn::io
