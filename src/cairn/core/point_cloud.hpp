#pragma once
// The one point-cloud type of cairn: positions plus optional per-point attributes in parallel arrays.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <limits>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace cairn {

using Vec3f = Eigen::Vector3f;
using Vec3d = Eigen::Vector3d;

struct Rgb {
  std::uint8_t r = 0, g = 0, b = 0;
  bool operator==(const Rgb&) const = default;
};

/// A named per-point scalar that has no dedicated slot (intensity, ring, curvature, confidence...).
struct ScalarField {
  std::string name;
  std::vector<float> values;
  bool operator==(const ScalarField&) const = default;
};

/// Positions are float, relative to `origin` (double), so georeferenced clouds (UTM, ~1e6 m) keep
/// their precision: world = origin + point. Optional attributes are either empty or hold one
/// entry per point.
struct PointCloud {
  std::vector<Vec3f> points;
  std::vector<Vec3f> normals;
  std::vector<Rgb> colors;
  std::vector<double> times;          // per-point timestamps [s]
  std::vector<std::int32_t> labels;   // per-point integer labels
  std::vector<ScalarField> fields;    // any other scalar properties, kept through IO
  Vec3d origin = Vec3d::Zero();

  [[nodiscard]] std::size_t size() const { return points.size(); }
  [[nodiscard]] bool empty() const { return points.empty(); }
  [[nodiscard]] bool has_normals() const { return !normals.empty(); }
  [[nodiscard]] bool has_colors() const { return !colors.empty(); }
  [[nodiscard]] bool has_times() const { return !times.empty(); }
  [[nodiscard]] bool has_labels() const { return !labels.empty(); }

  /// Position in the world frame, in double precision.
  [[nodiscard]] Vec3d world(std::size_t i) const { return origin + points[i].cast<double>(); }

  /// Pointer to the field of that name, or nullptr.
  [[nodiscard]] const ScalarField* field(const std::string& name) const;
  [[nodiscard]] ScalarField* field(const std::string& name);

  /// Throws InputError if attribute arrays do not match the number of points.
  void check_consistent(const std::string& what = "point cloud") const;

  /// Throws InputError naming `what` and the first offending index if any coordinate is NaN/Inf.
  void check_finite(const std::string& what = "point cloud") const;

  void reserve(std::size_t n);
};

/// Copy of the points with the given indices (all attributes carried along).
[[nodiscard]] PointCloud select(const PointCloud& cloud, std::span<const std::uint32_t> indices);

/// Removes points whose coordinates are not finite. Returns the kept indices (in input order).
std::vector<std::uint32_t> remove_non_finite(PointCloud& cloud);

/// Appends `b` to `a` (attributes kept only when both clouds have them; origins reconciled).
void append(PointCloud& a, const PointCloud& b);

struct Aabb {
  Vec3f min = Vec3f::Constant(std::numeric_limits<float>::max());
  Vec3f max = Vec3f::Constant(std::numeric_limits<float>::lowest());
};
[[nodiscard]] Aabb bounds(std::span<const Vec3f> points);

/// Arithmetic mean of positions (double accumulation).
[[nodiscard]] Vec3f centroid(std::span<const Vec3f> points);
[[nodiscard]] Vec3f centroid(std::span<const Vec3f> points, std::span<const std::uint32_t> indices);

}  // namespace cairn
