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
#include <string>
#include <vector>

#include "cairn/core/io/io.hpp"
#include "cairn/core/point_cloud.hpp"
#include "cairn/sim/convex_decomposition.hpp"

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

  template <class V>
  void visit(V& v) {
    v("size_x", size_x, "[m] terrain extent along x (centred at the origin)");
    v("size_y", size_y, "[m] terrain extent along y");
    v("slope_x", slope_x, "mean slope along x (rise/run)");
    v("slope_y", slope_y, "mean slope along y");
    v("bump_amplitude", bump_amplitude, "[m] smooth undulations (3-8 m wavelengths)");
    v("roughness", roughness, "[m] gravel roughness (10 cm correlation)");
  }
};

struct StoneConfig {
  int count = 7;
  double min_volume = 0.5, max_volume = 1.0;  // [m^3], as the paper's Sec. 6.1 stones
  double min_spacing = 0.4;       // [m] minimum gap between stones' horizontal footprints
  double placement_radius = 4.0;  // [m] stone centroids lie within this radius (~50 m^2)
  double flat_fraction = 0.3;     // share of flat (slab-like) stones vs roundish ones
  double embed_depth = 0.03;      // [m] how deep the lowest point sinks below the terrain
  /// Centre of the placement ellipse [m] and the ratio of its y to its x semi-axis.
  double center_x = 0.0, center_y = 0.0;
  double placement_aspect = 1.0;
  /// Keep-out disc (e.g. the excavator's footprint): no stone footprint reaches into it.
  double keep_out_x = 0.0, keep_out_y = 0.0, keep_out_radius = 0.0;  // [m]; radius 0 = none
  /// "spread": stones apart (footprints keep min_spacing), as the paper's experiments need;
  /// "pile": each stone slid against the ones placed before until they (almost) touch.
  std::string arrangement = "spread";
  /// Pile: the largest gap [m] left between a stone and its neighbour (bisection tolerance).
  double pile_gap = 0.01;
  /// Real scanned stone meshes (PLY, any unit: mm is detected and converted) used for a share
  /// of the stones, each scaled to the drawn volume; the rest are procedural rocks.
  std::vector<std::string> real_meshes;
  double real_fraction = 0.0;
  /// Tip each stone quasi-statically until its centroid lies over its support on the terrain, so
  /// it rests stably (checked in MuJoCo: tests/physics). Off by default to keep older sites.
  bool settle = false;
  /// The stones' collision shapes in the physics: convex parts where a mesh's hull adds more
  /// than max_excess of its volume (the real scanned stones' concavities).
  ConvexDecompositionConfig collision;

  template <class V>
  void visit(V& v) {
    v("count", count, "number of stones");
    v("min_volume", min_volume, "[m^3] smallest stone volume (paper: 0.5)");
    v("max_volume", max_volume, "[m^3] largest stone volume (paper: 1)");
    v("min_spacing", min_spacing, "[m] gap between footprints (spread)");
    v("placement_radius", placement_radius, "[m] x semi-axis of the placement ellipse");
    v("placement_aspect", placement_aspect, "y / x semi-axis ratio of the placement ellipse");
    v("center_x", center_x, "[m] placement centre x");
    v("center_y", center_y, "[m] placement centre y");
    v("flat_fraction", flat_fraction, "share of slab-like procedural stones");
    v("embed_depth", embed_depth, "[m] how deep the lowest point sinks into the terrain");
    v("keep_out_x", keep_out_x, "[m] keep-out disc centre x (the machine)");
    v("keep_out_y", keep_out_y, "[m] keep-out disc centre y");
    v("keep_out_radius", keep_out_radius, "[m] keep-out disc radius (0 = none)");
    v("arrangement", arrangement, "spread | pile");
    v("pile_gap", pile_gap, "[m] largest gap between touching stones (pile)");
    v("real_meshes", real_meshes, "PLY meshes of real scanned stones");
    v("real_fraction", real_fraction, "share of stones made from real meshes");
    v("settle", settle, "tip stones until they rest stably on the terrain");
    v("collision", collision, "convex parts of the stones' collision shapes (physics)");
  }
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

  template <class V>
  void visit(V& v) {
    v("spacing", spacing, "[m] point spacing on all surfaces");
    v("noise_sigma", noise_sigma, "[m] position noise");
    v("true_normals", true_normals, "also store the true surface normals");
    v("visibility", visibility, "keep only points visible from the viewpoints");
    v("ring_viewpoints", ring_viewpoints, "viewpoints on the ring");
    v("ring_radius", ring_radius, "[m] ring radius around the site centre");
    v("ring_height", ring_height, "[m] ring height above the terrain");
    v("overhead_height", overhead_height, "[m] overhead viewpoint height");
    v("visibility_step", visibility_step, "[m] line-of-sight step inside stone boxes");
  }
};

struct SiteConfig {
  TerrainConfig terrain;
  StoneConfig stones;

  template <class V>
  void visit(V& v) {
    v("terrain", terrain, "terrain height field");
    v("stones", stones, "stones and their placement");
  }
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
  std::string source = "procedural";  // or the file name of the real scanned mesh
  double yaw = 0.0;            // [rad] rotation about the vertical applied to the stone's mesh
  Eigen::AlignedBox3d bounds;  // world-frame bounding box of the mesh
  /// Convex parts the physics collides (points fixed to the mesh's vertices by index, so they
  /// move with it; replacing the mesh invalidates them); empty: the mesh's own hull
  /// (StoneConfig::collision).
  std::vector<CollisionPart> collision_parts;
};

/// The point sets whose convex hulls the physics collides for a stone, in the world frame: one
/// per collision part, or all mesh vertices when it has none.
std::vector<std::vector<Eigen::Vector3d>> collision_point_sets(const Stone& stone);

struct Site {
  TerrainConfig terrain_config;
  StoneConfig stone_config;
  Terrain terrain;
  std::vector<Stone> stones;
  /// The stones rest on the terrain as the physics holds it (sim::settle_site): physics scenes of
  /// this site start from these poses as they are, without seats carved under the stones or a
  /// gentle start, so the world stays where the sensors saw it.
  bool at_rest = false;
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

/// A real scanned stone mesh made ready for a site: units normalised (a mesh larger than
/// `kMillimetreThreshold` in extent is taken to be in mm), outward orientation, centred at its
/// volume centroid, principal axes aligned (longest along x, shortest along z so it rests on its
/// broad side), scaled to `target_volume` [m^3]. Throws InputError for unreadable or open meshes
/// (zero volume).
io::Mesh prepare_real_stone_mesh(const io::Mesh& raw, double target_volume);
inline constexpr double kMillimetreThreshold = 10.0;  // [extent units]

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
