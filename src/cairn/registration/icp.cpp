#include "cairn/registration/icp.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>

#include "cairn/core/error.hpp"

namespace cairn {
namespace {

using Mat6 = Eigen::Matrix<double, 6, 6>;
using Vec6 = Eigen::Matrix<double, 6, 1>;

enum class Objective { point_to_point, point_to_plane };
enum class Kernel { none, huber, cauchy, tukey, geman_mcclure };

Objective parse_objective(const std::string& s) {
  if (s == "point_to_plane") return Objective::point_to_plane;
  if (s == "point_to_point") return Objective::point_to_point;
  throw ConfigError("icp.objective: unknown value '" + s + "' (point_to_plane or point_to_point)");
}

Kernel parse_kernel(const std::string& s) {
  if (s == "none") return Kernel::none;
  if (s == "huber") return Kernel::huber;
  if (s == "cauchy") return Kernel::cauchy;
  if (s == "tukey") return Kernel::tukey;
  if (s == "geman_mcclure") return Kernel::geman_mcclure;
  throw ConfigError("icp.kernel: unknown value '" + s + "' (none, huber, cauchy, tukey, geman_mcclure)");
}

/// Robust kernel ρ(r) and its IRLS weight w(r) = ρ'(r) / r, with scale k.
struct RobustKernel {
  Kernel kind;
  double k;

  [[nodiscard]] double weight(double r) const {
    const double a = std::abs(r);
    switch (kind) {
      case Kernel::none: return 1.0;
      case Kernel::huber: return a <= k ? 1.0 : k / a;
      case Kernel::cauchy: return 1.0 / (1.0 + (r / k) * (r / k));
      case Kernel::tukey: {
        if (a >= k) return 0.0;
        const double u = 1.0 - (r / k) * (r / k);
        return u * u;
      }
      case Kernel::geman_mcclure: {
        const double d = k * k + r * r;
        return k * k * k * k / (d * d);
      }
    }
    return 1.0;
  }

  [[nodiscard]] double rho(double r) const {
    const double a = std::abs(r), r2 = r * r, k2 = k * k;
    switch (kind) {
      case Kernel::none: return 0.5 * r2;
      case Kernel::huber: return a <= k ? 0.5 * r2 : k * (a - 0.5 * k);
      case Kernel::cauchy: return 0.5 * k2 * std::log1p(r2 / k2);
      case Kernel::tukey: {
        if (a >= k) return k2 / 6.0;
        const double u = 1.0 - r2 / k2;
        return k2 / 6.0 * (1.0 - u * u * u);
      }
      case Kernel::geman_mcclure: return 0.5 * k2 * r2 / (k2 + r2);
    }
    return 0.5 * r2;
  }
};

/// Sums of one linearisation (Gauss-Newton normal equations + statistics).
struct Linearization {
  Mat6 H = Mat6::Zero();
  Vec6 b = Vec6::Zero();
  double error = 0.0;    // Σ ρ(r)
  double sq_dist = 0.0;  // Σ |p - q|² over inliers
  std::size_t inliers = 0;

  void add(const Linearization& o) {
    H += o.H;
    b += o.b;
    error += o.error;
    sq_dist += o.sq_dist;
    inliers += o.inliers;
  }
};

/// Indices of `pts` sorted along a Morton (Z-order) curve: neighbouring queries then walk the same
/// kd-tree nodes and touch the same cache lines (2–3× faster nearest-neighbour passes on unordered
/// clouds). Ties keep the input order, so the permutation is deterministic.
std::vector<std::uint32_t> morton_order(std::span<const Vec3f> pts) {
  const Aabb box = bounds(pts);
  const float extent = std::max((box.max - box.min).maxCoeff(), 1e-6f);
  const float scale = float((1u << 20) - 1) / extent;
  const auto spread = [](std::uint64_t v) {  // 21 bits → every third bit of 63
    v &= 0x1fffff;
    v = (v | v << 32) & 0x1f00000000ffffull;
    v = (v | v << 16) & 0x1f0000ff0000ffull;
    v = (v | v << 8) & 0x100f00f00f00f00full;
    v = (v | v << 4) & 0x10c30c30c30c30c3ull;
    v = (v | v << 2) & 0x1249249249249249ull;
    return v;
  };
  std::vector<std::pair<std::uint64_t, std::uint32_t>> keyed(pts.size());
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const Eigen::Vector3f q = (pts[i] - box.min) * scale;
    keyed[i] = {spread(std::uint64_t(q.x())) | spread(std::uint64_t(q.y())) << 1 | spread(std::uint64_t(q.z())) << 2,
                std::uint32_t(i)};
  }
  std::sort(keyed.begin(), keyed.end());
  std::vector<std::uint32_t> order(pts.size());
  for (std::size_t i = 0; i < pts.size(); ++i) order[i] = keyed[i].second;
  return order;
}

struct Problem {
  std::span<const Vec3f> source;
  std::span<const std::uint32_t> order;  // visiting order of the source points (Morton)
  const IcpTarget& target;
  Objective objective;
  RobustKernel kernel;
  float max_sq_dist;
};

Eigen::Matrix3d skew(const Vec3d& v) {
  Eigen::Matrix3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

/// Adds the source points [begin, end) transformed by T: nearest target point, residual, Jacobian
/// w.r.t. the left perturbation T ← exp([ω; v]) T, so that ∂(Tp)/∂[ω; v] = [-[Tp]×, I].
void accumulate(const Problem& pb, const Eigen::Isometry3d& T, std::size_t begin, std::size_t end,
                Linearization& out) {
  const auto tgt = pb.target.points();
  const auto normals = pb.target.normals();
  for (std::size_t k = begin; k < end; ++k) {
    const Vec3d p = T * pb.source[pb.order[k]].cast<double>();
    float d2 = 0.0f;
    const std::uint32_t j = pb.target.tree().nearest_within(p.cast<float>(), pb.max_sq_dist, &d2);
    if (!(d2 <= pb.max_sq_dist)) continue;
    const Vec3d diff = p - tgt[j].cast<double>();
    if (pb.objective == Objective::point_to_plane) {
      const Vec3d n = normals[j].cast<double>();
      if (n.squaredNorm() == 0.0) continue;  // target point without a normal
      const double r = n.dot(diff);          // Sec. 4.2 / 4.4: point-to-plane residual nᵀ(Tp − q)
      constexpr int kDof = Vec6::SizeAtCompileTime;  // [ω; v]
      const Vec3d pxn = p.cross(n);
      const double J[kDof] = {pxn.x(), pxn.y(), pxn.z(), n.x(), n.y(), n.z()};
      const double w = pb.kernel.weight(r), wr = w * r;
      // H += (w J) Jᵀ and b += (w r) J entry by entry: the products and sums of Eigen's outer
      // product (byte-identical without FMA contraction), without its temporaries (the
      // sanitizer build's mapping loop).
      for (int row = 0; row < kDof; ++row) {
        const double wJ = w * J[row];
        for (int col = 0; col < kDof; ++col) out.H(row, col) += wJ * J[col];
        out.b[row] += wr * J[row];
      }
      out.error += pb.kernel.rho(r);
    } else {
      const double r = diff.norm();  // point-to-point residual |Tp − q|, weighted on its length
      Eigen::Matrix<double, 3, 6> J;
      J << -skew(p), Eigen::Matrix3d::Identity();
      const double w = pb.kernel.weight(r);
      out.H.noalias() += w * (J.transpose() * J);
      out.b.noalias() += w * (J.transpose() * diff);
      out.error += pb.kernel.rho(r);
    }
    out.sq_dist += diff.squaredNorm();
    ++out.inliers;
  }
}

/// Fixed-size chunks summed in chunk order: the same floating-point sums whether the chunks run
/// serially or on any number of threads, so parallel == serial bit for bit.
constexpr std::size_t kChunk = 512;

Linearization linearize(const Problem& pb, const Eigen::Isometry3d& T, bool parallel) {
  const std::size_t n = pb.source.size();
  const std::size_t chunks = (n + kChunk - 1) / kChunk;
  std::vector<Linearization> partial(chunks);
  const auto run = [&](std::size_t c) { accumulate(pb, T, c * kChunk, std::min(n, (c + 1) * kChunk), partial[c]); };
  if (parallel && chunks > 1) {
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, chunks, 1),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                        for (std::size_t c = r.begin(); c != r.end(); ++c) run(c);
                      });
  } else {
    for (std::size_t c = 0; c < chunks; ++c) run(c);
  }
  Linearization sum;
  for (const auto& p : partial) sum.add(p);
  return sum;
}

/// Solves H ξ = −b for ξ = [ω; v] (6-DoF) or [ω_z; v] (4-DoF, ω_x = ω_y = 0). A tiny relative
/// damping keeps directions the data does not constrain (e.g. sliding along a plane) at zero.
Vec6 solve_increment(const Linearization& lin, bool four_dof) {
  Vec6 xi = Vec6::Zero();
  if (four_dof) {
    constexpr int kSel[4] = {2, 3, 4, 5};
    Eigen::Matrix4d H;
    Eigen::Vector4d b;
    for (int r = 0; r < 4; ++r) {
      b(r) = lin.b(kSel[r]);
      for (int c = 0; c < 4; ++c) H(r, c) = lin.H(kSel[r], kSel[c]);
    }
    H.diagonal().array() += 1e-9 * H.trace() / 4.0;
    const Eigen::Vector4d x = H.ldlt().solve(-b);
    for (int r = 0; r < 4; ++r) xi(kSel[r]) = x(r);
  } else {
    Mat6 H = lin.H;
    H.diagonal().array() += 1e-9 * H.trace() / 6.0;
    xi = H.ldlt().solve(-lin.b);
  }
  return xi;
}

Eigen::Isometry3d exp_update(const Vec6& xi) {
  Eigen::Isometry3d dT = Eigen::Isometry3d::Identity();
  const Vec3d w = xi.head<3>();
  const double angle = w.norm();
  if (angle > 0.0) dT.linear() = Eigen::AngleAxisd(angle, w / angle).toRotationMatrix();
  dT.translation() = xi.tail<3>();
  return dT;
}

void check_finite(std::span<const Vec3f> pts, const char* what) {
  for (std::size_t i = 0; i < pts.size(); ++i)
    if (!pts[i].allFinite())
      throw InputError(std::string("icp: ") + what + " point " + std::to_string(i) + " is not finite");
}

void fill_statistics(IcpResult& res, const Linearization& lin, std::size_t num_source) {
  res.num_inliers = lin.inliers;
  res.rmse = lin.inliers ? std::sqrt(lin.sq_dist / double(lin.inliers)) : 0.0;
  res.fitness = num_source ? double(lin.inliers) / double(num_source) : 0.0;
  res.error = lin.error;
  res.hessian = lin.H;
}

}  // namespace

void IcpConfig::validate() const {
  (void)parse_objective(objective);
  (void)parse_kernel(kernel);
  if (!(kernel_scale > 0.0) || !std::isfinite(kernel_scale))
    throw ConfigError("icp.kernel_scale must be a positive number of metres");
  if (!(max_correspondence_distance > 0.0) || !std::isfinite(max_correspondence_distance))
    throw ConfigError("icp.max_correspondence_distance must be a positive number of metres");
  if (max_iterations < 1) throw ConfigError("icp.max_iterations must be at least 1");
  if (!(translation_tolerance >= 0.0)) throw ConfigError("icp.translation_tolerance must be >= 0");
  if (!(rotation_tolerance >= 0.0)) throw ConfigError("icp.rotation_tolerance must be >= 0");
  if (min_correspondences < 3) throw ConfigError("icp.min_correspondences must be at least 3");
}

const char* to_string(IcpStatus s) {
  switch (s) {
    case IcpStatus::converged: return "converged";
    case IcpStatus::max_iterations: return "max_iterations";
    case IcpStatus::too_few_correspondences: return "too_few_correspondences";
    case IcpStatus::degenerate: return "degenerate";
  }
  return "unknown";
}

// ---- IcpTarget -------------------------------------------------------------------------------

IcpTarget::IcpTarget(std::vector<Vec3f> points) : IcpTarget(std::move(points), std::vector<Vec3f>{}, false) {}

IcpTarget::IcpTarget(std::vector<Vec3f> points, std::vector<Vec3f> normals)
    : IcpTarget(std::move(points), std::move(normals), true) {}

IcpTarget::IcpTarget(std::vector<Vec3f> points, std::vector<Vec3f> normals, bool with_normals) {
  if (points.empty()) throw InputError("icp: the target has no points");
  check_finite(points, "target");
  if (with_normals && normals.size() != points.size())
    throw InputError("icp: the target has " + std::to_string(points.size()) + " points but " +
                     std::to_string(normals.size()) + " normals");
  // Stored in Morton order: the kd-tree's leaves then sit in contiguous memory.
  order_ = morton_order(points);
  points_.resize(points.size());
  for (std::size_t i = 0; i < order_.size(); ++i) points_[i] = points[order_[i]];
  if (with_normals) {
    normals_.resize(points.size());
    for (std::size_t i = 0; i < order_.size(); ++i) {
      const Vec3f& n = normals[order_[i]];
      const float len = n.norm();
      normals_[i] = (std::isfinite(len) && len > 0.0f) ? Vec3f(n / len) : Vec3f::Zero();  // invalid: skipped
    }
  }
  tree_ = std::make_unique<KdTree>(std::span<const Vec3f>(points_));
}

IcpTarget::IcpTarget(std::vector<Vec3f> points, const NormalConfig& normal_config) : IcpTarget(std::move(points)) {
  normals_ = estimate_normals(points_, *tree_, normal_config).normals;
}

IcpTarget IcpTarget::from_cloud(const PointCloud& cloud, const NormalConfig& normal_config) {
  cloud.check_consistent("icp target");
  IcpTarget t = cloud.has_normals() ? IcpTarget(cloud.points, cloud.normals) : IcpTarget(cloud.points, normal_config);
  t.origin_ = cloud.origin;
  return t;
}

// ---- registration ----------------------------------------------------------------------------

IcpResult register_icp(std::span<const Vec3f> source, const IcpTarget& target, const Eigen::Isometry3d& T_init,
                       const IcpConfig& config) {
  config.validate();
  if (source.empty()) throw InputError("icp: the source has no points");
  check_finite(source, "source");
  if (!T_init.matrix().allFinite()) throw InputError("icp: the initial transform is not finite");
  const Objective objective = parse_objective(config.objective);
  if (objective == Objective::point_to_plane && !target.has_normals())
    throw ConfigError("icp.objective: point_to_plane needs a target with normals (build the IcpTarget with "
                      "normals or a NormalConfig), or use point_to_point");

  const std::vector<std::uint32_t> order = morton_order(source);
  const Problem pb{source, order, target, objective, {parse_kernel(config.kernel), config.kernel_scale},
                   float(config.max_correspondence_distance * config.max_correspondence_distance)};
  const auto min_pairs = std::size_t(config.min_correspondences);

  IcpResult res;
  res.T_target_source = T_init;
  for (int it = 0; it < config.max_iterations; ++it) {
    const Linearization lin = linearize(pb, res.T_target_source, config.parallel);
    if (lin.inliers < min_pairs) {
      res.status = IcpStatus::too_few_correspondences;
      fill_statistics(res, lin, source.size());
      return res;
    }
    const Vec6 xi = solve_increment(lin, config.four_dof);  // Gauss-Newton step (IRLS weights)
    if (!xi.allFinite()) {
      res.status = IcpStatus::degenerate;
      fill_statistics(res, lin, source.size());
      return res;
    }
    res.T_target_source = exp_update(xi) * res.T_target_source;
    res.iterations = it + 1;
    if (xi.head<3>().norm() < config.rotation_tolerance && xi.tail<3>().norm() < config.translation_tolerance) {
      res.status = IcpStatus::converged;
      res.converged = true;
      break;
    }
  }
  // Statistics and Hessian at the returned transform (one more correspondence pass).
  const Linearization fin = linearize(pb, res.T_target_source, config.parallel);
  fill_statistics(res, fin, source.size());
  if (fin.inliers < min_pairs) {
    res.status = IcpStatus::too_few_correspondences;
    res.converged = false;
  }
  return res;
}

IcpResult register_icp(const PointCloud& source, const IcpTarget& target, const Eigen::Isometry3d& T_init,
                       const IcpConfig& config) {
  // Local frames: p_world = origin + p. T_local = Trans(−o_t) · T_world · Trans(o_s).
  const Eigen::Translation3d to_src(source.origin), from_tgt(-target.origin());
  const Eigen::Isometry3d T_local = from_tgt * T_init * to_src;
  IcpResult res = register_icp(std::span<const Vec3f>(source.points), target, T_local, config);
  res.T_target_source = Eigen::Translation3d(target.origin()) * res.T_target_source * to_src.inverse();
  return res;
}

IcpResult evaluate_alignment(std::span<const Vec3f> source, const IcpTarget& target,
                             const Eigen::Isometry3d& T_target_source, double max_correspondence_distance) {
  if (source.empty()) throw InputError("icp: the source has no points");
  check_finite(source, "source");
  if (!(max_correspondence_distance > 0.0))
    throw ConfigError("icp: max_correspondence_distance must be a positive number of metres");
  const std::vector<std::uint32_t> order = morton_order(source);
  const Problem pb{source, order, target, Objective::point_to_point, {Kernel::none, 1.0},
                   float(max_correspondence_distance * max_correspondence_distance)};
  IcpResult res;
  res.T_target_source = T_target_source;
  res.status = IcpStatus::converged;
  res.converged = true;
  fill_statistics(res, linearize(pb, T_target_source, true), source.size());
  return res;
}

}  // namespace cairn
