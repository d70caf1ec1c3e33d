#include "cairn/sim/convex_decomposition.hpp"

#include "cairn/core/error.hpp"

#include <Eigen/Geometry>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <optional>
#include <string>
#include <utility>

extern "C" {  // last: its headers define macros (True, False, minimize_, ...)
#include <libqhull_r/qhull_ra.h>
}

namespace cairn::sim {
namespace {

using Eigen::Vector3d;
using Triangle = std::array<std::uint32_t, 3>;

// Interior samples sit off the grid's nodes by these fractions of a cell, so no sample column
// runs exactly through a mesh vertex or edge of a mesh built on a regular lattice.
constexpr double kColumnOffsetX = 0.5 + 1.3e-3, kColumnOffsetY = 0.5 + 0.7e-3, kLayerOffset = 0.5 + 0.3e-3;
constexpr std::size_t kMaxSearchSurfacePoints = 3000;  // hulls during the search of a cut
constexpr double kMinConcavityCut = 0.1;   // a cut must remove this share of its part's concavity
constexpr double kAxisAlignedCosine = 0.999;  // a principal axis this close to an axis is that axis
constexpr double kPlaneTolerance = 1e-9;   // of the mesh's size: a vertex this close lies in a cutting plane

/// qhull's messages (a flat point set is an expected case, answered with volume 0) go nowhere.
FILE* qhull_messages() {
  static FILE* sink = std::fopen("/dev/null", "w");
  return sink;
}

/// A region of space: the points x with n.x <= d for every plane (n, d).
struct HalfspaceRegion {
  std::vector<Eigen::Vector4d> planes;
};

/// Sample points of the mesh's solid and surface, for estimating parts' volumes and hulls.
struct SolidSampling {
  std::vector<Vector3d> inside;   // on a grid, each standing for cell_volume
  double cell_volume = 0.0;
  std::vector<Vector3d> surface;  // vertices and points on large triangles, about a cell apart
};

/// Cells of the grid whose centre lies inside the mesh: the crossings of a vertical line through
/// each column with the triangles, paired in height order (a column with an odd count, grazing
/// an edge, is left out).
std::vector<Vector3d> interior_grid(std::span<const Vector3d> v, std::span<const Triangle> t,
                                    const Eigen::AlignedBox3d& box, double h) {
  const Vector3d size = box.sizes();
  const int nx = std::max(1, static_cast<int>(std::ceil(size.x() / h)));
  const int ny = std::max(1, static_cast<int>(std::ceil(size.y() / h)));
  const int nz = std::max(1, static_cast<int>(std::ceil(size.z() / h)));
  std::vector<std::vector<double>> crossings(static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny));
  const auto column_x = [&](int i) { return box.min().x() + (i + kColumnOffsetX) * h; };
  const auto column_y = [&](int j) { return box.min().y() + (j + kColumnOffsetY) * h; };
  for (const Triangle& tri : t) {
    const Vector3d& a = v[tri[0]];
    const Vector3d& b = v[tri[1]];
    const Vector3d& c = v[tri[2]];
    const double area2 = (b.x() - a.x()) * (c.y() - a.y()) - (b.y() - a.y()) * (c.x() - a.x());
    if (area2 == 0.0) continue;  // vertical: no column crosses it
    const int i0 = std::max(0, static_cast<int>(std::floor((std::min({a.x(), b.x(), c.x()}) - box.min().x()) / h - kColumnOffsetX)));
    const int i1 = std::min(nx - 1, static_cast<int>(std::ceil((std::max({a.x(), b.x(), c.x()}) - box.min().x()) / h)));
    const int j0 = std::max(0, static_cast<int>(std::floor((std::min({a.y(), b.y(), c.y()}) - box.min().y()) / h - kColumnOffsetY)));
    const int j1 = std::min(ny - 1, static_cast<int>(std::ceil((std::max({a.y(), b.y(), c.y()}) - box.min().y()) / h)));
    for (int j = j0; j <= j1; ++j) {
      for (int i = i0; i <= i1; ++i) {
        const double x = column_x(i), y = column_y(j);
        const double wa = ((b.x() - x) * (c.y() - y) - (b.y() - y) * (c.x() - x)) / area2;
        const double wb = ((c.x() - x) * (a.y() - y) - (c.y() - y) * (a.x() - x)) / area2;
        const double wc = 1.0 - wa - wb;
        if (wa < 0.0 || wb < 0.0 || wc < 0.0) continue;
        crossings[static_cast<std::size_t>(j) * static_cast<std::size_t>(nx) + static_cast<std::size_t>(i)].push_back(
            wa * a.z() + wb * b.z() + wc * c.z());
      }
    }
  }
  std::vector<Vector3d> inside;
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) {
      std::vector<double>& z = crossings[static_cast<std::size_t>(j) * static_cast<std::size_t>(nx) + static_cast<std::size_t>(i)];
      if (z.size() % 2 != 0) continue;
      std::sort(z.begin(), z.end());
      for (int k = 0; k < nz; ++k) {
        const double zk = box.min().z() + (k + kLayerOffset) * h;
        const auto above = std::upper_bound(z.begin(), z.end(), zk) - z.begin();
        if (above % 2 == 1) inside.emplace_back(column_x(i), column_y(j), zk);
      }
    }
  }
  return inside;
}

/// The vertices, and on triangles longer than a cell a barycentric lattice about a cell apart.
std::vector<Vector3d> surface_samples(std::span<const Vector3d> v, std::span<const Triangle> t, double h) {
  std::vector<Vector3d> out(v.begin(), v.end());
  for (const Triangle& tri : t) {
    const Vector3d &a = v[tri[0]], &b = v[tri[1]], &c = v[tri[2]];
    const double longest = std::max({(b - a).norm(), (c - b).norm(), (a - c).norm()});
    const int m = static_cast<int>(std::ceil(longest / h));
    for (int i = 0; i <= m; ++i) {
      for (int j = 0; i + j <= m; ++j) {
        const int k = m - i - j;
        if (i == m || j == m || k == m) continue;  // the corners are vertices already
        out.push_back((i * a + j * b + k * c) / m);
      }
    }
  }
  return out;
}

/// A polygon vertex on a triangle: position and weights of the triangle's corners.
struct ClipVertex {
  Vector3d p;
  Eigen::Vector3d w;
};

/// Sutherland–Hodgman: the part of a convex polygon with n.x <= d.
std::vector<ClipVertex> clip_polygon(const std::vector<ClipVertex>& poly, const Eigen::Vector4d& plane) {
  std::vector<ClipVertex> out;
  for (std::size_t i = 0; i < poly.size(); ++i) {
    const ClipVertex& a = poly[i];
    const ClipVertex& b = poly[(i + 1) % poly.size()];
    const double da = plane.head<3>().dot(a.p) - plane.w(), db = plane.head<3>().dot(b.p) - plane.w();
    if (da <= 0.0) out.push_back(a);
    if ((da < 0.0 && db > 0.0) || (da > 0.0 && db < 0.0)) {
      const double u = da / (da - db);
      out.push_back({a.p + u * (b.p - a.p), a.w + u * (b.w - a.w)});
    }
  }
  return out;
}

/// The exact surface points of a region: the mesh's vertices inside it and the corners of its
/// triangles clipped to it. A triangle that only touches a cutting plane from outside adds
/// nothing; one lying in the plane belongs to the side the solid is on (its outward normal
/// along the plane's), so a face flush with a cut never widens the part across it.
CollisionPart exact_part(const HalfspaceRegion& r, std::span<const Vector3d> v, std::span<const Triangle> t,
                         double eps) {
  CollisionPart part;
  std::vector<bool> taken(v.size(), false);
  const auto take_vertex = [&](std::uint32_t i) {
    if (taken[i]) return;
    taken[i] = true;
    part.push_back({{i, i, i, i}, {1.0, 0.0, 0.0, 0.0}});
  };
  for (const Triangle& tri : t) {
    std::vector<ClipVertex> poly = {{v[tri[0]], Vector3d::UnitX()}, {v[tri[1]], Vector3d::UnitY()},
                                    {v[tri[2]], Vector3d::UnitZ()}};
    const Vector3d normal = (v[tri[1]] - v[tri[0]]).cross(v[tri[2]] - v[tri[0]]);
    for (const Eigen::Vector4d& plane : r.planes) {
      double lo = INFINITY, hi = -INFINITY;
      for (std::uint32_t i : tri) {
        const double d = plane.head<3>().dot(v[i]) - plane.w();
        lo = std::min(lo, d);
        hi = std::max(hi, d);
      }
      const bool in_plane = lo >= -eps && hi <= eps;
      if ((in_plane && normal.dot(plane.head<3>()) <= 0.0) || (!in_plane && lo >= 0.0)) {
        poly.clear();
      } else if (!in_plane && hi > 0.0) {
        poly = clip_polygon(poly, plane);
      }
      if (poly.empty()) break;
    }
    for (const ClipVertex& q : poly) {
      int corner = -1;
      for (int k = 0; k < 3; ++k) corner = q.w[k] == 1.0 ? k : corner;
      if (corner >= 0) {
        take_vertex(tri[static_cast<std::size_t>(corner)]);
      } else {
        part.push_back({{tri[0], tri[1], tri[2], tri[0]}, {q.w[0], q.w[1], q.w[2], 0.0}});
      }
    }
  }
  return part;
}

/// The mesh being cut.
struct CutMesh {
  std::span<const Vector3d> v;
  std::span<const Triangle> t;
  double eps = 0.0;  // [m] a vertex this close to a cutting plane lies in it
  std::array<std::uint32_t, 4> span{};  // vertices spanning it: the frame of inner points' weights
};

/// The parity of the triangles a ray from p along dir crosses (Moller–Trumbore).
bool odd_crossings(const Vector3d& p, const Vector3d& dir, std::span<const Vector3d> v, std::span<const Triangle> t) {
  int crossings = 0;
  for (const Triangle& tri : t) {
    const Vector3d e1 = v[tri[1]] - v[tri[0]], e2 = v[tri[2]] - v[tri[0]];
    const Vector3d q = dir.cross(e2);
    const double det = e1.dot(q);
    if (det == 0.0) continue;
    const Vector3d s = p - v[tri[0]];
    const double a = s.dot(q) / det;
    if (a < 0.0 || a > 1.0) continue;
    const Vector3d r = s.cross(e1);
    const double b = dir.dot(r) / det;
    if (b < 0.0 || a + b > 1.0) continue;
    crossings += e2.dot(r) / det > 0.0 ? 1 : 0;
  }
  return crossings % 2 == 1;
}

/// Whether p lies inside the closed mesh: two rays leaning off the axes (so they graze no edge of
/// a lattice-built mesh) must both cross it an odd number of times — a ray through a shared edge
/// counts it twice, and a corner wrongly inside would bulge a part's hull into the air.
bool inside_solid(const Vector3d& p, std::span<const Vector3d> v, std::span<const Triangle> t) {
  return odd_crossings(p, Vector3d(0.0123, 0.0347, 1.0).normalized(), v, t) &&
         odd_crossings(p, Vector3d(-0.0411, 0.0213, -1.0).normalized(), v, t);
}

/// Four vertices spanning the mesh (a well-shaped tetrahedron), for the affine weights of
/// points inside it.
std::array<std::uint32_t, 4> spanning_vertices(std::span<const Vector3d> v) {
  const auto farthest = [&](const auto& distance) {
    std::uint32_t best = 0;
    for (std::uint32_t i = 1; i < v.size(); ++i) best = distance(v[i]) > distance(v[best]) ? i : best;
    return best;
  };
  const std::uint32_t a = farthest([&](const Vector3d& p) { return -p.x(); });
  const std::uint32_t b = farthest([&](const Vector3d& p) { return (p - v[a]).squaredNorm(); });
  const Vector3d ab = (v[b] - v[a]).normalized();
  const std::uint32_t c = farthest([&](const Vector3d& p) { return (p - v[a]).cross(ab).squaredNorm(); });
  const Vector3d n = (v[b] - v[a]).cross(v[c] - v[a]).normalized();
  const std::uint32_t d = farthest([&](const Vector3d& p) { return std::abs(n.dot(p - v[a])); });
  return {a, b, c, d};
}

/// Where three of the region's planes meet inside the solid: corners of the piece that lie on
/// no triangle.
std::vector<MeshPoint> inner_corners(const HalfspaceRegion& r, const CutMesh& m) {
  std::vector<MeshPoint> out;
  if (r.planes.size() < 3) return out;
  const std::span<const Vector3d> v = m.v;
  const std::array<std::uint32_t, 4>& s = m.span;
  Eigen::Matrix3d frame;
  frame << v[s[1]] - v[s[0]], v[s[2]] - v[s[0]], v[s[3]] - v[s[0]];
  const Eigen::PartialPivLU<Eigen::Matrix3d> to_frame(frame);
  for (std::size_t i = 0; i < r.planes.size(); ++i) {
    for (std::size_t j = i + 1; j < r.planes.size(); ++j) {
      for (std::size_t k = j + 1; k < r.planes.size(); ++k) {
        Eigen::Matrix3d A;
        A << r.planes[i].head<3>().transpose(), r.planes[j].head<3>().transpose(), r.planes[k].head<3>().transpose();
        if (std::abs(A.determinant()) < 1e-9) continue;  // parallel planes meet nowhere
        const Vector3d x = A.partialPivLu().solve(Vector3d(r.planes[i].w(), r.planes[j].w(), r.planes[k].w()));
        const bool in_region = std::all_of(r.planes.begin(), r.planes.end(), [&](const Eigen::Vector4d& h) {
          return h.head<3>().dot(x) <= h.w() + m.eps;
        });
        if (!in_region || !inside_solid(x, v, m.t)) continue;
        const Vector3d l = to_frame.solve(x - v[s[0]]);
        out.push_back({s, {1.0 - l.sum(), l.x(), l.y(), l.z()}});
      }
    }
  }
  return out;
}

/// A part during the search: its region, its samples (indices), the hull of its samples (to
/// rank cuts), its exact part and hull, and its volume (the interior samples).
struct CutPiece {
  HalfspaceRegion region;
  std::vector<std::uint32_t> surface, inside;
  std::vector<MeshPoint> corners;  // where three of its planes meet inside the solid
  double search_hull = 0.0, hull = 0.0, volume = 0.0;
  CollisionPart part;
  bool final = false;
  [[nodiscard]] double concavity() const { return hull - volume; }
  void make_exact(const CutMesh& m) {
    part = exact_part(region, m.v, m.t, m.eps);
    part.insert(part.end(), corners.begin(), corners.end());
    hull = convex_hull_volume(part_points(part, m.v));
  }
};

double sampled_hull(const std::vector<Vector3d>& pts, const std::vector<std::uint32_t>& idx,
                    std::vector<Vector3d> p) {
  const std::size_t stride = std::max<std::size_t>(1, (idx.size() + kMaxSearchSurfacePoints - 1) / kMaxSearchSurfacePoints);
  p.reserve(idx.size() / stride + 1);
  for (std::size_t i = 0; i < idx.size(); i += stride) p.push_back(pts[idx[i]]);
  return convex_hull_volume(p);
}

/// A candidate piece: its samples, and the hull of its surface samples and inner corners.
CutPiece make_cut_piece(HalfspaceRegion region, std::vector<std::uint32_t> surface, std::vector<std::uint32_t> inside,
                        const SolidSampling& s, const CutMesh& m) {
  CutPiece p{std::move(region), std::move(surface), std::move(inside)};
  p.corners = inner_corners(p.region, m);
  p.search_hull = sampled_hull(s.surface, p.surface, part_points(p.corners, m.v));
  p.volume = static_cast<double>(p.inside.size()) * s.cell_volume;
  return p;
}

/// Splits the indices by the plane n.x <= cut.
std::pair<std::vector<std::uint32_t>, std::vector<std::uint32_t>> split_by_plane(const std::vector<Vector3d>& pts,
                                                                                 const std::vector<std::uint32_t>& idx,
                                                                                 const Vector3d& n, double cut) {
  std::pair<std::vector<std::uint32_t>, std::vector<std::uint32_t>> out;
  for (std::uint32_t i : idx) (n.dot(pts[i]) <= cut ? out.first : out.second).push_back(i);
  return out;
}

/// Directions to cut a piece across: the mesh's axes and the piece's principal axes (of its
/// interior samples), which follow a bent or tilted lobe.
std::vector<Vector3d> cut_directions(const CutPiece& p, const SolidSampling& s) {
  std::vector<Vector3d> dirs = {Vector3d::UnitX(), Vector3d::UnitY(), Vector3d::UnitZ()};
  if (p.inside.size() < 4) return dirs;
  Vector3d mean = Vector3d::Zero();
  for (std::uint32_t i : p.inside) mean += s.inside[i];
  mean /= static_cast<double>(p.inside.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (std::uint32_t i : p.inside) cov += (s.inside[i] - mean) * (s.inside[i] - mean).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
  for (int k = 0; k < 3; ++k) {
    const Vector3d d = eig.eigenvectors().col(k);
    if (d.cwiseAbs().maxCoeff() < kAxisAlignedCosine) dirs.push_back(d);  // not an axis already
  }
  return dirs;
}

/// The best cut of a piece (its children's sampled hulls smallest) across the cut directions,
/// or nothing when no cut removes kMinConcavityCut of its concavity with both children above the
/// smallest part.
std::optional<std::pair<CutPiece, CutPiece>> best_cut(const CutPiece& p, const SolidSampling& s, const CutMesh& m,
                                                      double min_volume, const ConvexDecompositionConfig& c) {
  std::optional<std::pair<CutPiece, CutPiece>> best;
  double best_hulls = p.search_hull - kMinConcavityCut * std::max(0.0, p.concavity());
  for (const Vector3d& n : cut_directions(p, s)) {
    double lo = INFINITY, hi = -INFINITY;
    for (std::uint32_t i : p.surface) {
      lo = std::min(lo, n.dot(s.surface[i]));
      hi = std::max(hi, n.dot(s.surface[i]));
    }
    for (int q = 1; q <= c.planes_per_axis; ++q) {
      const double cut = lo + (hi - lo) * q / (c.planes_per_axis + 1);
      auto [in_a, in_b] = split_by_plane(s.inside, p.inside, n, cut);
      if (static_cast<double>(std::min(in_a.size(), in_b.size())) * s.cell_volume < min_volume) continue;
      auto [s_a, s_b] = split_by_plane(s.surface, p.surface, n, cut);
      const Eigen::Vector4d plane(n.x(), n.y(), n.z(), cut);
      HalfspaceRegion ra = p.region, rb = p.region;
      ra.planes.push_back(plane);
      rb.planes.push_back(-plane);
      CutPiece a = make_cut_piece(std::move(ra), std::move(s_a), std::move(in_a), s, m);
      CutPiece b = make_cut_piece(std::move(rb), std::move(s_b), std::move(in_b), s, m);
      if (a.search_hull > 0.0 && b.search_hull > 0.0 && a.search_hull + b.search_hull < best_hulls) {
        best_hulls = a.search_hull + b.search_hull;
        best.emplace(std::move(a), std::move(b));
      }
    }
  }
  return best;
}

}  // namespace

double convex_hull_volume(std::span<const Vector3d> points) {
  if (points.size() < 4) return 0.0;
  std::vector<coordT> xyz;
  xyz.reserve(3 * points.size());
  for (const Vector3d& p : points) {
    if (!p.allFinite()) return 0.0;
    xyz.insert(xyz.end(), {p.x(), p.y(), p.z()});
  }
  // "FA": the area and volume are computed inside qh_new_qhull, under qhull's error handler
  // (called after it, qh_getarea would exit() the process on an error). "QJ" (joggled input)
  // answers a nearly degenerate set that the exact run rejects.
  double volume = 0.0;
  for (const char* options : {"qhull FA", "qhull FA QJ"}) {
    qhT qh_storage;
    qhT* qh = &qh_storage;
    qh_zero(qh, qhull_messages());
    std::string flags = options;
    const int code = qh_new_qhull(qh, 3, static_cast<int>(points.size()), xyz.data(), False, flags.data(), nullptr,
                                  qhull_messages());
    if (code == 0) volume = qh->totvol;
    qh_freeqhull(qh, !qh_ALL);
    int still_long = 0, total_long = 0;
    qh_memfreeshort(qh, &still_long, &total_long);
    if (code == 0) break;
  }
  return volume;
}

double mesh_volume(std::span<const Vector3d> v, std::span<const Triangle> t) {
  if (v.empty()) return 0.0;
  const Vector3d ref = v.front();  // a local reference point limits cancellation
  double six_volume = 0.0;
  for (const Triangle& tri : t) six_volume += (v[tri[0]] - ref).dot((v[tri[1]] - ref).cross(v[tri[2]] - ref));
  return six_volume / 6.0;
}

std::vector<Vector3d> part_points(const CollisionPart& part, std::span<const Vector3d> v) {
  std::vector<Vector3d> out;
  out.reserve(part.size());
  for (const MeshPoint& q : part) {
    out.push_back(q.w[0] * v[q.i[0]] + q.w[1] * v[q.i[1]] + q.w[2] * v[q.i[2]] + q.w[3] * v[q.i[3]]);
  }
  return out;
}

ConvexDecomposition decompose_convex(std::span<const Vector3d> v, std::span<const Triangle> t,
                                     const ConvexDecompositionConfig& c) {
  for (const Triangle& tri : t) {
    if (std::max({tri[0], tri[1], tri[2]}) >= v.size()) throw InputError("decompose_convex: a triangle indexes no vertex");
  }
  ConvexDecomposition out;
  out.mesh_volume = mesh_volume(v, t);
  if (c.max_excess < 0.0) return out;
  out.hull_volume = out.parts_volume = convex_hull_volume(v);
  if (!(out.mesh_volume > 0.0) || out.hull_volume <= (1.0 + c.max_excess) * out.mesh_volume) return out;
  Eigen::AlignedBox3d box;
  for (const Vector3d& p : v) box.extend(p);
  const double h = box.sizes().maxCoeff() / std::max(1, c.grid_cells);
  SolidSampling s;
  s.inside = interior_grid(v, t, box, h);
  s.cell_volume = out.mesh_volume / static_cast<double>(std::max<std::size_t>(1, s.inside.size()));
  s.surface = surface_samples(v, t, h);
  std::vector<std::uint32_t> all_surface(s.surface.size()), all_inside(s.inside.size());
  std::iota(all_surface.begin(), all_surface.end(), 0U);
  std::iota(all_inside.begin(), all_inside.end(), 0U);
  const CutMesh mesh{v, t, kPlaneTolerance * box.sizes().maxCoeff(), spanning_vertices(v)};
  std::vector<CutPiece> pieces;
  pieces.push_back(make_cut_piece({}, std::move(all_surface), std::move(all_inside), s, mesh));
  pieces.back().hull = out.hull_volume;
  const auto total_hull = [&] {
    return std::accumulate(pieces.begin(), pieces.end(), 0.0, [](double a, const CutPiece& p) { return a + p.hull; });
  };
  while (static_cast<int>(pieces.size()) < c.max_parts && total_hull() > (1.0 + c.max_excess) * out.mesh_volume) {
    std::size_t worst = pieces.size();
    for (std::size_t i = 0; i < pieces.size(); ++i) {
      if (!pieces[i].final && (worst == pieces.size() || pieces[i].concavity() > pieces[worst].concavity())) worst = i;
    }
    if (worst == pieces.size()) break;
    std::optional<std::pair<CutPiece, CutPiece>> cut = best_cut(pieces[worst], s, mesh, c.min_part_share * out.mesh_volume, c);
    if (!cut) {
      pieces[worst].final = true;
      continue;
    }
    cut->first.make_exact(mesh);
    cut->second.make_exact(mesh);
    if (!(cut->first.hull > 0.0 && cut->second.hull > 0.0)) {  // qhull found no solid: keep the part whole
      pieces[worst].final = true;
      continue;
    }
    pieces[worst] = std::move(cut->first);
    pieces.push_back(std::move(cut->second));
  }
  if (pieces.size() < 2) return out;
  out.parts_volume = total_hull();
  for (CutPiece& p : pieces) out.parts.push_back(std::move(p.part));
  return out;
}

}  // namespace cairn::sim
