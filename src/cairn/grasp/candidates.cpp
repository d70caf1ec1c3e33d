#include "cairn/grasp/candidates.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <numbers>
#include <numeric>
#include <random>

#include <tbb/parallel_for.h>

#include "cairn/core/kdtree.hpp"
#include "cairn/core/voxel_grid.hpp"
#include "cairn/core/units.hpp"

namespace cairn::grasp {
namespace {

using Eigen::Isometry3d;
using Eigen::Matrix3d;
using Eigen::Vector3d;
constexpr double kInf = std::numeric_limits<double>::infinity();
/// [m] A box's shadow is grown by this before it rejects a point: far above the rounding of the
/// exact slab test, far below any length of the gripper or the cloud.
constexpr double kShadowTolerance = 1e-6;
/// Spheres that cover a closing region for the kd-tree (3 holds the least volume for the default
/// gripper's 1.0 x 2.8 x 0.5 m region: 3 x 1.7 m^3 against 14 m^3 for one sphere).
constexpr int kClosingSpheres = 3;
/// [m] The closing's bisection stops when the jaw tips' contact is known to this (0.05 mm: far
/// below any voxel; at most 15 steps for the default jaws, where 24 gave 1e-7 m).
constexpr double kTipTolerance = 5e-5;
/// [m] Each of those spheres is grown by this (the float rounding of the kd-tree's distances is ~1e-6 m).
constexpr double kSphereTolerance = 1e-4;

Matrix3d axis_rotation(const Vector3d& axis, double deg) { return Eigen::AngleAxisd(deg * kDeg, axis).toRotationMatrix(); }

/// Entry and exit advance of a point through one box (empty when in > out).
std::pair<double, double> sweep_interval(const SweptBox& b, const Vector3d& q) {
  const Vector3d u = b.axes.transpose() * (q - b.center);
  double lo = -kInf, hi = kInf;
  for (int i = 0; i < 3; ++i) {
    if (std::abs(b.dir[i]) < 1e-12) {
      if (std::abs(u[i]) > b.half[i]) return {kInf, -kInf};
      continue;
    }
    double t1 = (-b.half[i] - u[i]) / b.dir[i], t2 = (b.half[i] - u[i]) / b.dir[i];
    if (t1 > t2) std::swap(t1, t2);
    lo = std::max(lo, t1);
    hi = std::min(hi, t2);
    if (lo > hi) return {kInf, -kInf};
  }
  return {lo, hi};
}

/// Largest |y| and |z| of the gripper's vertices in G.
Eigen::Vector2d lateral_extent(const std::vector<ConvexPart>& parts) {
  Eigen::Vector2d e = Eigen::Vector2d::Zero();
  for (const ConvexPart& p : parts)
    for (const Vector3d& v : p.vertices) e = e.cwiseMax(Eigen::Vector2d(std::abs(v.y()), std::abs(v.z())));
  return e;
}

/// Largest distance of a gripper vertex from the origin of G.
double part_reach(const std::vector<ConvexPart>& parts) {
  double r = 0.0;
  for (const ConvexPart& p : parts)
    for (const Vector3d& v : p.vertices) r = std::max(r, v.norm());
  return r;
}

std::vector<std::uint32_t> choose_samples(const PointCloud& cloud, int n, unsigned seed) {
  std::vector<std::uint32_t> object;
  for (std::size_t i = 0; i < cloud.size(); ++i)
    if (cloud.labels[i] == kObject) object.push_back(std::uint32_t(i));
  std::mt19937 rng(seed);
  std::shuffle(object.begin(), object.end(), rng);
  if (object.size() > std::size_t(n)) object.resize(std::size_t(n));
  return object;
}

/// The object's highest point within `radius` of the vertical line through `centre` (the top
/// above the centre of mass), or the object point closest to that line.
std::optional<std::uint32_t> top_above(const PointCloud& cloud, const Vector3d& centre, const Vector3d& up, double radius) {
  std::optional<std::uint32_t> best, nearest;
  double best_h = -kInf, nearest_d = kInf;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    if (cloud.labels[i] != kObject) continue;
    const Vector3d d = cloud.points[i].cast<double>() - centre;
    const double lateral = (d - d.dot(up) * up).norm(), h = d.dot(up);
    if (lateral < nearest_d) nearest_d = lateral, nearest = std::uint32_t(i);
    if (lateral <= radius && h > best_h) best_h = h, best = std::uint32_t(i);
  }
  return best ? best : nearest;
}

/// Beyond the paper: the approach along -up, closing along `minor` turned about it by each yaw.
std::vector<Matrix3d> vertical_orientations(const Vector3d& up, const Vector3d& minor, const CandidateConfig& c) {
  Matrix3d G;
  G.col(0) = -up;
  G.col(1) = minor;
  G.col(2) = G.col(0).cross(G.col(1));
  std::vector<Matrix3d> out;
  for (const double yaw : c.vertical_yaws_deg) out.push_back(G * axis_rotation(Vector3d::UnitX(), yaw));
  return out;
}

/// The rotated gripper orientations of one sample (Sec. 5.3): G's x = -x_F (towards the
/// object), y = y_F, z = -z_F, then rotated about y, z and x in the configured steps.
std::vector<Matrix3d> orientations(const Matrix3d& F, const CandidateConfig& c) {
  Matrix3d G;
  G << -F.col(0), F.col(1), -F.col(2);
  std::vector<Matrix3d> out;
  for (const double b : c.rotations_y_deg)
    for (const double a : c.rotations_z_deg)
      for (const double g : c.rotations_x_deg)
        out.push_back(G * axis_rotation(Vector3d::UnitY(), b) * axis_rotation(Vector3d::UnitZ(), a) *
                      axis_rotation(Vector3d::UnitX(), g));
  return out;
}

struct SampleContext {
  const PlanningCloud& pc;
  const GripperConfig& gripper;
  const GraspConfig& config;
  const KdTree& tree;               // over pc.cloud.points
  const std::vector<Vec3f>& coarse;  // the collision cloud (collision_voxels)
  const std::vector<std::int32_t>& coarse_labels;
  const KdTree& coarse_tree;
  std::vector<Matrix3d> vertical;  // the vertical orientations (the same for every sample)
};

/// The collision points around one sample (relative to it, coordinate by coordinate) and the
/// fixed settings of its poses.
struct SampleNeighbourhood {
  Vector3d p;                        // the sample point
  std::vector<float> ax, ay, az;     // collision points relative to p
  std::vector<bool> object;          // ... which lie on the object
  double start = 0.0;                // the push starts with the palm this far before p
  float slab = 0.0f;                 // |z| of the points any pose looks at (gripper height, padded)
};

/// The neighbourhood's points along the axes of one orientation (R^T d, d relative to the sample)
/// within a slab |z| <= the gripper's height (padded) about the approach: the points its fitted
/// opening and its push look at, computed once per orientation.
struct RotatedNeighbourhood {
  std::vector<float> x, y, z;
  std::vector<bool> object;
  std::vector<float> all_z;  // scratch: z of every point
};

void rotate(const SampleNeighbourhood& n, const Eigen::Matrix3f& Rt, float slab, RotatedNeighbourhood& out) {
  const std::size_t size = n.ax.size();
  // Rt.row(r).dot(d) as Eigen 3.4 sums a fixed 3-vector: a dx + (b dy + c dz).
  const auto along = [&](int r, std::size_t k) { return Rt(r, 0) * n.ax[k] + (Rt(r, 1) * n.ay[k] + Rt(r, 2) * n.az[k]); };
  out.all_z.resize(size);
  for (std::size_t k = 0; k < size; ++k) out.all_z[k] = along(2, k);  // vectorised; most points leave here
  out.x.clear();
  out.y.clear();
  out.z.clear();
  out.object.clear();
  for (std::size_t k = 0; k < size; ++k) {
    if (std::abs(out.all_z[k]) > slab) continue;
    out.x.push_back(along(0, k));
    out.y.push_back(along(1, k));
    out.z.push_back(out.all_z[k]);
    out.object.push_back(n.object[k]);
  }
}

/// The opening that clears the object's points in the jaws' band (|z| <= jaw height / 2) across
/// the approach axis by the padding on both sides (GPD's hand is fixed; an angular gripper's
/// pre-grasp opening is free).
double fitted_opening(const RotatedNeighbourhood& r, const GripperConfig& g, double padding) {
  float half = 0.0f;
  const float band = float(0.5 * g.jaw_height);
  for (std::size_t k = 0; k < r.z.size(); ++k) {
    if (!r.object[k] || std::abs(r.z[k]) > band) continue;
    half = std::max(half, std::abs(r.y[k]));
  }
  return std::clamp(2.0 * (double(half) + padding), opening_at(g, min_jaw_angle(g)), max_opening(g));
}

/// The closing of one pushed pose T on the full-resolution cloud; where the closing jaws would
/// sweep into the environment (the tips into the ground under a low stone), the gripper backs
/// off along the approach and closes again, never more than `pushed` (the advance from the push's
/// start: the way back was checked by it).
void close_with_backoff(const SampleContext& ctx, const Isometry3d& T, double opening,
                        double pushed, std::vector<Candidate>& out, CandidateCounts& counts) {
  const CandidateConfig& cc = ctx.config.candidates;
  const double voxel = ctx.config.cloud.voxel, clearance = cc.tip_clearance_voxels * voxel;
  const double open_angle = jaw_angle_for(ctx.gripper, opening);
  const JawLines open = jaw_lines(ctx.gripper, open_angle);
  bool hypothesis = false;
  for (const double back : cc.backoff_voxels) {
    if (back * voxel > pushed) break;
    Isometry3d Tb = T;
    Tb.translation() -= back * voxel * T.linear().col(0);
    LocalPoints local;
    gather_local(ctx.pc.cloud, ctx.tree, Tb, opening, ctx.gripper, local, clearance);
    const auto in_region = std::count_if(local.object.begin(), local.object.end(),
                                         [&](const Vector3d& q) { return open.encloses(q); });
    if (std::size_t(in_region) < cc.min_object_points) break;
    hypothesis = true;
    Closing closing = close_jaws(ctx.gripper, open_angle, local.object, local.normals, local.environment,
                                 ctx.config.force_closure.patch_voxels * voxel, clearance);
    if (closing.failure == "collision_close") continue;
    if (closing.closed) {
      ++counts.collision_free;
      out.push_back({.T = Tb, .opening = opening, .closing = std::move(closing)});
    }
    break;
  }
  counts.hypotheses += hypothesis ? 1 : 0;
}

/// The collision points of one sample in G at the push's start for one orientation (rotated:
/// the neighbourhood along its axes), those beside `lateral` (|y|, |z|) dropped: they can never
/// be touched.
std::vector<Vector3d> start_points(const SampleNeighbourhood& n, const RotatedNeighbourhood& r,
                                   const Eigen::Vector2d& lateral) {
  assert(float(lateral.y()) <= n.slab);
  const float x0 = float(n.start), y_max = float(lateral.x()), z_max = float(lateral.y());
  std::vector<Vector3d> out;
  for (std::size_t k = 0; k < r.z.size(); ++k) {
    if (std::abs(r.z[k]) > z_max || std::abs(r.y[k]) > y_max) continue;
    out.emplace_back(double(r.x[k] + x0), double(r.y[k]), double(r.z[k]));
  }
  return out;
}

/// One orientation at one pre-grasp opening (`parts`: the gripper at it): pushed, then closed
/// (Sec. 5.3). `start_G`: the orientation's start_points for a lateral extent at least this
/// opening's.
void try_pose(const SampleContext& ctx, const SampleNeighbourhood& n, const Matrix3d& R, double opening,
              const std::vector<ConvexPart>& parts, std::span<const Vector3d> start_G, std::vector<Candidate>& out,
              CandidateCounts& counts) {
  const CandidateConfig& cc = ctx.config.candidates;
  const double voxel = ctx.config.cloud.voxel, padding = cc.padding_voxels * voxel;
  const std::vector<SweptBox> boxes = swept_boxes(parts, padding);
  const Eigen::Vector2d lateral = lateral_extent(parts) + Eigen::Vector2d::Constant(padding);
  ++counts.poses;
  const Vector3d o_start = n.p - n.start * R.col(0);
  // The same points (and order) start_points would give for this opening's lateral extent.
  const float y_max = float(lateral.x()), z_max = float(lateral.y());
  std::vector<Vector3d> mine;
  mine.reserve(start_G.size());
  for (const Vector3d& q : start_G)
    if (std::abs(float(q.y())) <= y_max && std::abs(float(q.z())) <= z_max) mine.push_back(q);
  const std::optional<double> s = advance_to_contact(boxes, mine);
  if (!s || !std::isfinite(*s)) return;  // collision at the start, or nothing touched
  Isometry3d T = Isometry3d::Identity();
  T.linear() = R;
  T.translation() = o_start + (*s - cc.clearance_voxels * voxel) * R.col(0);
  close_with_backoff(ctx, T, opening, *s - cc.clearance_voxels * voxel, out, counts);
}

/// Candidates of one sample point: every orientation at every configured opening (and the
/// fitted one).
void sample_candidates(const SampleContext& ctx, std::uint32_t sample, std::vector<Candidate>& out,
                       CandidateCounts& counts) {
  const PointCloud& cloud = ctx.pc.cloud;
  const CandidateConfig& cc = ctx.config.candidates;
  const double voxel = ctx.config.cloud.voxel, padding = cc.padding_voxels * voxel;
  Neighbors nb;
  ctx.tree.radius(cloud.points[sample], float(cc.lrf_radius_voxels * voxel), nb);
  std::vector<Vec3f> normals;
  for (const std::uint32_t j : nb.indices)
    if (cloud.labels[j] == kObject) normals.push_back(cloud.normals[j]);
  const Matrix3d F = local_reference_frame(normals, cloud.normals[sample].cast<double>());
  // The jaws turn about z_G: the gripper's height is the same at every opening.
  const double height = std::max({0.5 * ctx.gripper.jaw_height,
                                  lateral_extent(gripper_parts(ctx.gripper, max_opening(ctx.gripper))).y(),
                                  lateral_extent(gripper_parts(ctx.gripper, opening_at(ctx.gripper, min_jaw_angle(ctx.gripper)))).y()});
  SampleNeighbourhood n{.p = cloud.points[sample].cast<double>(),
                        .start = ctx.gripper.jaw_length + cc.start_margin_voxels * cc.collision_voxels * voxel,
                        .slab = float(height + padding)};
  const double reach = part_reach(gripper_parts(ctx.gripper, max_opening(ctx.gripper)));  // the widest
  ctx.coarse_tree.radius(cloud.points[sample], float(n.start + reach + 2.0 * padding), nb);
  for (const std::uint32_t i : nb.indices) {
    const Vec3f d = ctx.coarse[i] - cloud.points[sample];
    n.ax.push_back(d.x());
    n.ay.push_back(d.y());
    n.az.push_back(d.z());
    n.object.push_back(ctx.coarse_labels[i] == kObject);
  }
  std::vector<Matrix3d> rotations = orientations(F, cc);
  rotations.insert(rotations.end(), ctx.vertical.begin(), ctx.vertical.end());
  RotatedNeighbourhood rotated;
  for (const Matrix3d& R : rotations) {
    rotate(n, R.transpose().cast<float>(), n.slab, rotated);
    std::vector<double> openings;
    for (const double share : cc.openings) openings.push_back(share * max_opening(ctx.gripper));
    if (cc.fit_opening) openings.push_back(fitted_opening(rotated, ctx.gripper, padding));
    std::vector<std::vector<ConvexPart>> parts;  // the gripper at each opening
    Eigen::Vector2d widest = Eigen::Vector2d::Zero();
    for (const double o : openings) {
      parts.push_back(gripper_parts(ctx.gripper, o));
      widest = widest.cwiseMax(lateral_extent(parts.back()));
    }
    const std::vector<Vector3d> start_G = start_points(n, rotated, widest + Eigen::Vector2d::Constant(padding));
    for (std::size_t i = 0; i < openings.size(); ++i) try_pose(ctx, n, R, openings[i], parts[i], start_G, out, counts);
  }
}

}  // namespace

Vector3d minor_horizontal_axis(const PointCloud& cloud, const Vector3d& up) {
  const Vector3d u = up.unitOrthogonal(), v = up.cross(u);
  Eigen::Matrix2d C = Eigen::Matrix2d::Zero();
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  std::size_t n = 0;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    if (cloud.labels[i] != kObject) continue;
    const Vector3d p = cloud.points[i].cast<double>();
    const Eigen::Vector2d q(p.dot(u), p.dot(v));
    mean += q, C += q * q.transpose(), ++n;
  }
  if (n < 2) return u;
  mean /= double(n);
  C = C / double(n) - mean * mean.transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(C);
  const Eigen::Vector2d a = es.eigenvectors().col(0);  // smallest eigenvalue
  return (a.x() * u + a.y() * v).normalized();
}

Matrix3d local_reference_frame(std::span<const Vec3f> normals, const Vector3d& normal) {
  Matrix3d M = Matrix3d::Zero();
  for (const Vec3f& n : normals) M += n.cast<double>() * n.cast<double>().transpose();
  const Eigen::SelfAdjointEigenSolver<Matrix3d> es(M);
  Vector3d x = es.eigenvectors().col(2), z = es.eigenvectors().col(0);
  if (normals.empty() || normal.squaredNorm() < 0.5) {  // no normals around: the given one
    x = normal.squaredNorm() > 0 ? normal.normalized() : Vector3d::UnitZ();
    z = x.unitOrthogonal();
  }
  if (x.dot(normal) < 0) x = -x;
  Vector3d y = z.cross(x).normalized();
  z = x.cross(y);
  Matrix3d F;
  F << x, y, z;
  return F;
}

Vector3d closing_centre(const GripperConfig& g, const Isometry3d& T) { return T * Vector3d(0.5 * g.jaw_length, 0.0, 0.0); }

double closing_lateral(const GripperConfig& g, double opening) {
  // Jaws turned inwards (an opening below the pivots' spacing) still span the pivots at their roots.
  return 0.5 * g.hinge_spacing + g.jaw_length * std::max(0.0, std::sin(jaw_angle_for(g, opening))) + g.jaw_thickness;
}

double closing_reach(const GripperConfig& g, double opening) {
  const double lateral = closing_lateral(g, opening);
  return std::sqrt(0.25 * g.jaw_length * g.jaw_length + lateral * lateral + 0.25 * g.jaw_height * g.jaw_height);
}

std::vector<SweptBox> swept_boxes(const std::vector<ConvexPart>& parts, double padding) {
  std::vector<SweptBox> out;
  for (const ConvexPart& p : parts) {
    SweptBox b{.center = p.center, .half = p.half_extents + (p.axes.transpose() * Vector3d(0.0, padding, padding)).cwiseAbs(),
               .axes = p.axes, .dir = -p.axes.transpose().col(0), .shadow = Eigen::Vector2d::Zero()};
    const Vector3d extent = p.axes.cwiseAbs() * b.half;  // the box's half extents along G's axes
    b.shadow = extent.tail<2>() + Eigen::Vector2d::Constant(kShadowTolerance);
    out.push_back(b);
  }
  return out;
}

std::optional<double> advance_to_contact(const std::vector<SweptBox>& boxes, std::span<const Vector3d> points_G) {
  double first = kInf;
  for (const Vector3d& q : points_G) {
    for (const SweptBox& b : boxes) {
      if (std::abs(q.y() - b.center.y()) > b.shadow.x() || std::abs(q.z() - b.center.z()) > b.shadow.y()) continue;
      const auto [in, out] = sweep_interval(b, q);
      if (in > out || out < 0.0) continue;  // never touched, or behind the start
      if (in <= 0.0) return std::nullopt;   // inside at the start
      first = std::min(first, in);
    }
  }
  return first;
}

namespace {

/// gather_local, one point at a time (the frame's transforms prepared once): a point of the
/// closing region is kept when its y in G falls into [lo, hi) (the segment one sphere covers).
class LocalGatherer {
 public:
  LocalGatherer(const PointCloud& cloud, const Isometry3d& T, const GripperConfig& g, double opening, LocalPoints& out,
                double clearance)
      : cloud_(cloud), g_(g), out_(out), clearance_(clearance), Rt_(T.linear().transpose()), Rf_(Rt_.cast<float>()),
        o_(T.translation().cast<float>()), half_(float(0.5 * g.jaw_height)), lateral_(closing_lateral(g, opening)) {
    out.object.clear();
    out.normals.clear();
    out.environment.clear();
  }
  [[nodiscard]] double lateral() const { return lateral_; }
  void operator()(std::uint32_t i, double lo = -kInf, double hi = kInf) const {
    const Vec3f d = cloud_.points[i] - o_;
    if (std::abs(Rf_.row(2).dot(d)) > half_) return;  // cheap rejection first
    const Vector3d q = (Rf_ * d).cast<double>();
    if (std::abs(q.y()) > lateral_ || q.y() < lo || q.y() >= hi) return;
    const bool object = cloud_.labels[i] == kObject;
    if (q.x() <= 0.0 || q.x() > g_.jaw_length + (object ? 0.0 : clearance_)) return;
    if (object) {
      out_.object.push_back(q);
      out_.normals.push_back(Rt_ * cloud_.normals[i].cast<double>());
    } else {
      out_.environment.push_back(q);
    }
  }

 private:
  const PointCloud& cloud_;
  const GripperConfig& g_;
  LocalPoints& out_;
  double clearance_;
  Matrix3d Rt_;
  Eigen::Matrix3f Rf_;
  Vec3f o_;
  float half_;
  double lateral_;
};

}  // namespace

void gather_local(const PointCloud& cloud, std::span<const std::uint32_t> indices, const Isometry3d& T, double opening,
                  const GripperConfig& g, LocalPoints& out, double clearance) {
  const LocalGatherer gather(cloud, T, g, opening, out, clearance);
  for (const std::uint32_t i : indices) gather(i);
}

void gather_local(const PointCloud& cloud, const KdTree& tree, const Isometry3d& T, double opening,
                  const GripperConfig& g, LocalPoints& out, double clearance) {
  const LocalGatherer gather(cloud, T, g, opening, out, clearance);
  // The region is a slab (jaw height) ~3x wider than deep: spheres along y, one per segment of
  // y, hold ~1/3 of the one sphere around it; each takes only its segment's points.
  const double depth = g.jaw_length + clearance, lateral = gather.lateral();
  const double h = lateral / double(kClosingSpheres);  // half a segment
  const double r = std::sqrt(0.25 * depth * depth + 0.25 * g.jaw_height * g.jaw_height + h * h) + kSphereTolerance;
  const auto edge = [&](int k) { return -lateral + double(2 * k) * h; };  // one value per shared edge
  for (int k = 0; k < kClosingSpheres; ++k) {
    const double y = -lateral + double(2 * k + 1) * h;
    const double lo = k == 0 ? -kInf : edge(k), hi = k + 1 == kClosingSpheres ? kInf : edge(k + 1);
    tree.for_each_in_radius((T * Vector3d(0.5 * depth, y, 0.0)).cast<float>(), float(r),
                            [&](std::uint32_t i, float) { gather(i, lo, hi); });
  }
}

namespace {


/// The object points between the open jaws, as contiguous coordinates (the closing's bisection
/// runs over them a few dozen times).
struct RelevantPoints {
  std::vector<std::size_t> index;  // into the object's points
  std::vector<double> x, y;
};

/// The shifts of the object along y that keep it off each jaw at `angle`: [dL, dR].
std::pair<double, double> shift_bounds(const JawLines& j, const RelevantPoints& rel) {
  // Four independent running bounds (max and min are exact in any order): the bisection of
  // close_jaws calls this ~26 times per closing.
  constexpr std::size_t kLanes = 4;
  std::array<double, kLanes> dL, dR;
  dL.fill(-kInf);
  dR.fill(kInf);
  const std::size_t n = rel.x.size();
  for (std::size_t k = 0; k < n; ++k) {
    const double x = rel.x[k], y = rel.y[k];
    const std::size_t lane = k % kLanes;
    const double l = j.left(x) - y, r = j.right(x) - y;
    const bool in = x <= j.reach;
    dL[lane] = in && l > dL[lane] ? l : dL[lane];
    dR[lane] = in && r < dR[lane] ? r : dR[lane];
  }
  return {std::max({dL[0], dL[1], dL[2], dL[3]}), std::min({dR[0], dR[1], dR[2], dR[3]})};
}

/// Does a jaw sweep through (or within `clearance` of) a non-object point between the two angles?
bool sweeps_environment(const GripperConfig& g, std::span<const Vector3d> env, double from, double to,
                        double clearance) {
  const double h = 0.5 * g.hinge_spacing;
  for (const Vector3d& q : env) {
    for (const double side : {-1.0, 1.0}) {
      const double dy = side * (q.y() - side * h);  // outwards from the hinge
      const double r = std::hypot(q.x(), dy);
      if (r > g.jaw_length + clearance) continue;
      const double phi = std::atan2(dy, q.x());
      if (phi >= to - clearance / std::max(r, clearance) && phi <= from) return true;
    }
  }
  return false;
}

/// The contact patch of one jaw: its centre and the jaw's force direction (the jaw face's
/// normal, or the object's where the jaw touches with its tip edge).
void contact_patch(const JawLines& j, std::span<const Vector3d> obj, std::span<const Vector3d> normals,
                   std::span<const std::size_t> rel, double angle, double bound, double patch, int side,
                   Closing& c) {
  Vector3d sum = Vector3d::Zero(), n_sum = Vector3d::Zero();
  int count = 0;
  const double reach = j.reach;
  for (const std::size_t i : rel) {
    const Vector3d& q = obj[i];
    if (q.x() > reach) continue;
    const bool touches = side < 0 ? j.left(q.x()) - q.y() >= bound - patch
                                  : j.right(q.x()) - q.y() <= bound + patch;
    if (!touches) continue;
    sum += q;
    n_sum += normals[i];
    ++count;
  }
  const std::size_t k = side < 0 ? 0 : 1;
  c.contacts[k] = sum / std::max(count, 1);
  c.patch_points[k] = count;
  c.normals[k] = n_sum.norm() > 0.0 ? Vector3d(n_sum.normalized()) : Vector3d::Zero();
  c.forces[k] = Vector3d(std::sin(angle), side < 0 ? std::cos(angle) : -std::cos(angle), 0.0);
  // The tip edge on a face of the object: the object goes on beyond the tip where a longer jaw
  // would cut into it; the contact normal is then the object's.
  bool tip = false;
  for (const Vector3d& q : obj) {
    if (q.x() <= reach || q.x() > reach + 2.0 * patch || std::abs(q.z()) > 0.5 * j.height) continue;
    tip = tip || (side < 0 ? j.left(q.x()) - q.y() > bound : j.right(q.x()) - q.y() < bound);
  }
  if (tip && n_sum.norm() > 0.5 * count) c.forces[k] = -n_sum.normalized();
}

}  // namespace

Closing close_jaws(const GripperConfig& g, double open_angle, std::span<const Vector3d> obj,
                   std::span<const Vector3d> normals, std::span<const Vector3d> env, double patch, double clearance) {
  const JawLines open = jaw_lines(g, open_angle);
  Closing c;
  RelevantPoints rel;
  for (std::size_t i = 0; i < obj.size(); ++i) {
    const Vector3d& q = obj[i];
    if (q.x() > 0 && q.x() <= g.jaw_length && q.y() > open.left(q.x()) && q.y() < open.right(q.x())) {
      rel.index.push_back(i);
      rel.x.push_back(q.x());
      rel.y.push_back(q.y());
    }
  }
  const double closed = min_jaw_angle(g);
  auto feasible = [&](double a) {
    const auto [dL, dR] = shift_bounds(jaw_lines(g, a), rel);
    return dL <= dR;
  };
  if (rel.index.empty() || feasible(closed)) {
    c.failure = "empty";
    return c;
  }
  double lo = closed, hi = open_angle;  // infeasible at lo, feasible at hi
  while ((hi - lo) * g.jaw_length > kTipTolerance) {
    const double mid = 0.5 * (lo + hi);
    (feasible(mid) ? hi : lo) = mid;
  }
  c.angle = hi;
  if (sweeps_environment(g, env, open_angle, c.angle, clearance)) {
    c.failure = "collision_close";
    return c;
  }
  const JawLines at = jaw_lines(g, c.angle);
  const auto [dL, dR] = shift_bounds(at, rel);
  c.shift = 0.5 * (dL + dR);
  contact_patch(at, obj, normals, rel.index, c.angle, dL, patch, -1, c);
  contact_patch(at, obj, normals, rel.index, c.angle, dR, patch, +1, c);
  c.closed = c.patch_points[0] > 0 && c.patch_points[1] > 0;
  if (!c.closed) c.failure = "empty";
  return c;
}

std::vector<Candidate> generate_candidates(const PlanningCloud& pc, const KdTree& tree, const GripperConfig& gripper,
                                           const GraspConfig& config, CandidateCounts& counts) {
  PointCloud labelled;
  labelled.points = pc.cloud.points;
  labelled.labels = pc.cloud.labels;
  const PointCloud coarse = voxel_downsample(labelled, {.res_voxel = config.candidates.collision_voxels * config.cloud.voxel});
  const KdTree coarse_tree(coarse.points);
  std::vector<std::uint32_t> samples = choose_samples(pc.cloud, config.candidates.samples, config.candidates.seed);
  SampleContext ctx{.pc = pc, .gripper = gripper, .config = config, .tree = tree, .coarse = coarse.points,
                    .coarse_labels = coarse.labels, .coarse_tree = coarse_tree, .vertical = {}};
  if (!config.candidates.vertical_yaws_deg.empty()) {
    const Vector3d up = pc.ground_normal.normalized();
    ctx.vertical = vertical_orientations(up, minor_horizontal_axis(pc.cloud, up), config.candidates);
    const Vector3d mass = pc.mass_centroid - pc.cloud.origin;
    const std::optional<std::uint32_t> top = top_above(pc.cloud, mass, up, config.cloud.voxel);
    if (top && std::find(samples.begin(), samples.end(), *top) == samples.end()) samples.push_back(*top);
  }
  std::vector<std::vector<Candidate>> per(samples.size());
  std::vector<CandidateCounts> per_counts(per.size());
  tbb::parallel_for(std::size_t{0}, per.size(),
                    [&](std::size_t k) { sample_candidates(ctx, samples[k], per[k], per_counts[k]); });
  std::vector<Candidate> out;
  counts = {.samples = samples.size()};
  for (std::size_t k = 0; k < per.size(); ++k) {
    counts.poses += per_counts[k].poses;
    counts.hypotheses += per_counts[k].hypotheses;
    counts.collision_free += per_counts[k].collision_free;
    for (Candidate& c : per[k]) out.push_back(std::move(c));
  }
  return out;
}

}  // namespace cairn::grasp
