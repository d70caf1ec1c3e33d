#pragma once
// Procedural stone site: a rough, sloped terrain with a handful of irregular, rock-like stones
// resting on it, plus a LiDAR-like surface sampler that produces a labelled, noisy point cloud.
// This is the seed of the simulator (ray casting, the excavator and physics come later).
//
// Everything is deterministic for a given seed: randomness comes from std::mt19937_64 through our
// own uniform / normal transforms (uniform01, standard_normal), never through the standard
// library's distributions, whose output differs between implementations.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <random>
#include <vector>

#include "cairn/core/io/io.hpp"
#include "cairn/core/point_cloud.hpp"

namespace cairn::sim {

// ---------------------------------------------------------------------------------------------
// Configuration

/// Terrain shape. Defaults describe a rough construction site.
struct TerrainConfig {
  double size_x = 12.0, size_y = 12.0;    // [m], centred at the origin
  double slope_x = 0.08, slope_y = 0.03;  // mean slope (rise/run)
  /// [m] smooth undulations: a sum of a few random 2-D sinusoids (wavelengths 3–8 m) whose RMS
  /// equals that of a single sinusoid of this amplitude (bump_amplitude / sqrt(2)).
  double bump_amplitude = 0.25;
  /// [m] gravel roughness at cm scale: smooth value noise with ~10 cm correlation; the lattice
  /// values have this standard deviation.
  double roughness = 0.015;
};

struct StoneConfig {
  int count = 7;
  double min_volume = 0.5, max_volume = 1.0;  // [m^3], as the paper's Sec. 6.1 stones
  double min_spacing = 0.4;       // [m] minimum gap between stones' horizontal footprints
  double placement_radius = 4.0;  // [m] stone centroids lie within this radius (~50 m^2)
  double flat_fraction = 0.3;     // share of flat (slab-like) stones vs roundish ones
  double embed_depth = 0.03;      // [m] how deep the lowest point sinks below the terrain
};

struct SamplingConfig {
  double spacing = 0.03;      // [m] LiDAR-like point spacing on all surfaces
  double noise_sigma = 0.01;  // [m] isotropic Gaussian position noise
  bool true_normals = false;  // also fill cloud.normals with the noise-free surface normals
  /// Keep only points that a sensor could see: a point is visible when the line of sight to at
  /// least one viewpoint is not blocked by a stone (and, for stone points, the surface faces
  /// it). Viewpoints: a ring around the site centre at cabin height (the swinging excavator's
  /// LiDARs) plus one overhead (the drone). Without it, stone undersides and the terrain under
  /// overhangs — which no sensor sees — would count as points of the scene.
  bool visibility = true;
  int ring_viewpoints = 8;
  double ring_radius = 5.0;     // [m]
  double ring_height = 3.5;     // [m] above the terrain at the site centre
  double overhead_height = 10.0;  // [m] above the terrain at the site centre
  double visibility_step = 0.03;  // [m] line-of-sight sampling step inside stone bounding boxes
};

struct SiteConfig {
  TerrainConfig terrain;
  StoneConfig stones;
};

// ---------------------------------------------------------------------------------------------
// Site

/// Height field z = height(x, y): mean slope + smooth undulations + cm-scale gravel roughness.
/// Defined everywhere (the roughness lattice is clamped beyond the site border).
struct Terrain {
  /// One undulation term: amplitude * sin(wave_vector . (x, y) + phase).
  struct Wave {
    Eigen::Vector2d wave_vector = Eigen::Vector2d::Zero();  // [rad/m]
    double amplitude = 0.0;                                 // [m]
    double phase = 0.0;                                     // [rad]
  };

  TerrainConfig config;
  std::vector<Wave> waves;
  // Roughness value noise: lattice of heights on a regular grid, smoothly interpolated.
  double noise_cell = 0.1;                                 // [m] lattice spacing
  Eigen::Vector2d noise_origin = Eigen::Vector2d::Zero();  // [m] position of lattice node (0, 0)
  int noise_nx = 0, noise_ny = 0;                          // lattice nodes along x / y
  std::vector<double> noise;                               // noise_nx * noise_ny, row-major in y

  /// Random terrain for the given configuration (waves and roughness lattice drawn from rng).
  static Terrain random(const TerrainConfig& config, std::mt19937_64& rng);

  [[nodiscard]] double height(double x, double y) const;
  /// Upward unit normal of the height field at (x, y).
  [[nodiscard]] Eigen::Vector3d normal(double x, double y) const;

 private:
  [[nodiscard]] double roughness_at(double x, double y) const;
};

struct Stone {
  io::Mesh mesh;  // world-frame closed triangle mesh (outward-oriented, origin zero)
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();  // world-frame volume centroid [m]
  double volume = 0.0;         // [m^3] (the mesh volume, equal to the drawn target volume)
  bool flat = false;           // slab-like stone
  double yaw = 0.0;            // [rad] rotation about the vertical applied to the stone's mesh
  Eigen::AlignedBox3d bounds;  // world-frame bounding box of the mesh
};

struct Site {
  TerrainConfig terrain_config;
  StoneConfig stone_config;
  Terrain terrain;
  std::vector<Stone> stones;
};

/// A random site. Throws ConfigError on invalid configuration values, or when the stones cannot
/// be placed with the requested spacing inside the placement radius.
Site generate_site(const SiteConfig& config, std::uint64_t seed);

// ---------------------------------------------------------------------------------------------
// Sampling

struct SampledSite {
  PointCloud cloud;                 // noisy points (world frame, origin zero), labels = truth
  std::vector<std::int32_t> truth;  // per point: -1 terrain, k = stone k
};

/// LiDAR-like sampling of the surfaces: terrain on a jittered grid (points inside stones dropped),
/// stone surfaces area-weighted (points below the terrain dropped), then Gaussian noise. There is
/// no occlusion: terrain under a stone's overhang is kept (ray casting comes later).
/// Throws ConfigError on invalid configuration values.
SampledSite sample_site(const Site& site, const SamplingConfig& config, std::uint64_t seed);

// ---------------------------------------------------------------------------------------------
// Geometry helpers

/// Irregular, rock-like closed mesh of exactly `target_volume` [m^3], centred at its centroid,
/// its shortest axis roughly along z (flat stones: thickness <= 0.35 of the horizontal extent).
io::Mesh make_stone_mesh(double target_volume, bool flat, std::mt19937_64& rng);

/// Unit sphere approximated by a subdivided icosahedron (20 * 4^subdivisions outward faces).
io::Mesh make_icosphere(int subdivisions);

/// Enclosed volume of a closed, outward-oriented triangle mesh (divergence theorem) [m^3].
double mesh_volume(const io::Mesh& mesh);

/// Volume centroid of a closed, outward-oriented triangle mesh (world frame).
Eigen::Vector3d mesh_centroid(const io::Mesh& mesh);

/// Whether p (world frame) lies inside the closed mesh (parity of a vertical ray's crossings).
/// For many queries against one mesh, build a SolidMesh once instead.
bool inside_mesh(const io::Mesh& mesh, const Eigen::Vector3d& p);

/// A closed, outward-oriented triangle mesh prepared for many inside queries: the triangles are
/// binned into a 2-D grid over the xy bounding box, so the upward vertical ray from a query
/// point only meets the triangles of one cell. Crossings are counted watertight: each edge
/// function is evaluated with its endpoints in index order (the two triangles sharing an edge
/// get exactly opposite values) and ties on an edge or vertex follow the top-left rule, so a ray
/// through an edge or vertex is counted once.
class SolidMesh {
 public:
  /// Throws InputError on out-of-range triangle indices.
  explicit SolidMesh(const io::Mesh& mesh);

  [[nodiscard]] bool contains(const Eigen::Vector3d& p) const;
  [[nodiscard]] const Eigen::AlignedBox3d& bounds() const { return bounds_; }

 private:
  struct Vertex {
    double x, y, z;
  };
  /// Whether the vertical line through (x, y) meets triangle t; if so, z is the meeting height.
  bool covers(std::uint32_t t, double x, double y, double& z) const;

  std::vector<Vertex> vertices_;
  std::vector<std::array<std::uint32_t, 3>> triangles_;
  std::vector<signed char> orientation_;  // sign of each triangle's projected (xy) area
  Eigen::AlignedBox3d bounds_;
  int nx_ = 1, ny_ = 1;                 // grid cells along x / y
  double cell_x_ = 1.0, cell_y_ = 1.0;  // [m]
  // Triangles of cell c: cell_triangles_[cell_begin_[c], cell_begin_[c + 1]).
  std::vector<std::uint32_t> cell_begin_;
  std::vector<std::uint32_t> cell_triangles_;
};

/// Uniform double in [0, 1) from the top 53 bits of one draw.
double uniform01(std::mt19937_64& rng);

/// Standard normal deviate (Box–Muller, one output per call).
double standard_normal(std::mt19937_64& rng);

}  // namespace cairn::sim
