#include "cairn/sim/procedural_site.hpp"

#include <tbb/parallel_for.h>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <filesystem>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <mutex>
#include <numbers>
#include <optional>
#include <sstream>
#include <string>
#include <unordered_map>

#include "cairn/core/error.hpp"

namespace cairn::sim {
namespace {

using Vec2d = Eigen::Vector2d;
using Triangle = std::array<std::uint32_t, 3>;

constexpr double kPi = std::numbers::pi;
constexpr double kTwoPi = 2.0 * std::numbers::pi;

struct Range {
  double lo, hi;
};

// Terrain ------------------------------------------------------------------------------------
constexpr int kTerrainWaveCount = 4;      // sinusoids making the undulations
constexpr Range kWavelength{3.0, 8.0};    // [m]
constexpr Range kWaveWeight{0.5, 1.0};    // relative amplitude of each sinusoid
constexpr double kRoughnessCell = 0.1;    // [m] gravel-noise correlation length
constexpr double kRoughnessMargin = 1.0;  // [m] lattice reach beyond the site
constexpr double kGradientStep = 1e-4;    // [m] central-difference step (normals)

// Stone shape ----------------------------------------------------------------------------------
constexpr int kStoneSubdivisions = 3;         // icosphere with 1280 faces
constexpr int kMaxIcosphereSubdivisions = 7;  // 327'680 faces
constexpr Range kMidAxis{0.72, 0.88};         // y / x semi-axis ratio (~0.8)
constexpr Range kRoundMinorAxis{0.62, 0.78};  // z / x for roundish stones (~0.7)
constexpr Range kFlatMinorAxis{0.28, 0.40};   // z / x for slabs (~0.35)
// Slab thickness / length at most; 0.35 * sqrt(2) < 0.5 keeps the world-frame min/max extent
// ratio below 0.5 for any yaw (a yaw shrinks the longest horizontal extent by at most sqrt(2)).
constexpr double kFlatMaxThickness = 0.35;
constexpr int kLobeCount = 5;          // Gaussian bulges / hollows on the sphere
constexpr Range kLobeWidth{0.4, 0.9};  // [rad] angular width of a lobe
constexpr Range kLobeWeight{0.5, 1.0};
constexpr int kSurfaceWaveCount = 3;              // low-frequency waves over directions
constexpr Range kSurfaceWaveFrequency{1.5, 3.0};  // [rad per unit of direction]
constexpr Range kSurfaceWaveWeight{0.3, 0.6};
constexpr Range kRadialAmplitude{0.10, 0.20};  // max relative radial perturbation
constexpr int kMinCuts = 3, kMaxCuts = 5;      // planar fracture facets per stone
constexpr Range kCutOffset{0.62, 0.85};        // plane offset / support along normal

// Placement and sampling -----------------------------------------------------------------------
constexpr double kMaxRoundTilt = 10.0 * kPi / 180.0;  // roundish stones rest slightly tilted
constexpr int kMaxPlacementAttempts = 10000;          // rejection samples per stone
constexpr int kMaxSettleSteps = 120;                  // tipping steps when settling
constexpr double kSettleStep = 0.5 * kPi / 180.0;     // [rad] per tipping step
constexpr double kSettleContact = 0.01;               // [m] above the terrain still counts as support
constexpr double kSettleMargin = 0.05;                // [m] centroid inside the support by this much
constexpr double kMaxTerrainSamples = 1e8;            // guard against absurd spacing
// Sequential placement jams now and then: the stones placed first leave no gap wide enough for a
// large later one (exp1 seed 24; exp2 seeds 8, 18, 21, 24, 25, 27, 28 ...). The stones' shapes and
// places are then drawn again from the continuing random sequence (which stones take a real mesh
// is kept), so every seed that placed its stones at once keeps its site.
constexpr int kMaxLayoutAttempts = 50;

// Inside queries -------------------------------------------------------------------------------
constexpr double kTrianglesPerCell = 2.0;  // SolidMesh grid density
constexpr int kMaxGridSide = 256;          // cells per axis at most
constexpr double kMinCellSize = 1e-9;      // [m] guards flat bounding boxes

double uniform(std::mt19937_64& rng, Range r) { return r.lo + (r.hi - r.lo) * uniform01(rng); }

std::size_t uniform_index(std::mt19937_64& rng, std::size_t n) {
  return std::min(n - 1, static_cast<std::size_t>(uniform01(rng) * static_cast<double>(n)));
}

Eigen::Vector3d random_unit(std::mt19937_64& rng) {
  const double z = 2.0 * uniform01(rng) - 1.0;
  const double phi = kTwoPi * uniform01(rng);
  const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
  return {r * std::cos(phi), r * std::sin(phi), z};
}

void require(bool ok, const std::string& message) {
  if (!ok) throw ConfigError(message);
}

void validate(const TerrainConfig& c) {
  require(std::isfinite(c.size_x) && std::isfinite(c.size_y) && c.size_x > 0 && c.size_y > 0,
          "TerrainConfig: size_x and size_y must be positive");
  require(std::isfinite(c.slope_x) && std::isfinite(c.slope_y), "TerrainConfig: slope not finite");
  require(std::isfinite(c.bump_amplitude) && c.bump_amplitude >= 0,
          "TerrainConfig: bump_amplitude must be >= 0");
  require(std::isfinite(c.roughness) && c.roughness >= 0, "TerrainConfig: roughness must be >= 0");
}

void validate(const StoneConfig& c) {
  require(c.count >= 0, "StoneConfig: count must be >= 0");
  require(std::isfinite(c.max_volume) && c.min_volume > 0 && c.min_volume <= c.max_volume,
          "StoneConfig: need 0 < min_volume <= max_volume");
  require(std::isfinite(c.min_spacing) && c.min_spacing >= 0, "StoneConfig: min_spacing < 0");
  require(std::isfinite(c.placement_radius) && c.placement_radius >= 0,
          "StoneConfig: placement_radius must be >= 0");
  require(c.flat_fraction >= 0 && c.flat_fraction <= 1, "StoneConfig: flat_fraction not in [0,1]");
  require(std::isfinite(c.embed_depth), "StoneConfig: embed_depth not finite");
  require(std::isfinite(c.center_x) && std::isfinite(c.center_y), "StoneConfig: centre not finite");
  require(std::isfinite(c.placement_aspect) && c.placement_aspect > 0,
          "StoneConfig: placement_aspect must be positive");
  require(std::isfinite(c.keep_out_x) && std::isfinite(c.keep_out_y) &&
              std::isfinite(c.keep_out_radius) && c.keep_out_radius >= 0,
          "StoneConfig: keep-out disc invalid");
  require(c.arrangement == "spread" || c.arrangement == "pile",
          "StoneConfig: arrangement must be 'spread' or 'pile'");
  require(std::isfinite(c.pile_gap) && c.pile_gap > 0, "StoneConfig: pile_gap must be positive");
  require(c.real_fraction >= 0 && c.real_fraction <= 1, "StoneConfig: real_fraction not in [0,1]");
  require(c.real_fraction == 0 || !c.real_meshes.empty(),
          "StoneConfig: real_fraction > 0 needs real_meshes");
  const ConvexDecompositionConfig& d = c.collision;
  require(std::isfinite(d.max_excess), "StoneConfig: collision.max_excess not finite");
  require(d.max_parts >= 1 && d.planes_per_axis >= 1 && d.grid_cells >= 2,
          "StoneConfig: collision needs max_parts >= 1, planes_per_axis >= 1, grid_cells >= 2");
  require(d.min_part_share > 0 && d.min_part_share < 0.5, "StoneConfig: collision.min_part_share not in (0, 0.5)");
}

void validate(const SamplingConfig& c, const TerrainConfig& t) {
  require(std::isfinite(c.spacing) && c.spacing > 0, "SamplingConfig: spacing must be positive");
  require(std::isfinite(c.noise_sigma) && c.noise_sigma >= 0,
          "SamplingConfig: noise_sigma must be >= 0");
  require(t.size_x * t.size_y / (c.spacing * c.spacing) <= kMaxTerrainSamples,
          "SamplingConfig: spacing too small for the site size");
}

// Meshes in double precision -------------------------------------------------------------------

struct RawMesh {
  std::vector<Eigen::Vector3d> v;
  std::vector<Triangle> t;
};

Eigen::AlignedBox3d bounding_box(const std::vector<Eigen::Vector3d>& v) {
  Eigen::AlignedBox3d box;
  for (const auto& p : v) box.extend(p);
  return box;
}

/// World-frame vertices of an io::Mesh; throws InputError on out-of-range triangle indices.
RawMesh to_raw(const io::Mesh& mesh) {
  RawMesh s;
  s.v.reserve(mesh.vertices.size());
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i) s.v.push_back(mesh.vertices.world(i));
  for (const auto& tri : mesh.triangles)
    for (auto idx : tri)
      if (idx >= s.v.size())
        throw InputError("mesh: triangle index " + std::to_string(idx) + " out of range (" +
                         std::to_string(s.v.size()) + " vertices)");
  s.t = mesh.triangles;
  return s;
}

io::Mesh to_mesh(const std::vector<Eigen::Vector3d>& v, const std::vector<Triangle>& t) {
  io::Mesh mesh;
  mesh.vertices.points.reserve(v.size());
  for (const auto& p : v) mesh.vertices.points.push_back(p.cast<float>());
  mesh.triangles = t;
  return mesh;
}

struct Moments {
  double volume = 0.0;
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
};

/// Divergence theorem: sum of signed tetrahedra (reference vertex, triangle).
Moments volume_moments(const std::vector<Eigen::Vector3d>& v, const std::vector<Triangle>& t) {
  if (v.empty()) return {};
  const Eigen::Vector3d ref = v.front();  // local reference point limits cancellation
  double six_volume = 0.0;
  Eigen::Vector3d weighted = Eigen::Vector3d::Zero();
  for (const auto& tri : t) {
    const Eigen::Vector3d a = v[tri[0]] - ref, b = v[tri[1]] - ref, c = v[tri[2]] - ref;
    const double d = a.dot(b.cross(c));
    six_volume += d;
    weighted += d * (a + b + c);
  }
  Moments m{six_volume / 6.0, ref};
  if (six_volume != 0.0) m.centroid += weighted / (4.0 * six_volume);
  return m;
}

RawMesh icosphere(int subdivisions) {
  const double g = std::numbers::phi;
  RawMesh s;
  s.v = {{-1, g, 0},  {1, g, 0},  {-1, -g, 0}, {1, -g, 0}, {0, -1, g},  {0, 1, g},
         {0, -1, -g}, {0, 1, -g}, {g, 0, -1},  {g, 0, 1},  {-g, 0, -1}, {-g, 0, 1}};
  for (auto& p : s.v) p.normalize();
  s.t = {{0, 11, 5},  {0, 5, 1},  {0, 1, 7},  {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
         {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
         {3, 8, 9},   {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
  for (int level = 0; level < subdivisions; ++level) {
    std::unordered_map<std::uint64_t, std::uint32_t> midpoints;  // edge key -> new vertex
    const auto midpoint = [&](std::uint32_t i, std::uint32_t j) {
      const auto key = (std::uint64_t{std::min(i, j)} << 32) | std::max(i, j);
      const auto [it, added] = midpoints.try_emplace(key, static_cast<std::uint32_t>(s.v.size()));
      if (added) s.v.push_back((s.v[i] + s.v[j]).normalized());
      return it->second;
    };
    std::vector<Triangle> finer;
    finer.reserve(4 * s.t.size());
    for (const auto& [a, b, c] : s.t) {
      const auto ab = midpoint(a, b), bc = midpoint(b, c), ca = midpoint(c, a);
      finer.insert(finer.end(), {{a, ab, ca}, {b, bc, ab}, {c, ca, bc}, {ab, bc, ca}});
    }
    s.t = std::move(finer);
  }
  return s;
}

// Stone shape ----------------------------------------------------------------------------------

/// Rock bulges and hollows: relative radial offsets per unit direction, from a few Gaussian lobes
/// on the sphere plus low-frequency waves, zero-mean and scaled to a random max amplitude.
std::vector<double> radial_perturbation(const std::vector<Eigen::Vector3d>& dirs,
                                        std::mt19937_64& rng) {
  std::vector<double> r(dirs.size(), 0.0);
  for (int k = 0; k < kLobeCount; ++k) {
    const Eigen::Vector3d centre = random_unit(rng);
    const double sign = uniform01(rng) < 0.5 ? -1.0 : 1.0;
    const double weight = sign * uniform(rng, kLobeWeight);
    const double width = uniform(rng, kLobeWidth);
    for (std::size_t i = 0; i < dirs.size(); ++i)  // 1 - cos(angle) ~ angle^2 / 2
      r[i] += weight * std::exp(-(1.0 - dirs[i].dot(centre)) / (width * width));
  }
  for (int k = 0; k < kSurfaceWaveCount; ++k) {
    const Eigen::Vector3d frequency = uniform(rng, kSurfaceWaveFrequency) * random_unit(rng);
    const double phase = kTwoPi * uniform01(rng);
    const double weight = uniform(rng, kSurfaceWaveWeight);
    for (std::size_t i = 0; i < dirs.size(); ++i)
      r[i] += weight * std::sin(frequency.dot(dirs[i]) + phase);
  }
  double mean = 0.0, max_abs = 0.0;
  for (double x : r) mean += x / static_cast<double>(r.size());
  for (double x : r) max_abs = std::max(max_abs, std::abs(x - mean));
  const double scale = max_abs > 0 ? uniform(rng, kRadialAmplitude) / max_abs : 0.0;
  for (double& x : r) x = (x - mean) * scale;
  return r;
}

/// Broken-rock facets: vertices beyond a few random planes are flattened onto them.
void fracture_cuts(std::vector<Eigen::Vector3d>& v, std::mt19937_64& rng) {
  const auto cuts = kMinCuts + static_cast<int>(uniform_index(rng, kMaxCuts - kMinCuts + 1));
  for (int k = 0; k < cuts; ++k) {
    const Eigen::Vector3d n = random_unit(rng);
    double support = 0.0;
    for (const auto& p : v) support = std::max(support, p.dot(n));
    const double offset = support * uniform(rng, kCutOffset);
    for (auto& p : v) p -= std::max(0.0, p.dot(n) - offset) * n;
  }
}

/// Slabs stay slabs: squash z so the thickness is at most kFlatMaxThickness of the length.
void limit_thickness(std::vector<Eigen::Vector3d>& v) {
  const Eigen::AlignedBox3d box = bounding_box(v);
  const Eigen::Vector3d size = box.sizes();
  const double ratio = size.z() / std::max(size.x(), size.y());
  if (ratio <= kFlatMaxThickness) return;
  const double mid_z = box.center().z(), squash = kFlatMaxThickness / ratio;
  for (auto& p : v) p.z() = mid_z + (p.z() - mid_z) * squash;
}

// Placement ------------------------------------------------------------------------------------

/// Which stones are slabs: round(flat_fraction * count) of them, at random positions.
std::vector<bool> flat_flags(const StoneConfig& c, std::mt19937_64& rng) {
  const auto n = static_cast<std::size_t>(c.count);
  const auto n_flat = static_cast<std::size_t>(std::lround(c.flat_fraction * c.count));
  std::vector<bool> flags(n, false);
  std::fill_n(flags.begin(), std::min(n, n_flat), true);
  for (std::size_t i = n; i > 1; --i) {  // Fisher–Yates with our own index draws
    const std::size_t j = uniform_index(rng, i);
    const bool tmp = flags[i - 1];
    flags[i - 1] = flags[j];
    flags[j] = tmp;
  }
  return flags;
}

/// Resting orientation: random yaw; roundish stones also get a small random tilt.
Eigen::Matrix3d resting_rotation(bool flat, double yaw, std::mt19937_64& rng) {
  const double tilt = flat ? 0.0 : kMaxRoundTilt * uniform01(rng);
  const double tilt_axis = kTwoPi * uniform01(rng);
  const Eigen::Vector3d axis(std::cos(tilt_axis), std::sin(tilt_axis), 0.0);
  return (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(tilt, axis))
      .toRotationMatrix();
}

struct Footprint {
  Vec2d centre;
  double radius;  // horizontal disc around the centroid containing the whole stone
};

bool outside_keep_out(const Vec2d& spot, double radius, const StoneConfig& c) {
  return c.keep_out_radius <= 0 ||
         (spot - Vec2d(c.keep_out_x, c.keep_out_y)).norm() >= radius + c.keep_out_radius;
}

/// Rejection sampling in the placement disc; footprint discs keep min_spacing between them.
/// Nothing when no free spot was found in kMaxPlacementAttempts samples.
std::optional<Vec2d> free_spot(double radius, const std::vector<Footprint>& placed, const StoneConfig& c,
                               std::mt19937_64& rng) {
  for (int attempt = 0; attempt < kMaxPlacementAttempts; ++attempt) {
    const double r = c.placement_radius * std::sqrt(uniform01(rng));
    const double angle = kTwoPi * uniform01(rng);
    const Vec2d spot(c.center_x + r * std::cos(angle),
                     c.center_y + c.placement_aspect * r * std::sin(angle));
    const bool free = std::all_of(placed.begin(), placed.end(), [&](const Footprint& f) {
      return (spot - f.centre).norm() >= radius + f.radius + c.min_spacing;
    });
    if (free && outside_keep_out(spot, radius, c)) return spot;
  }
  return std::nullopt;
}

/// Height of the centroid such that the deepest vertex sinks embed_depth below the terrain.
double resting_height(const std::vector<Eigen::Vector3d>& v, const Vec2d& spot,
                      const Terrain& terrain, double embed_depth) {
  double lowest = std::numeric_limits<double>::max();
  for (const auto& p : v)
    lowest = std::min(lowest, p.z() - terrain.height(spot.x() + p.x(), spot.y() + p.y()));
  return -embed_depth - lowest;
}

/// Shape of one stone in its local frame (centred at the volume centroid, shortest axis ~z).
struct StoneShape {
  RawMesh local;
  std::vector<CollisionPart> parts;  // collision parts on `local`
  double volume = 0.0;
  bool flat = false;
  std::string source = "procedural";
};

/// Whether the stone (vertices relative to its centroid, centroid at `centroid`) intersects any
/// placed stone: a vertex of one inside the other.
bool collides(const std::vector<Eigen::Vector3d>& v, const Eigen::Vector3d& centroid,
              const std::vector<Stone>& placed, const std::vector<SolidMesh>& solids) {
  Eigen::AlignedBox3d box;
  for (const auto& p : v) box.extend(p + centroid);
  for (std::size_t k = 0; k < placed.size(); ++k) {
    if (!box.intersects(placed[k].bounds)) continue;
    for (const auto& p : v)
      if (solids[k].contains(p + centroid)) return true;
  }
  return false;
}

/// Quasi-static settling: while the centroid's horizontal projection lies outside the support
/// (the vertices within settle_contact of the lowest contact), the stone tips by settle_step about
/// the horizontal axis through the support towards the centroid, then is lowered onto the terrain
/// again. Stops when stable or after kMaxSettleSteps. Returns the rotation applied.
Eigen::Matrix3d settle(std::vector<Eigen::Vector3d>& v, const Vec2d& spot, const Terrain& terrain,
                       const StoneConfig& c) {
  Eigen::Matrix3d applied = Eigen::Matrix3d::Identity();
  for (int step = 0; step < kMaxSettleSteps; ++step) {
    const double z = resting_height(v, spot, terrain, c.embed_depth);
    // Support: vertices at most settle_contact above the terrain (with the stone embedded).
    std::vector<Vec2d> support;
    for (const auto& p : v) {
      const double gap = p.z() + z - terrain.height(spot.x() + p.x(), spot.y() + p.y());
      if (gap <= kSettleContact) support.push_back(p.head<2>());
    }
    if (support.size() < 3) support.clear();
    // Is the centroid (origin of v) inside the convex hull of the support? Monotone chain.
    bool stable = false;
    Vec2d towards = Vec2d::Zero();
    if (!support.empty()) {
      std::sort(support.begin(), support.end(), [](const Vec2d& a, const Vec2d& b) {
        return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y());
      });
      std::vector<Vec2d> hull;
      const auto cross = [](const Vec2d& o, const Vec2d& a, const Vec2d& b) {
        return (a - o).x() * (b - o).y() - (a - o).y() * (b - o).x();
      };
      for (int pass = 0; pass < 2; ++pass) {
        const std::size_t base = hull.size();
        for (const auto& q : support) {
          while (hull.size() >= base + 2 && cross(hull[hull.size() - 2], hull.back(), q) <= 0) hull.pop_back();
          hull.push_back(q);
        }
        hull.pop_back();
        std::reverse(support.begin(), support.end());
      }
      stable = hull.size() >= 3;
      for (std::size_t i = 0; i < hull.size() && stable; ++i) {
        const Vec2d& a = hull[i];
        const Vec2d& b = hull[(i + 1) % hull.size()];
        // Inside with a margin: the centroid must be settle_margin inside every edge.
        if (cross(a, b, Vec2d::Zero()) < kSettleMargin * (b - a).norm()) stable = false;
      }
      Vec2d mean = Vec2d::Zero();
      for (const auto& q : hull) mean += q / static_cast<double>(hull.size());
      towards = -mean;  // from the support towards the centroid
    } else {
      // A single contact point: tip away from the lowest vertex.
      double lowest = std::numeric_limits<double>::max();
      for (const auto& p : v) {
        const double gap = p.z() - terrain.height(spot.x() + p.x(), spot.y() + p.y());
        if (gap < lowest) {
          lowest = gap;
          towards = -p.head<2>();
        }
      }
    }
    if (stable || towards.norm() < 1e-9) break;
    // Tip: the centroid side goes down, i.e. rotate about the horizontal axis perpendicular to
    // `towards` so that points in that direction move down.
    const Eigen::Vector3d axis = Eigen::Vector3d(-towards.y(), towards.x(), 0.0).normalized();
    const Eigen::Matrix3d R = Eigen::AngleAxisd(kSettleStep, axis).toRotationMatrix();
    for (auto& p : v) p = R * p;
    applied = R * applied;
  }
  return applied;
}

/// Pile: the stone approaches the pile's centre along a random direction and stops where it
/// (almost) touches a stone placed before (bisection on the distance, tolerance pile_gap).
Vec2d pile_spot(const std::vector<Eigen::Vector3d>& v, const RawMesh& local, double radius,
                const std::vector<Stone>& placed, const std::vector<SolidMesh>& solids,
                const StoneConfig& c, const Terrain& terrain, std::mt19937_64& rng) {
  const Vec2d centre(c.center_x, c.center_y);
  if (placed.empty()) return centre;
  const double angle = kTwoPi * uniform01(rng);
  const Vec2d dir(std::cos(angle), std::sin(angle));
  const auto blocked_at = [&](double d) {
    const Vec2d spot = centre + d * dir;
    std::vector<Eigen::Vector3d> v_here = v;
    if (c.settle) settle(v_here, spot, terrain, c);
    const Eigen::Vector3d centroid(spot.x(), spot.y(), resting_height(v_here, spot, terrain, c.embed_depth));
    if (collides(v_here, centroid, placed, solids)) return true;
    // The other way round: a placed stone's vertex inside the new one.
    std::vector<Eigen::Vector3d> w;
    w.reserve(v_here.size());
    for (const auto& p : v_here) w.push_back(p + centroid);
    const SolidMesh mine(to_mesh(w, local.t));
    for (const auto& stone : placed) {
      if (!stone.bounds.intersects(mine.bounds())) continue;
      for (std::size_t i = 0; i < stone.mesh.vertices.size(); ++i)
        if (mine.contains(stone.mesh.vertices.world(i))) return true;
    }
    return false;
  };
  double far = radius;
  for (const auto& stone : placed) {
    const double r = (stone.centroid.head<2>() - centre).norm() +
                     0.5 * stone.bounds.sizes().head<2>().norm();
    far = std::max(far, r + radius + c.pile_gap);
  }
  double near = 0.0;
  if (!blocked_at(near)) return centre + near * dir;  // cannot happen with a stone at the centre
  while (far - near > c.pile_gap) {
    const double mid = 0.5 * (near + far);
    (blocked_at(mid) ? near : far) = mid;
  }
  return centre + far * dir;
}

/// The collision parts of a real stone mesh at unit volume, decomposed once per process and
/// configuration (0.1–1.4 s for the shipped meshes; many sites reuse them).
std::vector<CollisionPart> real_stone_parts(const std::string& path, const RawMesh& unit,
                                            const ConvexDecompositionConfig& c) {
  static std::mutex guard;
  static std::map<std::string, std::vector<CollisionPart>> done;
  std::ostringstream key;
  key.precision(17);
  key << path << ' ' << unit.v.size() << ' ' << unit.t.size() << ' ' << c.max_excess << ' ' << c.max_parts << ' '
      << c.planes_per_axis << ' ' << c.grid_cells << ' ' << c.min_part_share;
  {
    const std::lock_guard<std::mutex> lock(guard);
    if (const auto it = done.find(key.str()); it != done.end()) return it->second;
  }
  std::vector<CollisionPart> parts = decompose_convex(unit.v, unit.t, c).parts;
  const std::lock_guard<std::mutex> lock(guard);
  return done.emplace(key.str(), std::move(parts)).first->second;
}

/// One stone: orientation, spot and resting height for a given shape; nothing when the stone
/// found no free spot (free_spot).
std::optional<Stone> place_stone(StoneShape shape, std::vector<Footprint>& footprints,
                                 const std::vector<Stone>& placed, const std::vector<SolidMesh>& solids,
                                 const StoneConfig& c, const Terrain& terrain, std::mt19937_64& rng) {
  Stone stone;
  stone.flat = shape.flat;
  stone.volume = shape.volume;
  stone.source = shape.source;
  stone.yaw = kTwoPi * uniform01(rng);
  const Eigen::Matrix3d rotation = resting_rotation(shape.flat, stone.yaw, rng);
  std::vector<Eigen::Vector3d> v;
  v.reserve(shape.local.v.size());
  double radius = 0.0;
  for (const auto& p : shape.local.v) {
    v.push_back(rotation * p);
    radius = std::max(radius, v.back().head<2>().norm());
  }
  const std::optional<Vec2d> found = c.arrangement == "pile"
                                         ? pile_spot(v, shape.local, radius, placed, solids, c, terrain, rng)
                                         : free_spot(radius, footprints, c, rng);
  if (!found) return std::nullopt;
  const Vec2d spot = *found;
  if (c.settle) {
    const Eigen::Matrix3d tipped = settle(v, spot, terrain, c);
    stone.yaw = std::atan2(tipped(1, 0), tipped(0, 0)) + stone.yaw;
  }
  footprints.push_back({spot, radius});
  stone.centroid =
      Eigen::Vector3d(spot.x(), spot.y(), resting_height(v, spot, terrain, c.embed_depth));
  for (auto& p : v) p += stone.centroid;
  stone.mesh = to_mesh(v, shape.local.t);
  stone.bounds = bounding_box(to_raw(stone.mesh).v);
  stone.collision_parts = std::move(shape.parts);
  return stone;
}

// Sampling -------------------------------------------------------------------------------------

struct Samples {
  std::vector<Eigen::Vector3d> points;  // noise-free positions
  std::vector<Eigen::Vector3d> normals;
  std::vector<std::int32_t> truth;
  bool with_normals = false;

  void add(const Eigen::Vector3d& p, const Eigen::Vector3d& n, std::int32_t label) {
    points.push_back(p);
    normals.push_back(n);  // always kept: the visibility model needs them
    truth.push_back(label);
  }
};

bool inside_any(const std::vector<SolidMesh>& solids, const Eigen::Vector3d& p) {
  return std::any_of(solids.begin(), solids.end(),
                     [&](const SolidMesh& s) { return s.contains(p); });
}

/// Ground returns: one point per cell of a jittered grid; points inside stones are dropped.
void sample_terrain(const Site& site, const std::vector<SolidMesh>& solids, double spacing,
                    std::mt19937_64& rng, Samples& out) {
  const auto& tc = site.terrain_config;
  const long nx = std::max(1L, std::lround(tc.size_x / spacing));
  const long ny = std::max(1L, std::lround(tc.size_y / spacing));
  const double dx = tc.size_x / static_cast<double>(nx), dy = tc.size_y / static_cast<double>(ny);
  for (long j = 0; j < ny; ++j)
    for (long i = 0; i < nx; ++i) {
      const double x = -0.5 * tc.size_x + (static_cast<double>(i) + uniform01(rng)) * dx;
      const double y = -0.5 * tc.size_y + (static_cast<double>(j) + uniform01(rng)) * dy;
      const Eigen::Vector3d p(x, y, site.terrain.height(x, y));
      if (inside_any(solids, p)) continue;
      out.add(p, site.terrain.normal(x, y), -1);
    }
}

/// Stone returns: area-weighted uniform points per triangle (stochastic rounding of
/// area / spacing^2); points below the terrain surface (buried part) are dropped.
void sample_stone(const RawMesh& s, std::int32_t label, const Terrain& terrain, double spacing,
                  std::mt19937_64& rng, Samples& out) {
  const double density = 1.0 / (spacing * spacing);
  for (const auto& tri : s.t) {
    const auto &a = s.v[tri[0]], &b = s.v[tri[1]], &c = s.v[tri[2]];
    const Eigen::Vector3d cross = (b - a).cross(c - a);
    const double expected = 0.5 * cross.norm() * density;
    const double whole = std::floor(expected);
    const auto count = static_cast<long>(whole) + (uniform01(rng) < expected - whole ? 1 : 0);
    const Eigen::Vector3d normal = cross.normalized();
    for (long k = 0; k < count; ++k) {
      const double s1 = std::sqrt(uniform01(rng));  // uniform barycentric coordinates
      const double r2 = uniform01(rng);
      const Eigen::Vector3d p = (1.0 - s1) * a + s1 * (1.0 - r2) * b + s1 * r2 * c;
      if (p.z() < terrain.height(p.x(), p.y())) continue;
      out.add(p, normal, label);
    }
  }
}

/// Sensor positions of the visibility model (SamplingConfig::visibility).
std::vector<Eigen::Vector3d> viewpoints(const Site& site, const SamplingConfig& c) {
  const double z0 = site.terrain.height(0.0, 0.0);
  std::vector<Eigen::Vector3d> v;
  for (int k = 0; k < c.ring_viewpoints; ++k) {
    const double a = 2.0 * std::numbers::pi * double(k) / double(c.ring_viewpoints);
    v.emplace_back(c.ring_radius * std::cos(a), c.ring_radius * std::sin(a), z0 + c.ring_height);
  }
  v.emplace_back(0.0, 0.0, z0 + c.overhead_height);
  return v;
}

/// Whether the segment p → v passes through a stone: sampled every `step` inside the stones'
/// bounding boxes only (slab test), starting one step away from p.
bool blocked(const Eigen::Vector3d& p, const Eigen::Vector3d& v, const std::vector<SolidMesh>& solids,
             double step) {
  const Eigen::Vector3d d = v - p;
  const double len = d.norm();
  const Eigen::Vector3d dir = d / len;
  for (const auto& s : solids) {
    double t0 = step, t1 = len;  // slab test of the ray against the stone's bounding box
    for (int a = 0; a < 3; ++a) {
      if (std::abs(dir[a]) < 1e-12) {
        if (p[a] < s.bounds().min()[a] || p[a] > s.bounds().max()[a]) t1 = -1.0;
        continue;
      }
      double ta = (s.bounds().min()[a] - p[a]) / dir[a], tb = (s.bounds().max()[a] - p[a]) / dir[a];
      if (ta > tb) std::swap(ta, tb);
      t0 = std::max(t0, ta);
      t1 = std::min(t1, tb);
    }
    for (double t = t0; t <= t1; t += step)
      if (s.contains(p + t * dir)) return true;
  }
  return false;
}

/// Drops the samples that no viewpoint sees (see SamplingConfig::visibility).
void remove_hidden(Samples& samples, const Site& site,
                   const std::vector<SolidMesh>& solids, const SamplingConfig& c) {
  const auto views = viewpoints(site, c);
  constexpr double kNearStone = 0.3;  // [m] only points this close to a stone's box can be hidden
  std::vector<std::uint8_t> keep(samples.points.size(), 1);
  tbb::parallel_for(std::size_t{0}, samples.points.size(), [&](std::size_t i) {
    const Eigen::Vector3d& p = samples.points[i];
    const bool near = std::any_of(solids.begin(), solids.end(), [&](const SolidMesh& s) {
      return s.bounds().exteriorDistance(p) < kNearStone;
    });
    if (!near) return;
    keep[i] = std::any_of(views.begin(), views.end(), [&](const Eigen::Vector3d& v) {
      return samples.normals[i].dot(v - p) > 0.0 && !blocked(p, v, solids, c.visibility_step);
    });
  });
  Samples kept;
  kept.with_normals = samples.with_normals;
  for (std::size_t i = 0; i < keep.size(); ++i) {
    if (!keep[i]) continue;
    kept.points.push_back(samples.points[i]);
    kept.normals.push_back(samples.normals[i]);
    kept.truth.push_back(samples.truth[i]);
  }
  samples = std::move(kept);
}

/// Range noise: isotropic Gaussian on every coordinate; builds the output cloud.
SampledSite add_noise(const Samples& samples, double sigma, std::mt19937_64& rng) {
  SampledSite out;
  out.cloud.points.reserve(samples.points.size());
  for (const auto& p : samples.points) {
    const double nx = standard_normal(rng);
    const double ny = standard_normal(rng);
    const double nz = standard_normal(rng);
    out.cloud.points.push_back((p + sigma * Eigen::Vector3d(nx, ny, nz)).cast<float>());
  }
  if (samples.with_normals)
    for (const auto& n : samples.normals) out.cloud.normals.push_back(n.cast<float>());
  out.truth = samples.truth;
  out.cloud.labels = samples.truth;
  return out;
}

}  // namespace

// Random numbers -------------------------------------------------------------------------------

double uniform01(std::mt19937_64& rng) { return static_cast<double>(rng() >> 11) * 0x1.0p-53; }

double standard_normal(std::mt19937_64& rng) {
  const double u1 = (static_cast<double>(rng() >> 11) + 1.0) * 0x1.0p-53;  // (0, 1]: log finite
  const double u2 = uniform01(rng);
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(kTwoPi * u2);
}

// Terrain --------------------------------------------------------------------------------------

Terrain Terrain::random(const TerrainConfig& config, std::mt19937_64& rng) {
  validate(config);
  Terrain t;
  t.config = config;
  double sum_sq = 0.0;  // undulations: random sinusoids, RMS = bump_amplitude / sqrt(2)
  for (int k = 0; k < kTerrainWaveCount; ++k) {
    const double wavelength = uniform(rng, kWavelength);
    const double direction = kTwoPi * uniform01(rng);
    Wave w;
    w.wave_vector = kTwoPi / wavelength * Vec2d(std::cos(direction), std::sin(direction));
    w.amplitude = uniform(rng, kWaveWeight);
    w.phase = kTwoPi * uniform01(rng);
    sum_sq += w.amplitude * w.amplitude;
    t.waves.push_back(w);
  }
  for (auto& w : t.waves) w.amplitude *= config.bump_amplitude / std::sqrt(sum_sq);
  // Gravel roughness: Gaussian heights on a 10 cm lattice covering the site plus a margin.
  t.noise_cell = kRoughnessCell;
  t.noise_origin = -0.5 * Vec2d(config.size_x, config.size_y) - Vec2d::Constant(kRoughnessMargin);
  t.noise_nx =
      static_cast<int>(std::ceil((config.size_x + 2 * kRoughnessMargin) / t.noise_cell)) + 1;
  t.noise_ny =
      static_cast<int>(std::ceil((config.size_y + 2 * kRoughnessMargin) / t.noise_cell)) + 1;
  t.noise.resize(static_cast<std::size_t>(t.noise_nx) * static_cast<std::size_t>(t.noise_ny));
  for (auto& h : t.noise) h = config.roughness * standard_normal(rng);
  return t;
}

double Terrain::roughness_at(double x, double y) const {
  if (noise_nx < 2 || noise_ny < 2) return 0.0;
  const double u = std::clamp((x - noise_origin.x()) / noise_cell, 0.0, noise_nx - 1.0);
  const double v = std::clamp((y - noise_origin.y()) / noise_cell, 0.0, noise_ny - 1.0);
  const int i = std::min(static_cast<int>(u), noise_nx - 2);
  const int j = std::min(static_cast<int>(v), noise_ny - 2);
  const auto smooth = [](double s) { return s * s * (3.0 - 2.0 * s); };  // C1 value noise
  const double tx = smooth(u - i), ty = smooth(v - j);
  const auto node = [&](int di, int dj) {
    return noise[static_cast<std::size_t>(j + dj) * static_cast<std::size_t>(noise_nx) +
                 static_cast<std::size_t>(i + di)];
  };
  const double low = node(0, 0) + tx * (node(1, 0) - node(0, 0));
  const double high = node(0, 1) + tx * (node(1, 1) - node(0, 1));
  return low + ty * (high - low);
}

double Terrain::height(double x, double y) const {
  double h = config.slope_x * x + config.slope_y * y;
  for (const auto& w : waves) h += w.amplitude * std::sin(w.wave_vector.dot(Vec2d(x, y)) + w.phase);
  return h + roughness_at(x, y);
}

Eigen::Vector3d Terrain::normal(double x, double y) const {
  const double s = kGradientStep;
  const double gx = (height(x + s, y) - height(x - s, y)) / (2.0 * s);
  const double gy = (height(x, y + s) - height(x, y - s)) / (2.0 * s);
  return Eigen::Vector3d(-gx, -gy, 1.0).normalized();
}

// Site -----------------------------------------------------------------------------------------

/// Which stones take a real mesh (prepared at unit volume), and which one.
struct RealStones {
  std::vector<io::Mesh> meshes;
  std::vector<bool> use;
  std::vector<std::size_t> index;
};

/// Real meshes: loaded once; which stones use them is drawn only when asked for, so procedural
/// sites keep their random sequence.
RealStones choose_real_stones(const StoneConfig& c, std::mt19937_64& rng) {
  RealStones real;
  for (const auto& path : c.real_meshes) {
    if (c.real_fraction > 0) real.meshes.push_back(prepare_real_stone_mesh(io::read_ply_mesh(path), 1.0));
  }
  real.use.assign(static_cast<std::size_t>(c.count), false);
  real.index.assign(real.use.size(), 0);
  if (real.meshes.empty()) return real;
  const auto n_real = static_cast<std::size_t>(std::lround(c.real_fraction * c.count));
  std::vector<std::size_t> order(real.use.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  for (std::size_t i = order.size(); i > 1; --i) std::swap(order[i - 1], order[uniform_index(rng, i)]);
  for (std::size_t i = 0; i < std::min(n_real, order.size()); ++i) {
    real.use[order[i]] = true;
    real.index[order[i]] = i % real.meshes.size();
  }
  return real;
}

/// Shape of stone k: its volume, then a real mesh scaled to it or a procedural rock.
StoneShape stone_shape(std::size_t k, bool flat, const RealStones& real, const StoneConfig& c, std::mt19937_64& rng) {
  StoneShape shape;
  shape.volume = uniform(rng, {c.min_volume, c.max_volume});
  if (!real.use[k]) {
    shape.flat = flat;
    shape.local = to_raw(make_stone_mesh(shape.volume, flat, rng));
    shape.parts = decompose_convex(shape.local.v, shape.local.t, c.collision).parts;
    return shape;
  }
  shape.local = to_raw(real.meshes[real.index[k]]);
  shape.parts = real_stone_parts(c.real_meshes[real.index[k]], shape.local, c.collision);  // scale with it
  const double scale = std::cbrt(shape.volume);
  for (auto& p : shape.local.v) p *= scale;
  const Eigen::Vector3d size = bounding_box(shape.local.v).sizes();
  shape.flat = size.z() <= kFlatMaxThickness * std::max(size.x(), size.y()) * std::sqrt(2.0);
  shape.source = std::filesystem::path(c.real_meshes[real.index[k]]).filename().string();
  return shape;
}

/// One layout: every stone's shape and place, in order. Nothing when a stone found no spot.
std::optional<std::vector<Stone>> layout_stones(const RealStones& real, const StoneConfig& c, const Terrain& terrain,
                                                std::mt19937_64& rng) {
  std::vector<Stone> stones;
  std::vector<Footprint> footprints;
  std::vector<SolidMesh> solids;
  const std::vector<bool> flat = flat_flags(c, rng);
  for (std::size_t k = 0; k < flat.size(); ++k) {
    std::optional<Stone> stone =
        place_stone(stone_shape(k, flat[k], real, c, rng), footprints, stones, solids, c, terrain, rng);
    if (!stone) return std::nullopt;
    stones.push_back(std::move(*stone));
    solids.emplace_back(stones.back().mesh);
  }
  return stones;
}

Site generate_site(const SiteConfig& config, std::uint64_t seed) {
  validate(config.terrain);
  validate(config.stones);
  std::mt19937_64 rng(seed);
  Site site;
  site.terrain_config = config.terrain;
  site.stone_config = config.stones;
  site.terrain = Terrain::random(config.terrain, rng);
  const StoneConfig& c = config.stones;
  const RealStones real = choose_real_stones(c, rng);
  for (int attempt = 0; attempt < kMaxLayoutAttempts; ++attempt) {
    if (std::optional<std::vector<Stone>> stones = layout_stones(real, c, site.terrain, rng)) {
      site.stones = std::move(*stones);
      return site;
    }
  }
  throw ConfigError("generate_site: cannot place " + std::to_string(c.count) + " stones with min_spacing " +
                    std::to_string(c.min_spacing) + " m within placement_radius " + std::to_string(c.placement_radius) +
                    " m in " + std::to_string(kMaxLayoutAttempts) + " layouts (too many or too large stones)");
}

std::vector<std::vector<Eigen::Vector3d>> collision_point_sets(const Stone& stone) {
  const std::vector<Eigen::Vector3d> v = to_raw(stone.mesh).v;
  if (stone.collision_parts.empty()) return {v};
  std::vector<std::vector<Eigen::Vector3d>> sets;
  for (const CollisionPart& part : stone.collision_parts) {
    for (const MeshPoint& q : part) {
      if (std::max({q.i[0], q.i[1], q.i[2], q.i[3]}) >= v.size()) {
        throw InputError("stone: a collision part refers to a vertex its mesh does not have (mesh replaced?)");
      }
    }
    sets.push_back(part_points(part, v));
  }
  return sets;
}

SampledSite sample_site(const Site& site, const SamplingConfig& config, std::uint64_t seed) {
  validate(config, site.terrain_config);
  std::mt19937_64 rng(seed);
  std::vector<SolidMesh> solids;
  for (const auto& stone : site.stones) solids.emplace_back(stone.mesh);
  Samples samples;
  samples.with_normals = config.true_normals;
  const double expected =
      site.terrain_config.size_x * site.terrain_config.size_y / (config.spacing * config.spacing);
  samples.points.reserve(static_cast<std::size_t>(1.3 * expected));
  samples.truth.reserve(samples.points.capacity());
  sample_terrain(site, solids, config.spacing, rng, samples);
  for (std::size_t k = 0; k < solids.size(); ++k)
    sample_stone(to_raw(site.stones[k].mesh), static_cast<std::int32_t>(k), site.terrain,
                 config.spacing, rng, samples);
  if (config.visibility) remove_hidden(samples, site, solids, config);
  return add_noise(samples, config.noise_sigma, rng);
}

// Geometry helpers -----------------------------------------------------------------------------

io::Mesh make_stone_mesh(double target_volume, bool flat, std::mt19937_64& rng) {
  require(std::isfinite(target_volume) && target_volume > 0,
          "make_stone_mesh: target_volume must be positive");
  RawMesh s = icosphere(kStoneSubdivisions);
  // Ellipsoid with random axes (x longest, z shortest), then bulges and fracture facets.
  const double mid = uniform(rng, kMidAxis);
  const double minor = uniform(rng, flat ? kFlatMinorAxis : kRoundMinorAxis);
  const Eigen::Vector3d axes(1.0, mid, minor);
  const std::vector<double> bulge = radial_perturbation(s.v, rng);
  for (std::size_t i = 0; i < s.v.size(); ++i)
    s.v[i] = axes.cwiseProduct(s.v[i]) * (1.0 + bulge[i]);
  fracture_cuts(s.v, rng);
  if (flat) limit_thickness(s.v);
  // Exact target volume, centred at the volume centroid.
  const Moments m = volume_moments(s.v, s.t);
  const double scale = std::cbrt(target_volume / m.volume);
  for (auto& p : s.v) p = (p - m.centroid) * scale;
  return to_mesh(s.v, s.t);
}

io::Mesh prepare_real_stone_mesh(const io::Mesh& raw, double target_volume) {
  require(std::isfinite(target_volume) && target_volume > 0,
          "prepare_real_stone_mesh: target_volume must be positive");
  RawMesh s = to_raw(raw);
  if (s.v.size() < 4 || s.t.size() < 4) throw InputError("real stone mesh: fewer than 4 vertices/faces");
  const double extent = bounding_box(s.v).sizes().maxCoeff();
  const double unit = extent > kMillimetreThreshold ? 1e-3 : 1.0;  // mm -> m
  for (auto& p : s.v) p *= unit;
  Moments m = volume_moments(s.v, s.t);
  if (m.volume < 0) {  // inward-oriented: flip every triangle
    for (auto& t : s.t) std::swap(t[1], t[2]);
    m = volume_moments(s.v, s.t);
  }
  const double diameter = extent * unit;
  if (!(m.volume > 1e-3 * diameter * diameter * diameter)) {
    throw InputError("real stone mesh: encloses no volume (open or degenerate mesh)");
  }
  // Principal axes of the vertex cloud: longest -> x, shortest -> z (rests on its broad side).
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const auto& p : s.v) cov += (p - m.centroid) * (p - m.centroid).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);  // ascending eigenvalues
  Eigen::Matrix3d axes;
  axes.col(0) = eig.eigenvectors().col(2);
  axes.col(1) = eig.eigenvectors().col(1);
  axes.col(2) = axes.col(0).cross(axes.col(1));  // right-handed: no mirror image
  const double scale = std::cbrt(target_volume / m.volume);
  for (auto& p : s.v) p = axes.transpose() * (p - m.centroid) * scale;
  return to_mesh(s.v, s.t);
}

io::Mesh make_icosphere(int subdivisions) {
  // Appended, not `a + b + "]"`: GCC 12 warns falsely (-Warray-bounds) on that concatenation here.
  std::string range = "make_icosphere: subdivisions must be in [0, ";
  range.append(std::to_string(kMaxIcosphereSubdivisions)).append("]");
  require(subdivisions >= 0 && subdivisions <= kMaxIcosphereSubdivisions, range);
  const RawMesh s = icosphere(subdivisions);
  return to_mesh(s.v, s.t);
}

double mesh_volume(const io::Mesh& mesh) {
  const RawMesh s = to_raw(mesh);
  return mesh_volume(s.v, s.t);
}

Eigen::Vector3d mesh_centroid(const io::Mesh& mesh) {
  const RawMesh s = to_raw(mesh);
  return volume_moments(s.v, s.t).centroid;
}

bool inside_mesh(const io::Mesh& mesh, const Eigen::Vector3d& p) {
  return SolidMesh(mesh).contains(p);
}

// SolidMesh ------------------------------------------------------------------------------------

SolidMesh::SolidMesh(const io::Mesh& mesh) {
  const RawMesh raw = to_raw(mesh);
  bounds_ = bounding_box(raw.v);
  for (const auto& p : raw.v) vertices_.push_back({p.x(), p.y(), p.z()});
  triangles_ = raw.t;
  // Grid of ~kTrianglesPerCell triangles per cell over the xy bounding box.
  const auto side =
      static_cast<int>(std::sqrt(static_cast<double>(triangles_.size()) / kTrianglesPerCell));
  nx_ = ny_ = std::clamp(side, 1, kMaxGridSide);
  cell_x_ = std::max(bounds_.sizes().x(), kMinCellSize) / nx_;
  cell_y_ = std::max(bounds_.sizes().y(), kMinCellSize) / ny_;
  const auto cell_of = [&](double x, double y) {
    const int i = std::clamp(static_cast<int>((x - bounds_.min().x()) / cell_x_), 0, nx_ - 1);
    const int j = std::clamp(static_cast<int>((y - bounds_.min().y()) / cell_y_), 0, ny_ - 1);
    return std::array<int, 2>{i, j};
  };
  // Two passes (count, fill) over the cells each triangle's projected bounding box touches.
  std::vector<std::uint32_t> count(static_cast<std::size_t>(nx_ * ny_) + 1, 0);
  cell_triangles_.clear();
  for (int pass = 0; pass < 2; ++pass) {
    for (std::uint32_t t = 0; t < triangles_.size(); ++t) {
      const auto& [a, b, c] = triangles_[t];
      const Vertex &va = vertices_[a], &vb = vertices_[b], &vc = vertices_[c];
      const double area2 = (vb.x - va.x) * (vc.y - va.y) - (vb.y - va.y) * (vc.x - va.x);
      if (pass == 0) orientation_.push_back(static_cast<signed char>((area2 > 0) - (area2 < 0)));
      if (orientation_[t] == 0) continue;  // vertical triangle: no vertical ray crosses it
      const auto lo = cell_of(std::min({va.x, vb.x, vc.x}), std::min({va.y, vb.y, vc.y}));
      const auto hi = cell_of(std::max({va.x, vb.x, vc.x}), std::max({va.y, vb.y, vc.y}));
      for (int j = lo[1]; j <= hi[1]; ++j)
        for (int i = lo[0]; i <= hi[0]; ++i) {
          const auto cell = static_cast<std::size_t>(j * nx_ + i);
          if (pass == 0)
            ++count[cell + 1];
          else
            cell_triangles_[count[cell]++] = t;
        }
    }
    if (pass == 0) {
      for (std::size_t c = 1; c < count.size(); ++c) count[c] += count[c - 1];
      cell_begin_ = count;
      cell_triangles_.resize(count.back());
    }
  }
}

bool SolidMesh::covers(std::uint32_t t, double x, double y, double& z) const {
  const auto& tri = triangles_[t];
  std::array<double, 3> w{};  // weight of vertex e = edge function of the opposite edge
  for (int e = 0; e < 3; ++e) {
    const std::uint32_t i = tri[(e + 1) % 3], j = tri[(e + 2) % 3];
    const Vertex &lo = vertices_[std::min(i, j)], &hi = vertices_[std::max(i, j)];
    const double sign = (i < j ? 1.0 : -1.0) * orientation_[t];  // to counter-clockwise i -> j
    const double ex = hi.x - lo.x, ey = hi.y - lo.y;
    w[e] = sign * (ex * (y - lo.y) - ey * (x - lo.x));
    const double dx = sign * ex, dy = sign * ey;
    const bool top_left = dy < 0 || (dy == 0 && dx < 0);
    if (w[e] < 0 || (w[e] == 0 && !top_left)) return false;
  }
  const double sum = w[0] + w[1] + w[2];
  if (sum <= 0) return false;
  z = (w[0] * vertices_[tri[0]].z + w[1] * vertices_[tri[1]].z + w[2] * vertices_[tri[2]].z) / sum;
  return true;
}

bool SolidMesh::contains(const Eigen::Vector3d& p) const {
  if (!bounds_.contains(p)) return false;
  const int i = std::clamp(static_cast<int>((p.x() - bounds_.min().x()) / cell_x_), 0, nx_ - 1);
  const int j = std::clamp(static_cast<int>((p.y() - bounds_.min().y()) / cell_y_), 0, ny_ - 1);
  const auto cell = static_cast<std::size_t>(j * nx_ + i);
  bool inside = false;
  for (auto k = cell_begin_[cell]; k < cell_begin_[cell + 1]; ++k) {
    double z = 0.0;
    if (covers(cell_triangles_[k], p.x(), p.y(), z) && z > p.z()) inside = !inside;
  }
  return inside;
}

}  // namespace cairn::sim
