#include "cairn/segmentation/ground.hpp"

#include <tbb/parallel_for.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <deque>
#include <limits>
#include <numbers>
#include <optional>

#include "cairn/core/error.hpp"
#include "cairn/segmentation/grid2d.hpp"

namespace cairn {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr int kLaplaceIterations = 200;   // harmonic fill of object/empty cells

/// A 2-D grid of float values over the xy extent of the points.
struct Grid : GridFrame {
  std::vector<float> v;
  float& at(int x, int y) { return v[index(x, y)]; }
  [[nodiscard]] float at(int x, int y) const { return v[index(x, y)]; }
  /// Bilinear interpolation between cell centres.
  [[nodiscard]] float bilinear(float x, float y) const {
    const float fx = std::clamp((x - x0) / cell - 0.5f, 0.0f, float(nx - 1));
    const float fy = std::clamp((y - y0) / cell - 0.5f, 0.0f, float(ny - 1));
    const int i0 = std::min(int(fx), nx - 1), j0 = std::min(int(fy), ny - 1);
    const int i1 = std::min(i0 + 1, nx - 1), j1 = std::min(j0 + 1, ny - 1);
    const float tx = fx - float(i0), ty = fy - float(j0);
    return (1 - ty) * ((1 - tx) * at(i0, j0) + tx * at(i1, j0)) + ty * ((1 - tx) * at(i0, j1) + tx * at(i1, j1));
  }
};

Grid make_grid(std::span<const Vec3f> pts, float cell) {
  Grid g{GridFrame::covering(pts, cell, "ground: cell_size"), {}};
  g.v.assign(g.num_cells(), kInf);
  return g;
}

/// Fills +inf cells with the value of the nearest finite cell (multi-source BFS, 4-neighbourhood).
void fill_nearest(Grid& g) {
  std::deque<std::pair<int, int>> queue;
  for (int y = 0; y < g.ny; ++y)
    for (int x = 0; x < g.nx; ++x)
      if (g.at(x, y) < kInf) queue.emplace_back(x, y);
  constexpr int kDx[4] = {1, -1, 0, 0}, kDy[4] = {0, 0, 1, -1};
  while (!queue.empty()) {
    const auto [x, y] = queue.front();
    queue.pop_front();
    for (int k = 0; k < 4; ++k) {
      const int u = x + kDx[k], w = y + kDy[k];
      if (u < 0 || w < 0 || u >= g.nx || w >= g.ny || g.at(u, w) < kInf) continue;
      g.at(u, w) = g.at(x, y);
      queue.emplace_back(u, w);
    }
  }
}

/// Separable min (erode) or max (dilate) filter with a square window of half-width r cells.
Grid morph(const Grid& in, int r, bool erode) {
  const auto pick = [erode](float a, float b) { return erode ? std::min(a, b) : std::max(a, b); };
  Grid tmp = in, out = in;
  for (int y = 0; y < in.ny; ++y)
    for (int x = 0; x < in.nx; ++x) {
      float m = in.at(x, y);
      for (int k = std::max(0, x - r); k <= std::min(in.nx - 1, x + r); ++k) m = pick(m, in.at(k, y));
      tmp.at(x, y) = m;
    }
  for (int y = 0; y < in.ny; ++y)
    for (int x = 0; x < in.nx; ++x) {
      float m = tmp.at(x, y);
      for (int k = std::max(0, y - r); k <= std::min(in.ny - 1, y + r); ++k) m = pick(m, tmp.at(x, k));
      out.at(x, y) = m;
    }
  return out;
}

/// Progressive morphological filter: true for cells whose lowest point is terrain.
std::vector<std::uint8_t> pmf_ground_cells(Grid zmin, const GroundConfig& c) {
  std::vector<std::uint8_t> ground(zmin.v.size(), 1);
  const int max_half = std::max(1, int(std::ceil(c.max_window / c.cell_size / 2.0)));
  int prev_half = 0;
  for (int half = 1;; half = std::min(2 * half, max_half)) {
    const Grid opened = morph(morph(zmin, half, true), half, false);
    const double dh = prev_half == 0 ? c.initial_height
                                     : std::min(c.max_height, c.initial_height + c.slope * 2.0 *
                                                                   (half - prev_half) * c.cell_size);
    for (std::size_t i = 0; i < zmin.v.size(); ++i)
      if (zmin.v[i] - opened.v[i] > dh) ground[i] = 0;
    zmin = opened;
    prev_half = half;
    if (half == max_half) break;
  }
  return ground;
}

/// Harmonic (Laplace) fill of the cells that are not fixed, starting from nearest values.
void harmonic_fill(Grid& g, const std::vector<std::uint8_t>& fixed) {
  for (std::size_t i = 0; i < g.v.size(); ++i)
    if (!fixed[i]) g.v[i] = kInf;
  fill_nearest(g);
  for (int it = 0; it < kLaplaceIterations; ++it)
    for (int y = 0; y < g.ny; ++y)
      for (int x = 0; x < g.nx; ++x) {
        if (fixed[std::size_t(y) * g.nx + x]) continue;
        float s = 0;
        int n = 0;
        if (x > 0) s += g.at(x - 1, y), ++n;
        if (x + 1 < g.nx) s += g.at(x + 1, y), ++n;
        if (y > 0) s += g.at(x, y - 1), ++n;
        if (y + 1 < g.ny) s += g.at(x, y + 1), ++n;
        g.at(x, y) = s / float(n);
      }
}

/// Object cells take the height of a Gaussian-weighted quadratic fitted to the terrain cells
/// within `radius` (z = a + b x + c y + d x² + e xy + f y²): unlike the harmonic fill, it follows
/// the curvature of a bump crest under a stone. The result is clamped to the support's height
/// range widened by `margin` (no runaway extrapolation from one-sided support); cells with too
/// little support keep the harmonic value.
void quadratic_fill(Grid& g, const std::vector<std::uint8_t>& fixed, double radius, double margin) {
  constexpr int kMinSupport = 12;  // terrain cells needed for a quadratic fit
  const int r = std::max(1, int(std::ceil(radius / g.cell)));
  const double inv_two_sigma2 = 1.0 / (2.0 * (radius / 2.0) * (radius / 2.0));
  const Grid src = g;
  tbb::parallel_for(0, g.ny, [&](int y) {
    for (int x = 0; x < g.nx; ++x) {
      if (fixed[std::size_t(y) * g.nx + x]) continue;
      Eigen::Matrix<double, 6, 6> ata = Eigen::Matrix<double, 6, 6>::Zero();
      Eigen::Matrix<double, 6, 1> atb = Eigen::Matrix<double, 6, 1>::Zero();
      int support = 0;
      double lo = std::numeric_limits<double>::max(), hi = std::numeric_limits<double>::lowest();
      for (int v = std::max(0, y - r); v <= std::min(g.ny - 1, y + r); ++v)
        for (int u = std::max(0, x - r); u <= std::min(g.nx - 1, x + r); ++u) {
          if (!fixed[std::size_t(v) * g.nx + u]) continue;
          const double dx = (u - x) * double(g.cell), dy = (v - y) * double(g.cell);
          const double d2 = dx * dx + dy * dy;
          if (d2 > radius * radius) continue;
          const double w = std::exp(-d2 * inv_two_sigma2);
          Eigen::Matrix<double, 6, 1> row;
          row << 1.0, dx, dy, dx * dx, dx * dy, dy * dy;
          ata += w * row * row.transpose();
          atb += w * row * double(src.at(u, v));
          lo = std::min(lo, double(src.at(u, v)));
          hi = std::max(hi, double(src.at(u, v)));
          ++support;
        }
      if (support < kMinSupport) continue;
      const Eigen::LDLT<Eigen::Matrix<double, 6, 6>> ldlt(ata);
      if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) continue;
      const double z = ldlt.solve(atb)[0];
      if (std::isfinite(z)) g.at(x, y) = float(std::clamp(z, lo - margin, hi + margin));
    }
  });
}

constexpr int kMinFitPoints = 6;  // points for a cell's own plane fit

/// Least-squares z = a + b·dx + c·dy over the points of a cell within `band` above its minimum,
/// refit once on the points within half the band of the first fit; returns a (height at centre),
/// or nothing when the cell has too few points or they lie on a line.
std::optional<float> local_height(std::span<const Vec3f> pts, std::span<const std::uint32_t> idx, float zmin,
                                  float band, float cx, float cy) {
  Eigen::Vector3f coef(zmin + 0.5f * band, 0, 0);
  for (int pass = 0; pass < 2; ++pass) {
    Eigen::Matrix3d ata = Eigen::Matrix3d::Zero();
    Eigen::Vector3d atb = Eigen::Vector3d::Zero();
    int n = 0;
    for (auto i : idx) {
      const Vec3f& p = pts[i];
      const float dx = p.x() - cx, dy = p.y() - cy;
      const bool use = pass == 0 ? p.z() <= zmin + band
                                 : std::abs(p.z() - (coef[0] + coef[1] * dx + coef[2] * dy)) <= 0.5f * band;
      if (!use) continue;
      const Eigen::Vector3d r(1.0, dx, dy);
      ata += r * r.transpose();
      atb += r * double(p.z());
      ++n;
    }
    const bool solvable = n >= kMinFitPoints && ata.determinant() >= 1e-12;
    const Eigen::LDLT<Eigen::Matrix3d> ldlt(ata);
    if (!solvable || ldlt.info() != Eigen::Success) {
      if (pass == 0) return std::nullopt;
      return coef[0];
    }
    coef = ldlt.solve(atb).cast<float>();
  }
  return coef[0];
}

/// Height at a cell's centre from the lowest points of the terrain cells around it (3×3, itself
/// included) when the cell has too few points for its own fit (sparse data): a plane through those
/// points where they spread over the neighbourhood in both directions, clamped to their height
/// range widened by itself on both sides; else the cell's own lowest point. Taking the lowest point's height for the centre would
/// put the surface up to half a cell × slope too low on steep ground.
float sparse_height(const GridFrame& g, std::span<const Vec3f> pts, const std::vector<std::uint32_t>& lowest,
                    const std::vector<std::uint8_t>& terrain, int x, int y) {
  constexpr double kMinSpread = 0.25;  // [cells] smallest standard deviation of the points across any xy direction
  const float cx = g.x0 + (float(x) + 0.5f) * g.cell, cy = g.y0 + (float(y) + 0.5f) * g.cell;
  const float own = pts[lowest[g.index(x, y)]].z();
  Eigen::Matrix3d ata = Eigen::Matrix3d::Zero();
  Eigen::Vector3d atb = Eigen::Vector3d::Zero();
  float lo = own, hi = own;
  for (int v = std::max(0, y - 1); v <= std::min(g.ny - 1, y + 1); ++v)
    for (int u = std::max(0, x - 1); u <= std::min(g.nx - 1, x + 1); ++u) {
      const std::size_t k = g.index(u, v);
      if (!terrain[k]) continue;
      const Vec3f& p = pts[lowest[k]];
      const Eigen::Vector3d r(1.0, p.x() - cx, p.y() - cy);
      ata += r * r.transpose();
      atb += r * double(p.z());
      lo = std::min(lo, p.z());
      hi = std::max(hi, p.z());
    }
  const double n = ata(0, 0);
  if (n < 3) return own;
  const Eigen::Vector2d mean = ata.block<2, 1>(1, 0) / n;
  const Eigen::Matrix2d cov = ata.block<2, 2>(1, 1) / n - mean * mean.transpose();
  const double spread = kMinSpread * double(g.cell);
  if (Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(cov).eigenvalues()[0] < spread * spread) return own;
  const float margin = hi - lo;  // the centre may lie outside the points' hull (at a border of the terrain)
  return std::clamp(float(ata.ldlt().solve(atb)[0]), lo - margin, hi + margin);
}

/// Slope (rise/run) of the surface per cell: the gradient's length from central differences
/// (one-sided at the border).
Grid slope_of(const Grid& surface) {
  Grid out = surface;
  const auto diff = [&](int x0, int y0, int x1, int y1) {
    return (surface.at(x1, y1) - surface.at(x0, y0)) / (float(std::max(x1 - x0 + y1 - y0, 1)) * surface.cell);
  };
  for (int y = 0; y < surface.ny; ++y)
    for (int x = 0; x < surface.nx; ++x) {
      const float gx = surface.nx > 1 ? diff(std::max(x - 1, 0), y, std::min(x + 1, surface.nx - 1), y) : 0.0f;
      const float gy = surface.ny > 1 ? diff(x, std::max(y - 1, 0), x, std::min(y + 1, surface.ny - 1)) : 0.0f;
      out.at(x, y) = std::hypot(gx, gy);
    }
  return out;
}

/// Cells the filter took for objects whose lowest point lies in the ground band of the surface
/// (steep ground or terraces the windows cut off) become terrain; returns how many.
std::size_t rejoin_terrain(const Grid& surface, std::span<const Vec3f> pts, const std::vector<std::uint32_t>& lowest,
                           const std::vector<std::uint8_t>& occupied, const GroundConfig& c,
                           std::vector<std::uint8_t>& terrain) {
  const Grid slope = c.slope_height > 0 ? slope_of(surface) : Grid{};
  std::size_t added = 0;
  for (std::size_t k = 0; k < terrain.size(); ++k) {
    if (terrain[k] || !occupied[k]) continue;
    const Vec3f& p = pts[lowest[k]];
    const double band = c.d_plane + (c.slope_height > 0 ? double(float(c.slope_height) * slope.bilinear(p.x(), p.y())) : 0.0);
    if (p.z() - surface.bilinear(p.x(), p.y()) <= band) terrain[k] = 1, ++added;  // as GroundResult::is_ground
  }
  return added;
}

GroundResult ground_plane_method(std::span<const Vec3f> pts, const GroundConfig& c, std::mt19937_64& rng) {
  RansacPlaneConfig rc;
  rc.distance = c.d_plane;
  rc.max_iterations = c.ransac_iterations;
  rc.axis = Vec3f::UnitZ();
  rc.max_tilt = c.max_tilt_deg * std::numbers::pi / 180.0;
  const PlaneFit fit = fit_plane_ransac(pts, {}, rc, rng);
  if (!fit.found) throw InputError("ground: no plane found (too few or degenerate points)");
  GroundResult r;
  r.plane = fit.plane;
  if (r.plane.normal.z() < 0) r.plane = {-r.plane.normal, -r.plane.d};
  r.height.resize(pts.size());
  for (std::size_t i = 0; i < pts.size(); ++i) r.height[i] = r.plane.signed_distance(pts[i]);
  r.d_plane = c.d_plane;
  return r;
}

GroundResult ground_grid_method(std::span<const Vec3f> pts, const GroundConfig& c) {
  if (!(c.cell_size > 0) || !(c.max_window > 0)) throw ConfigError("ground: cell_size and max_window must be > 0");
  if (!(c.slope_height >= 0)) throw ConfigError("ground: slope_height must be >= 0");
  if (c.refine_iterations < 0) throw ConfigError("ground: refine_iterations must be >= 0");
  Grid zmin = make_grid(pts, float(c.cell_size));
  // Points sorted by cell (counting sort): cell k holds order[begin[k] .. begin[k + 1]).
  std::vector<std::uint32_t> cell_of(pts.size()), begin(zmin.v.size() + 1, 0), order(pts.size());
  std::vector<std::uint32_t> lowest(zmin.v.size(), 0);  // per cell: its lowest point
  for (std::uint32_t i = 0; i < pts.size(); ++i) {
    const std::size_t k = zmin.index_of(pts[i]);
    cell_of[i] = std::uint32_t(k);
    ++begin[k + 1];
    if (pts[i].z() < zmin.v[k]) {
      zmin.v[k] = pts[i].z();
      lowest[k] = i;
    }
  }
  for (std::size_t k = 0; k < zmin.v.size(); ++k) begin[k + 1] += begin[k];
  {
    std::vector<std::uint32_t> fill(begin.begin(), begin.end() - 1);
    for (std::uint32_t i = 0; i < pts.size(); ++i) order[fill[cell_of[i]]++] = i;
  }
  const auto members = [&](std::size_t k) {
    return std::span<const std::uint32_t>(order.data() + begin[k], begin[k + 1] - begin[k]);
  };
  std::vector<std::uint8_t> occupied(zmin.v.size());
  for (std::size_t k = 0; k < zmin.v.size(); ++k) occupied[k] = begin[k + 1] > begin[k];
  Grid filled = zmin;
  fill_nearest(filled);
  std::vector<std::uint8_t> ground = pmf_ground_cells(filled, c);
  for (std::size_t k = 0; k < ground.size(); ++k) ground[k] &= occupied[k];

  const auto terrain_surface = [&](const std::vector<std::uint8_t>& terrain) {
    Grid surface = zmin;
    tbb::parallel_for(std::size_t{0}, surface.v.size(), [&](std::size_t k) {
      if (!terrain[k]) return;
      const int x = int(k % std::size_t(surface.nx)), y = int(k / std::size_t(surface.nx));
      const float cx = surface.x0 + (float(x) + 0.5f) * surface.cell;
      const float cy = surface.y0 + (float(y) + 0.5f) * surface.cell;
      const std::optional<float> own = local_height(pts, members(k), zmin.v[k], float(c.initial_height), cx, cy);
      if (own)
        surface.v[k] = *own;
      else if (members(k).size() < std::size_t(kMinFitPoints))  // sparse data: too few points at all
        surface.v[k] = sparse_height(surface, pts, lowest, terrain, x, y);
    });
    harmonic_fill(surface, terrain);
    if (c.fill_radius > 0) quadratic_fill(surface, terrain, c.fill_radius, c.slope * c.fill_radius);
    return surface;
  };
  Grid surface = terrain_surface(ground);
  for (int it = 0; it < c.refine_iterations && rejoin_terrain(surface, pts, lowest, occupied, c, ground) > 0; ++it)
    surface = terrain_surface(ground);

  GroundResult r;
  r.height.resize(pts.size());
  r.d_plane = c.d_plane;
  const Grid slope = c.slope_height > 0 ? slope_of(surface) : Grid{};
  if (c.slope_height > 0) r.widening.resize(pts.size());
  tbb::parallel_for(std::size_t{0}, pts.size(), [&](std::size_t i) {
    r.height[i] = pts[i].z() - surface.bilinear(pts[i].x(), pts[i].y());
    if (c.slope_height > 0) r.widening[i] = float(c.slope_height) * slope.bilinear(pts[i].x(), pts[i].y());
  });
  return r;
}

}  // namespace

GroundResult estimate_ground(std::span<const Vec3f> points, const GroundConfig& config, std::mt19937_64& rng) {
  if (points.size() < 3) throw InputError("ground: need at least 3 points, got " + std::to_string(points.size()));
  GroundResult r;
  if (config.method == "plane")
    r = ground_plane_method(points, config, rng);
  else if (config.method == "grid")
    r = ground_grid_method(points, config);
  else
    throw ConfigError("ground: unknown method '" + config.method + "' (grid or plane)");

  // Dominant plane for the report: least squares over (at most ~kPlanePoints) ground points.
  constexpr std::size_t kPlanePoints = 20000;
  const std::size_t stride = std::max<std::size_t>(1, points.size() / kPlanePoints);
  std::vector<std::uint32_t> ground_idx;
  for (std::uint32_t i = 0; i < points.size(); i += std::uint32_t(stride))
    if (r.is_ground(i)) ground_idx.push_back(i);
  if (config.method == "grid") {
    if (auto p = fit_plane(points, ground_idx)) {
      r.plane = *p;
      if (r.plane.normal.z() < 0) r.plane = {-r.plane.normal, -r.plane.d};
    }
  }
  return r;
}

}  // namespace cairn
