#include "cairn/sim/physics/scene.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <memory>
#include <mutex>
#include <sstream>

#include "cairn/core/error.hpp"

namespace cairn::sim::detail {
namespace {

using Eigen::Isometry3d;
using Eigen::Matrix3d;
using Eigen::Vector2d;
using Eigen::Vector3d;

constexpr double kMinElevationRange = 1e-3;  // [m] MuJoCo needs a positive height-field range
// Contact buffers, sized by the free bodies: MuJoCo 2.2.2 allocates njmax^2 doubles (efc_AR)
// and clears them when it makes its data (three times per load), so oversized buffers cost more
// than the simulation itself (0.6 s per scene at njmax 3000). Measured: a stone on the height
// field has at most ~20 contacts at 0.1 m resolution, a gripper geom a few.
constexpr int kContactsPerStone = mjMAXCONPAIR + 14;  // its height-field pair + neighbours
// A further convex part of a stone (Stone::collision_parts): a stone's contacts spread over its
// parts (measured: a 6-stone pile with 8 extra parts used at most 94 of 416 + 8 x 16 contacts).
constexpr int kContactsPerExtraPart = 4;
constexpr int kContactsPerGripperGeom = 8;
constexpr int kContactsSpare = 32;
constexpr int kCondim = 6;                   // every contact: sliding, torsional and rolling friction
// Constraint rows per contact: 2 (condim - 1) for pyramidal cones, condim for elliptic ones. The
// njmax^2 buffers make this the largest cost of building a scene (settling a pile builds many).
int rows_per_contact(const std::string& cone) { return cone == "elliptic" ? kCondim : 2 * (kCondim - 1); }
constexpr int kNonContactRows = 16;  // the arm's weld (6), the jaws' coupling (1) and limits (2), spare
constexpr double kImpedanceSpan = 0.04;      // solimp dmin = dmax - span

/// MuJoCo reports fatal errors through this hook; the default prints and calls exit().
void throw_mujoco_error(const char* msg) { throw InputError(std::string("MuJoCo: ") + msg); }
void ignore_mujoco_warning(const char*) {}  // warnings are read from mjData::warning instead

struct MassProperties {
  double volume = 0.0;
  Vector3d centroid = Vector3d::Zero();
  Matrix3d inertia_unit_density = Matrix3d::Zero();  // about the centroid, world axes
};

/// Volume integrals of a closed, outward-oriented mesh (tetrahedra from a reference point).
MassProperties mass_properties(const io::Mesh& mesh, const Vector3d& reference) {
  MassProperties mp;
  Matrix3d second = Matrix3d::Zero();  // ∫ x x^T dV about `reference`
  Vector3d first = Vector3d::Zero();   // ∫ x dV
  for (const auto& t : mesh.triangles) {
    const Vector3d a = mesh.vertices.world(t[0]) - reference;
    const Vector3d b = mesh.vertices.world(t[1]) - reference;
    const Vector3d c = mesh.vertices.world(t[2]) - reference;
    const double v = a.dot(b.cross(c)) / 6.0;
    mp.volume += v;
    first += v * (a + b + c) / 4.0;
    const Vector3d s = a + b + c;
    second += v / 20.0 * (a * a.transpose() + b * b.transpose() + c * c.transpose() + s * s.transpose());
  }
  if (!(mp.volume > 0.0)) throw InputError("physics: stone mesh has no positive volume");
  const Vector3d offset = first / mp.volume;
  mp.centroid = reference + offset;
  const Matrix3d cov = second - mp.volume * offset * offset.transpose();  // about the centroid
  mp.inertia_unit_density = cov.trace() * Matrix3d::Identity() - cov;
  return mp;
}

/// The points MuJoCo builds a collision hull from: all of them (subdivisions < 0), or the
/// extreme point along each vertex direction of an icosphere with that many subdivisions
/// (10 * 4^s + 2 directions), ascending and unique. Fewer hull vertices make every
/// support-function walk of MuJoCo's convex collisions shorter (docs/simulator-physics.md).
/// Compared in float, as the stones' float vertices always were (site coordinates are metres
/// from the site's origin): in double, near-ties pick other vertices, and that rounding-level
/// change of the hulls alone changes which stones exp1 seed 1's three-stone experiment tracks.
std::vector<std::size_t> collision_vertices(const std::vector<Vector3d>& points, int subdivisions) {
  std::vector<std::size_t> out;
  const std::size_t n = points.size();
  if (subdivisions < 0 || n <= 10 * (std::size_t{1} << (2 * subdivisions)) + 2) {
    for (std::size_t i = 0; i < n; ++i) out.push_back(i);
    return out;
  }
  const io::Mesh sphere = make_icosphere(subdivisions);
  for (std::size_t d = 0; d < sphere.vertices.size(); ++d) {
    const Eigen::Vector3f dir = sphere.vertices.points[d];
    std::size_t best = 0;
    float best_dot = -INFINITY;
    for (std::size_t i = 0; i < n; ++i) {
      const float dot = dir.dot(points[i].cast<float>());
      if (dot > best_dot) {
        best_dot = dot;
        best = i;
      }
    }
    out.push_back(best);
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

std::string quat_attr(const Matrix3d& R) {
  const Eigen::Quaterniond q(R);
  std::ostringstream s;
  s.precision(17);
  s << q.w() << ' ' << q.x() << ' ' << q.y() << ' ' << q.z();
  return s.str();
}

std::string num(double v) {
  std::ostringstream s;
  s.precision(17);
  s << v;
  return s.str();
}

std::string vec_attr(const Vector3d& v) {
  std::ostringstream s;
  s.precision(17);
  s << v.x() << ' ' << v.y() << ' ' << v.z();
  return s.str();
}

struct HeightField {
  double x0 = 0, y0 = 0, spacing = 0.1;
  int nrow = 2, ncol = 2;  // rows along y, columns along x (MuJoCo: first sample at -x, -y)
  double zmin = 0, zmax = 0;
  std::vector<double> z;  // nrow * ncol
};

/// Samples the terrain on the world lattice of spacing `res` (x = i res, y = j res) over the
/// region: every scene of a site sees the same piecewise-linear ground wherever their regions
/// overlap, so a world at rest in one scene is at rest in the next.
HeightField sample_terrain(const Terrain& terrain, const Eigen::AlignedBox2d& region, double res) {
  HeightField h;
  h.spacing = res;
  h.x0 = std::floor(region.min().x() / res) * res;
  h.y0 = std::floor(region.min().y() / res) * res;
  h.ncol = std::max(2, static_cast<int>(std::ceil((region.max().x() - h.x0) / res)) + 1);
  h.nrow = std::max(2, static_cast<int>(std::ceil((region.max().y() - h.y0) / res)) + 1);
  h.z.resize(static_cast<std::size_t>(h.nrow) * static_cast<std::size_t>(h.ncol));
  h.zmin = INFINITY;
  h.zmax = -INFINITY;
  for (int r = 0; r < h.nrow; ++r) {
    for (int c = 0; c < h.ncol; ++c) {
      const double z = terrain.height(h.x0 + c * res, h.y0 + r * res);
      h.z[static_cast<std::size_t>(r) * static_cast<std::size_t>(h.ncol) + static_cast<std::size_t>(c)] = z;
      h.zmin = std::min(h.zmin, z);
      h.zmax = std::max(h.zmax, z);
    }
  }
  return h;
}

using Triangle = std::array<Vector3d, 3>;

/// Lowers the height-field samples under the given (stone hull) triangles to `clearance` below
/// the hull's underside: stones embedded in the terrain (StoneConfig::embed_depth) start in a
/// mould instead of overlapping the ground. Between samples the piecewise-linear surface can
/// still cut the hull's facet edges slightly (about resolution x slope change); Scene::relax
/// resolves that gently.
void carve_seats(HeightField& h, const std::vector<Triangle>& triangles, double clearance) {
  for (const auto& [a, b, c] : triangles) {
    const double lo_x = std::min({a.x(), b.x(), c.x()}), hi_x = std::max({a.x(), b.x(), c.x()});
    const double lo_y = std::min({a.y(), b.y(), c.y()}), hi_y = std::max({a.y(), b.y(), c.y()});
    const int c0 = std::max(0, static_cast<int>(std::ceil((lo_x - h.x0) / h.spacing)));
    const int c1 = std::min(h.ncol - 1, static_cast<int>(std::floor((hi_x - h.x0) / h.spacing)));
    const int r0 = std::max(0, static_cast<int>(std::ceil((lo_y - h.y0) / h.spacing)));
    const int r1 = std::min(h.nrow - 1, static_cast<int>(std::floor((hi_y - h.y0) / h.spacing)));
    const double det = (b.x() - a.x()) * (c.y() - a.y()) - (c.x() - a.x()) * (b.y() - a.y());
    if (std::abs(det) < 1e-12) continue;  // vertical triangle: no underside
    for (int r = r0; r <= r1; ++r) {
      for (int col = c0; col <= c1; ++col) {
        const double x = h.x0 + col * h.spacing, y = h.y0 + r * h.spacing;
        const double u = ((x - a.x()) * (c.y() - a.y()) - (c.x() - a.x()) * (y - a.y())) / det;
        const double w = ((b.x() - a.x()) * (y - a.y()) - (x - a.x()) * (b.y() - a.y())) / det;
        if (u < 0 || w < 0 || u + w > 1) continue;
        const double z = a.z() + u * (b.z() - a.z()) + w * (c.z() - a.z());
        double& hz = h.z[static_cast<std::size_t>(r) * static_cast<std::size_t>(h.ncol) + static_cast<std::size_t>(col)];
        hz = std::min(hz, z - clearance);
      }
    }
  }
}

/// Triangles of the convex hull MuJoCo collides for mesh geom `g` of a stone body whose origin
/// sits at `centroid` with world axes. MuJoCo 2.2.2's mesh graph: numvert, numface,
/// vert_edgeadr[numvert], vert_globalid[numvert], edge_localid[numvert + 3 numface],
/// face_globalid[3 numface]. Without a graph (small meshes) the mesh's own faces are used.
std::vector<Triangle> hull_triangles(const mjModel* m, int g, const Vector3d& centroid) {
  const int mesh = m->geom_dataid[g];
  const mjtNum* gq = m->geom_quat + 4 * g;
  const Matrix3d R = Eigen::Quaterniond(gq[0], gq[1], gq[2], gq[3]).normalized().toRotationMatrix();
  const Vector3d t = centroid + Vector3d(m->geom_pos[3 * g], m->geom_pos[3 * g + 1], m->geom_pos[3 * g + 2]);
  const float* vert = m->mesh_vert + 3 * m->mesh_vertadr[mesh];
  const auto world = [&](int i) {
    return Vector3d(t + R * Vector3d(vert[3 * i], vert[3 * i + 1], vert[3 * i + 2]));
  };
  std::vector<Triangle> out;
  if (m->mesh_graphadr[mesh] >= 0) {
    const int* graph = m->mesh_graph + m->mesh_graphadr[mesh];
    const int nv = graph[0], nf = graph[1];
    const int* face = graph + 2 + 3 * nv + 3 * nf;
    for (int f = 0; f < nf; ++f) out.push_back({world(face[3 * f]), world(face[3 * f + 1]), world(face[3 * f + 2])});
  } else {
    const int* face = m->mesh_face + 3 * m->mesh_faceadr[mesh];
    for (int f = 0; f < m->mesh_facenum[mesh]; ++f) {
      out.push_back({world(face[3 * f]), world(face[3 * f + 1]), world(face[3 * f + 2])});
    }
  }
  return out;
}

/// The collision geoms of stone k (its convex parts).
std::vector<int> stone_geoms(const mjModel* m, std::size_t k) {
  const int body = mj_name2id(m, mjOBJ_BODY, ("stone" + std::to_string(k)).c_str());
  std::vector<int> out;
  for (int g = 0; g < m->ngeom; ++g) {
    if (m->geom_bodyid[g] == body) out.push_back(g);
  }
  return out;
}

}  // namespace

std::string entity_name(int e) {
  switch (e) {
    case kTerrain: return "terrain";
    case kPalm: return "palm";
    case kJawLeft: return "jaw_left";
    case kJawRight: return "jaw_right";
    default: return "stone " + std::to_string(e);
  }
}

// ---------------------------------------------------------------------------------------------
// Scene construction, step by step: the stones' mass properties, the height field's region and
// samples, the MJCF text (options, assets, stones, gripper, its constraints), loading, seats, the
// geom → entity table.

namespace {

/// Per-stone mass properties at unit density and radius about the centroid; throws InputError
/// on a stone without a mesh.
struct StoneBodies {
  std::vector<MassProperties> props;
  std::vector<double> radius;
};

StoneBodies stone_bodies(const Site& site) {
  StoneBodies b;
  for (std::size_t k = 0; k < site.stones.size(); ++k) {
    const Stone& s = site.stones[k];
    if (s.mesh.triangles.empty()) throw InputError("physics: stone " + std::to_string(k) + " has no mesh");
    b.props.push_back(mass_properties(s.mesh, s.centroid));
    double radius = 0.0;
    for (std::size_t i = 0; i < s.mesh.vertices.size(); ++i) {
      radius = std::max(radius, (s.mesh.vertices.world(i) - b.props.back().centroid).norm());
    }
    b.radius.push_back(radius);
  }
  return b;
}

/// The height field's region: the free stones' footprints at their start poses (static stones
/// never touch the terrain) and the points the spec names (the gripper's path), plus the margin.
Eigen::AlignedBox2d terrain_region(const Site& site, const SceneSpec& spec, const std::vector<bool>& free,
                                   double margin) {
  Eigen::AlignedBox2d region;
  for (std::size_t k = 0; k < site.stones.size(); ++k) {
    if (!free[k]) continue;
    const Stone& s = site.stones[k];
    for (std::size_t i = 0; i < s.mesh.vertices.size(); ++i) region.extend((spec.start_poses[k] * s.mesh.vertices.world(i)).head<2>());
  }
  for (const Vector2d& p : spec.extra_xy) region.extend(p);
  if (region.isEmpty()) region.extend(Vector2d::Zero());
  region.min().array() -= margin;
  region.max().array() += margin;
  return region;
}

std::string mjcf_header(const PhysicsConfig& c, int max_contacts) {
  std::ostringstream x;
  x.precision(17);
  const std::string friction = num(c.friction) + " " + num(c.torsional_friction) + " " + num(c.rolling_friction);
  x << "<mujoco model=\"cairn_site\">\n"
    << "<compiler angle=\"radian\" inertiafromgeom=\"auto\"/>\n"
    << "<option timestep=\"" << c.timestep << "\" gravity=\"0 0 -9.81\" cone=\"" << c.cone
    << "\" jacobian=\"dense\" noslip_iterations=\"" << c.noslip_iterations << "\" iterations=\""
    << c.solver_iterations << "\" tolerance=\"" << c.solver_tolerance << "\"/>\n"
    << "<size nconmax=\"" << max_contacts << "\" njmax=\"" << max_contacts * rows_per_contact(c.cone) + kNonContactRows
    << "\"/>\n"
    << "<default><geom condim=\"" << kCondim << "\" friction=\"" << friction << "\" solref=\"" << c.contact_timeconst
    << " 1\" solimp=\"" << c.contact_impedance - kImpedanceSpan << ' ' << c.contact_impedance << " 0.001\"/></default>\n";
  return x.str();
}

std::string part_name(std::size_t stone, std::size_t part) {
  return "stone" + std::to_string(stone) + "_" + std::to_string(part);
}

/// The height field and the collision meshes of each stone: one per convex part (Stone::
/// collision_parts; the whole mesh when it has none), its hull vertices about the centroid.
std::string mjcf_assets(const Site& site, const StoneBodies& bodies, const HeightField& hf, double range,
                        const PhysicsConfig& c) {
  std::ostringstream x;
  x.precision(17);
  x << "<asset>\n<hfield name=\"terrain\" nrow=\"" << hf.nrow << "\" ncol=\"" << hf.ncol << "\" size=\""
    << 0.5 * (hf.ncol - 1) * hf.spacing << ' ' << 0.5 * (hf.nrow - 1) * hf.spacing << ' ' << range << ' '
    << c.terrain_base << "\"/>\n";
  for (std::size_t k = 0; k < site.stones.size(); ++k) {
    const std::vector<std::vector<Vector3d>> parts = collision_point_sets(site.stones[k]);
    for (std::size_t p = 0; p < parts.size(); ++p) {
      x << "<mesh name=\"" << part_name(k, p) << "\" vertex=\"";
      const std::vector<std::size_t> hull = collision_vertices(parts[p], c.hull_subdivisions);
      for (std::size_t i = 0; i < hull.size(); ++i) {
        x << (i ? " " : "") << vec_attr(parts[p][hull[i]] - bodies.props[k].centroid);
      }
      x << "\"/>\n";
    }
  }
  x << "</asset>\n";
  return x.str();
}

/// The terrain geom (its own rolling friction: the gravel bed) and the stone bodies.
std::string mjcf_world(const Site& site, const SceneSpec& spec, const std::vector<bool>& free,
                       const StoneBodies& bodies, const HeightField& hf, const PhysicsConfig& c) {
  std::ostringstream x;
  x.precision(17);
  const double half_x = 0.5 * (hf.ncol - 1) * hf.spacing, half_y = 0.5 * (hf.nrow - 1) * hf.spacing;
  x << "<geom name=\"terrain\" type=\"hfield\" hfield=\"terrain\" pos=\""
    << vec_attr({hf.x0 + half_x, hf.y0 + half_y, hf.zmin}) << "\" friction=\"" << num(c.friction) << ' '
    << num(c.torsional_friction) << ' ' << num(std::max(c.rolling_friction, c.ground_rolling_friction)) << "\"/>\n";
  for (std::size_t k = 0; k < site.stones.size(); ++k) {
    const Isometry3d& S = spec.start_poses[k];
    const double mass = c.rock_density * bodies.props[k].volume;
    const Matrix3d I = c.rock_density * bodies.props[k].inertia_unit_density;
    x << "<body name=\"stone" << k << "\" pos=\"" << vec_attr(S * bodies.props[k].centroid) << "\" quat=\""
      << quat_attr(S.linear()) << "\">\n" << (free[k] ? "<freejoint/>\n" : "")
      << "<inertial pos=\"0 0 0\" mass=\"" << mass << "\" fullinertia=\"" << I(0, 0) << ' ' << I(1, 1) << ' '
      << I(2, 2) << ' ' << I(0, 1) << ' ' << I(0, 2) << ' ' << I(1, 2) << "\"/>\n";
    for (std::size_t p = 0; p < std::max<std::size_t>(1, site.stones[k].collision_parts.size()); ++p) {
      x << "<geom name=\"" << part_name(k, p) << "\" type=\"mesh\" mesh=\"" << part_name(k, p) << "\"/>\n";
    }
    x << "</body>\n";
  }
  return x.str();
}

std::string box_geom(const std::string& name, const Vector3d& center, const Matrix3d& axes, const Vector3d& half,
                     double mass) {
  return "<geom name=\"" + name + "\" type=\"box\" pos=\"" + vec_attr(center) + "\" quat=\"" + quat_attr(axes) +
         "\" size=\"" + vec_attr(half) + "\" mass=\"" + num(mass) + "\"/>\n";
}

/// A jaw (in its hinge frame) as pads x pads boxes tiling its length and height: a flat contact
/// gives several contact points (MuJoCo 2.2.2 reports one per convex pair) and resists rotation.
std::string jaw_pads(const ConvexPart& jaw, const PhysicsConfig& c) {
  std::string out;
  const int n = c.jaw_pads;
  const Vector3d half(jaw.half_extents.x() / n, jaw.half_extents.y(), jaw.half_extents.z() / n);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const Vector3d offset(-jaw.half_extents.x() + (2 * i + 1) * half.x(), 0.0, -jaw.half_extents.z() + (2 * j + 1) * half.z());
      out += box_geom(jaw.name + "_" + std::to_string(i) + "_" + std::to_string(j), jaw.center + jaw.axes * offset,
                      jaw.axes, half, c.jaw_mass / (n * n));
    }
  }
  return out;
}

/// The angular gripper (robot/gripper.hpp): a free palm body held by the arm (a weld to a mocap
/// target), two jaw bodies on hinges at their pivots, starting at the spec's opening, which is
/// also as far as they open (the plan's pre-grasp opening; the hydraulics hold it). The joint
/// value is the jaw angle itself (ref = the start angle); free tip speed jaw_speed under the
/// full closing force.
std::string mjcf_gripper(const SceneSpec& spec, const GripperConfig& g, const PhysicsConfig& c) {
  const double angle0 = jaw_angle_for(g, spec.opening);
  const double damping = closing_torque(g) * g.jaw_length / c.jaw_speed;  // torque / (tip speed / length)
  const std::string pose = "pos=\"" + vec_attr(spec.T_world_gripper.translation()) + "\" quat=\"" +
                           quat_attr(spec.T_world_gripper.linear()) + "\"";
  const ConvexPart palm = palm_part(g);
  std::ostringstream x;
  x.precision(17);
  x << "<body name=\"gripper_target\" mocap=\"true\" " << pose << "/>\n"
    << "<body name=\"gripper\" " << pose << ">\n<freejoint/>\n"
    << box_geom(palm.name, palm.center, palm.axes, palm.half_extents, c.palm_mass);
  for (const JawSide side : {JawSide::Left, JawSide::Right}) {
    const ConvexPart jaw = jaw_part(g, side);
    const Isometry3d T = T_gripper_jaw(g, side, angle0);
    x << "<body name=\"" << jaw.name << "\" pos=\"" << vec_attr(T.translation()) << "\" quat=\""
      << quat_attr(T.linear()) << "\">\n"
      << "<joint name=\"" << jaw.name << "\" type=\"hinge\" axis=\"" << vec_attr(jaw_axis(side)) << "\" ref=\""
      << num(angle0) << "\" limited=\"true\" range=\"" << num(min_jaw_angle(g)) << ' ' << num(angle0)
      << "\" solreflimit=\"" << num(c.contact_timeconst) << " 1\" damping=\"" << num(damping) << "\"/>\n"
      << jaw_pads(jaw, c) << "</body>\n";
  }
  x << "</body>\n";
  return x.str();
}

/// The arm's weld, the jaws' mechanical coupling (one DoF: equal angles) and the hydraulic
/// actuator acting on both (MuJoCo's palm-jaw contacts are parent-child, filtered by default).
std::string mjcf_gripper_constraints(const GripperConfig& g, const PhysicsConfig& c) {
  const double torque = closing_torque(g);
  std::ostringstream x;
  x.precision(17);
  x << "<contact><exclude body1=\"jaw_left\" body2=\"jaw_right\"/></contact>\n"
    << "<equality><weld body1=\"gripper\" body2=\"gripper_target\" solref=\"" << c.arm_timeconst << " 1\"/>\n"
    << "<joint joint1=\"jaw_right\" joint2=\"jaw_left\" polycoef=\"0 1 0 0 0\" solref=\"" << c.arm_timeconst
    << " 1\"/></equality>\n<actuator>\n";
  for (const char* jaw : {"jaw_left", "jaw_right"}) {
    x << "<motor name=\"" << jaw << "\" joint=\"" << jaw << "\" gear=\"1\" ctrllimited=\"true\" ctrlrange=\""
      << -torque << ' ' << torque << "\"/>\n";
  }
  x << "</actuator>\n";
  return x.str();
}

/// Loads MJCF text through a virtual file system (MuJoCo 2.2.2 has no load-from-string).
mjModel* load_mjcf(const std::string& xml) {
  auto vfs = std::make_unique<mjVFS>();
  mj_defaultVFS(vfs.get());
  if (mj_makeEmptyFileVFS(vfs.get(), "site.xml", static_cast<int>(xml.size())) != 0) {
    throw InputError("physics: cannot create the in-memory MJCF file");
  }
  const int file = mj_findFileVFS(vfs.get(), "site.xml");
  std::memcpy(vfs->filedata[file], xml.data(), xml.size());
  std::array<char, 1024> error{};
  mjModel* m = nullptr;
  {
    // Scenes are built in parallel (settle_site's islands); MuJoCo 2.2.2 does not promise that
    // its XML parser and compiler are reentrant, so one load at a time. Stepping is per scene.
    static std::mutex loading;
    const std::lock_guard<std::mutex> lock(loading);
    m = mj_loadXML("site.xml", vfs.get(), error.data(), static_cast<int>(error.size()));
  }
  mj_deleteVFS(vfs.get());
  if (m == nullptr) throw InputError(std::string("physics: MuJoCo rejected the model: ") + error.data());
  return m;
}

/// Height-field samples normalised to [0, 1] of the elevation range, into the loaded model.
void write_height_field(mjModel* m, const HeightField& hf, double range) {
  const int hid = mj_name2id(m, mjOBJ_HFIELD, "terrain");
  for (std::size_t i = 0; i < hf.z.size(); ++i) {
    m->hfield_data[static_cast<std::size_t>(m->hfield_adr[hid]) + i] =
        static_cast<float>(std::clamp((hf.z[i] - hf.zmin) / range, 0.0, 1.0));
  }
}

}  // namespace

Scene::Scene(const Site& site, const SceneSpec& spec, const GripperConfig& gripper,
             const PhysicsConfig& config) {
  const std::size_t n = site.stones.size();
  if (spec.start_poses.size() != n) throw InputError("physics: one start pose per stone needed");
  if (!spec.free.empty() && spec.free.size() != n) throw InputError("physics: one free flag per stone needed");
  const std::vector<bool> free = spec.free.empty() ? std::vector<bool>(n, true) : spec.free;
  static std::once_flag hooks;  // MuJoCo's hooks are globals: set once, before any scene exists
  std::call_once(hooks, [] {
    mju_user_error = throw_mujoco_error;
    mju_user_warning = ignore_mujoco_warning;
  });
  const StoneBodies bodies = stone_bodies(site);
  HeightField hf = sample_terrain(site.terrain, terrain_region(site, spec, free, config.terrain_margin),
                                  config.terrain_resolution);
  const bool carve = config.seat_clearance >= 0.0 && !site.at_rest;
  if (carve) {  // seats reach at most down to the stones' lowest points
    for (const Stone& s : site.stones) hf.zmin = std::min(hf.zmin, s.bounds.min().z() - config.seat_clearance);
  }
  const double range = std::max(hf.zmax - hf.zmin, kMinElevationRange);
  const int num_free = static_cast<int>(std::count(free.begin(), free.end(), true));
  const int gripper_geoms = spec.with_gripper ? 1 + 2 * config.jaw_pads * config.jaw_pads : 0;
  int extra_parts = 0;  // free stones touch the parts of static ones too
  for (const Stone& s : site.stones) {
    if (s.collision_parts.size() > 1) extra_parts += static_cast<int>(s.collision_parts.size()) - 1;
  }
  const int max_contacts = kContactsPerStone * num_free + kContactsPerExtraPart * extra_parts +
                           kContactsPerGripperGeom * gripper_geoms + kContactsSpare;
  std::string xml = mjcf_header(config, max_contacts) + mjcf_assets(site, bodies, hf, range, config) +
                    "<worldbody>\n" + mjcf_world(site, spec, free, bodies, hf, config);
  if (spec.with_gripper) xml += mjcf_gripper(spec, gripper, config);
  xml += "</worldbody>\n";
  if (spec.with_gripper) xml += mjcf_gripper_constraints(gripper, config);
  xml += "</mujoco>\n";
  m_ = load_mjcf(xml);
  d_ = mj_makeData(m_);
  if (d_ == nullptr) {
    mj_deleteModel(m_);
    throw InputError("physics: MuJoCo could not allocate its data");
  }
  try {  // the destructor does not run for a constructor that throws
    if (carve) {  // seats under the stones' hulls at their placement in the Site
      for (std::size_t k = 0; k < n; ++k) {
        if (!free[k]) continue;
        for (int g : stone_geoms(m_, k)) carve_seats(hf, hull_triangles(m_, g, bodies.props[k].centroid), config.seat_clearance);
      }
    }
    write_height_field(m_, hf, range);
    for (std::size_t k = 0; k < n; ++k) {
      stone_mass_.push_back(config.rock_density * bodies.props[k].volume);
      centroid_.push_back(bodies.props[k].centroid);
    }
    stone_radius_ = bodies.radius;
    index_entities(free, spec.with_gripper);
    if (spec.with_gripper) {
      gripper_weight_ = m_->body_subtreemass[gripper_body_] * -m_->opt.gravity[2];
    }
    gripper_ = gripper;
    at_rest_ = site.at_rest;
    mj_forward(m_, d_);
  } catch (...) {
    mj_deleteData(d_);
    mj_deleteModel(m_);
    throw;
  }
}

void Scene::index_entities(const std::vector<bool>& free, bool with_gripper) {
  geom_entity_.assign(static_cast<std::size_t>(m_->ngeom), kTerrain);
  for (std::size_t k = 0; k < free.size(); ++k) {
    const std::string name = "stone" + std::to_string(k);
    const int body = mj_name2id(m_, mjOBJ_BODY, name.c_str());
    stone_body_.push_back(body);
    stone_qvel_.push_back(free[k] ? m_->jnt_dofadr[m_->body_jntadr[body]] : -1);
    for (int g : stone_geoms(m_, k)) geom_entity_[static_cast<std::size_t>(g)] = static_cast<int>(k);
  }
  if (!with_gripper) return;
  geom_entity_[static_cast<std::size_t>(mj_name2id(m_, mjOBJ_GEOM, "palm"))] = kPalm;
  const int jaw_body[2] = {mj_name2id(m_, mjOBJ_BODY, "jaw_left"), mj_name2id(m_, mjOBJ_BODY, "jaw_right")};
  for (int g = 0; g < m_->ngeom; ++g) {
    if (m_->geom_bodyid[g] == jaw_body[0]) geom_entity_[static_cast<std::size_t>(g)] = kJawLeft;
    if (m_->geom_bodyid[g] == jaw_body[1]) geom_entity_[static_cast<std::size_t>(g)] = kJawRight;
  }
  gripper_body_ = mj_name2id(m_, mjOBJ_BODY, "gripper");
  mocap_ = m_->body_mocapid[mj_name2id(m_, mjOBJ_BODY, "gripper_target")];
  const char* jaws[2] = {"jaw_left", "jaw_right"};
  for (int j = 0; j < 2; ++j) {
    const int jid = mj_name2id(m_, mjOBJ_JOINT, jaws[j]);
    jaw_qpos_[j] = m_->jnt_qposadr[jid];
    jaw_dof_[j] = m_->jnt_dofadr[jid];
  }
}

void Scene::relax(const PhysicsConfig& c, const std::vector<bool>& damped) {
  if (c.relax_time <= 0.0 || at_rest_) return;
  // Soft contacts everywhere and viscous damping on the chosen stones (mass-proportional, so
  // every stone creeps out of overlaps at about the same rate), then the model's own values.
  std::vector<mjtNum> solref(m_->geom_solref, m_->geom_solref + mjNREF * m_->ngeom);
  std::vector<mjtNum> damping(m_->dof_damping, m_->dof_damping + m_->nv);
  for (int g = 0; g < m_->ngeom; ++g) m_->geom_solref[mjNREF * g] = c.relax_timeconst;
  for (std::size_t k = 0; k < stone_body_.size(); ++k) {
    if (!damped[k] || stone_qvel_[k] < 0) continue;
    const double rate = 1.0 / c.relax_timeconst;
    const double r2 = stone_radius_[k] * stone_radius_[k];
    for (int i = 0; i < 6; ++i) {
      m_->dof_damping[stone_qvel_[k] + i] = stone_mass_[k] * rate * (i < 3 ? 1.0 : r2);
    }
  }
  const double end = d_->time + c.relax_time;
  while (d_->time < end) mj_step(m_, d_);
  std::copy(solref.begin(), solref.end(), m_->geom_solref);
  std::copy(damping.begin(), damping.end(), m_->dof_damping);
  for (std::size_t k = 0; k < stone_body_.size(); ++k) {
    if (damped[k] && stone_qvel_[k] >= 0) std::fill_n(d_->qvel + stone_qvel_[k], 6, 0.0);
  }
}

double Scene::hull_volume(int k) const {
  double total = 0.0;
  for (int g : stone_geoms(m_, static_cast<std::size_t>(k))) {
    double volume = 0.0;
    for (const auto& [a, b, c] : hull_triangles(m_, g, Vector3d::Zero())) volume += a.dot(b.cross(c)) / 6.0;
    total += std::abs(volume);
  }
  return total;
}

Scene::~Scene() {
  if (d_ != nullptr) mj_deleteData(d_);
  if (m_ != nullptr) mj_deleteModel(m_);
}

Isometry3d Scene::stone_body_pose(int k) const {
  const int b = stone_body_[static_cast<std::size_t>(k)];
  const mjtNum* q = d_->xquat + 4 * b;
  Isometry3d T = Isometry3d::Identity();
  T.linear() = Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized().toRotationMatrix();
  T.translation() = Vector3d(d_->xpos[3 * b], d_->xpos[3 * b + 1], d_->xpos[3 * b + 2]);
  return T;
}

Isometry3d Scene::stone_pose(int k) const {
  // body = T_world_stone * (centroid, identity)  =>  T_world_stone = body * (-centroid)
  const Isometry3d body = stone_body_pose(k);
  Isometry3d T = body;
  T.translation() = body.translation() - body.linear() * centroid_[static_cast<std::size_t>(k)];
  return T;
}

double Scene::stone_point_speed(int k) const {
  if (!is_free(k)) return 0.0;
  const mjtNum* v = d_->qvel + stone_qvel_[static_cast<std::size_t>(k)];
  const Vector3d lin(v[0], v[1], v[2]), ang(v[3], v[4], v[5]);
  return lin.norm() + ang.norm() * stone_radius_[static_cast<std::size_t>(k)];
}

double Scene::max_stone_speed() const {
  double s = 0.0;
  for (int k = 0; k < num_stones(); ++k) s = std::max(s, stone_point_speed(k));
  return s;
}

Isometry3d Scene::gripper_pose() const {
  const mjtNum* q = d_->xquat + 4 * gripper_body_;
  Isometry3d T = Isometry3d::Identity();
  T.linear() = Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized().toRotationMatrix();
  T.translation() = Vector3d(d_->xpos[3 * gripper_body_], d_->xpos[3 * gripper_body_ + 1],
                             d_->xpos[3 * gripper_body_ + 2]);
  return T;
}

void Scene::set_gripper_target(const Isometry3d& T) {
  const Eigen::Quaterniond q(T.linear());
  for (int i = 0; i < 3; ++i) d_->mocap_pos[3 * mocap_ + i] = T.translation()[i];
  d_->mocap_quat[4 * mocap_ + 0] = q.w();
  d_->mocap_quat[4 * mocap_ + 1] = q.x();
  d_->mocap_quat[4 * mocap_ + 2] = q.y();
  d_->mocap_quat[4 * mocap_ + 3] = q.z();
}

void Scene::set_jaw_command(double u) {
  const double torque = -std::clamp(u, -1.0, 1.0) * closing_torque(gripper_);  // a positive angle opens
  d_->ctrl[0] = torque;
  d_->ctrl[1] = torque;
}

double Scene::jaw_angle() const { return 0.5 * (d_->qpos[jaw_qpos_[0]] + d_->qpos[jaw_qpos_[1]]); }

double Scene::opening() const { return opening_at(gripper_, jaw_angle()); }

double Scene::jaw_speed() const {
  return gripper_.jaw_length * std::max(std::abs(d_->qvel[jaw_dof_[0]]), std::abs(d_->qvel[jaw_dof_[1]]));
}

double Scene::arm_load() const { return arm_force().z(); }

Eigen::Vector3d Scene::arm_force() const {
  // Generalised force of the arm's weld on the gripper's translational dofs (the free joint's
  // first three, world axes): the sum of J[row, dof] * force[row] over the weld's rows (dense
  // Jacobian).
  const int dof = m_->jnt_dofadr[m_->body_jntadr[gripper_body_]];
  Eigen::Vector3d f = Eigen::Vector3d::Zero();
  for (int i = 0; i < d_->nefc; ++i) {
    if (d_->efc_type[i] != mjCNSTR_EQUALITY) continue;
    for (int k = 0; k < 3; ++k) f[k] += d_->efc_J[i * m_->nv + dof + k] * d_->efc_force[i];
  }
  f.z() -= gripper_weight_;
  return f;
}

Eigen::Vector3d Scene::arm_moment() const {
  // The free joint's rotational dofs are the body's local axes: the weld's generalised force on
  // them is its moment about the body's origin in the body frame.
  const int dof = m_->jnt_dofadr[m_->body_jntadr[gripper_body_]] + 3;
  Eigen::Vector3d local = Eigen::Vector3d::Zero();
  for (int i = 0; i < d_->nefc; ++i) {
    if (d_->efc_type[i] != mjCNSTR_EQUALITY) continue;
    for (int k = 0; k < 3; ++k) local[k] += d_->efc_J[i * m_->nv + dof + k] * d_->efc_force[i];
  }
  const Eigen::Isometry3d T = gripper_pose();
  const Eigen::Vector3d com(d_->subtree_com[3 * gripper_body_], d_->subtree_com[3 * gripper_body_ + 1],
                            d_->subtree_com[3 * gripper_body_ + 2]);
  return T.linear() * local + (com - T.translation()).cross(Eigen::Vector3d(0, 0, -gripper_weight_));
}

std::vector<Scene::GeomBox> Scene::gripper_boxes() const {
  std::vector<GeomBox> out;
  for (int g = 0; g < m_->ngeom; ++g) {
    const int e = geom_entity_[static_cast<std::size_t>(g)];
    if (!is_gripper(e)) continue;
    GeomBox b{.entity = e};
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) b.pose.linear()(r, c) = d_->geom_xmat[9 * g + 3 * r + c];
      b.pose.translation()[r] = d_->geom_xpos[3 * g + r];
      b.half[r] = m_->geom_size[3 * g + r];
    }
    out.push_back(b);
  }
  return out;
}

std::vector<Contact> Scene::contacts() const {
  std::vector<Contact> out;
  for (int i = 0; i < d_->ncon; ++i) {
    const mjContact& c = d_->contact[i];
    int a = geom_entity_[static_cast<std::size_t>(c.geom1)];
    int b = geom_entity_[static_cast<std::size_t>(c.geom2)];
    if (a == b) continue;
    Vector3d normal(c.frame[0], c.frame[1], c.frame[2]);
    if (a > b) {
      std::swap(a, b);
      normal = -normal;
    }
    std::array<mjtNum, 6> f{};
    mj_contactForce(m_, d_, i, f.data());
    out.push_back({.a = a, .b = b, .depth = -c.dist, .normal_force = f[0], .normal = normal});
  }
  return out;
}

}  // namespace cairn::sim::detail
