#include "cairn/mapping/pose_graph.hpp"

#include <ceres/ceres.h>

#include <algorithm>
#include <memory>
#include <string>

#include "cairn/core/error.hpp"

namespace cairn {
namespace {

template <class T>
using Vec3 = Eigen::Matrix<T, 3, 1>;

Eigen::Matrix<double, 6, 6> sqrt_information(const Matrix6d& information) {
  // Ω = L Lᵀ  →  eᵀ Ω e = |Lᵀ e|²  (LDLT tolerates semidefinite Ω).
  const Eigen::SelfAdjointEigenSolver<Matrix6d> es(0.5 * (information + information.transpose()));
  const Eigen::Matrix<double, 6, 1> s = es.eigenvalues().cwiseMax(0.0).cwiseSqrt();
  return s.asDiagonal() * es.eigenvectors().transpose();
}

struct RelativeCost {
  Eigen::Quaterniond q_z_inv;
  Eigen::Vector3d t_z;
  Matrix6d sqrt_info;
  template <class T>
  bool operator()(const T* qi, const T* ti, const T* qj, const T* tj, T* r) const {
    const Eigen::Map<const Eigen::Quaternion<T>> Qi(qi), Qj(qj);
    const Eigen::Map<const Vec3<T>> Ti(ti), Tj(tj);
    const Eigen::Quaternion<T> qi_inv = Qi.conjugate();
    const Eigen::Quaternion<T> qzi = q_z_inv.cast<T>();
    const Eigen::Quaternion<T> q_e = qzi * (qi_inv * Qj);
    const Vec3<T> t_e = qzi * (qi_inv * (Tj - Ti) - t_z.cast<T>());
    Eigen::Matrix<T, 6, 1> e;
    const T sign = q_e.w() < T(0) ? T(-2) : T(2);
    e << sign * q_e.x(), sign * q_e.y(), sign * q_e.z(), t_e;
    Eigen::Map<Eigen::Matrix<T, 6, 1>> out(r);
    out = sqrt_info.cast<T>() * e;
    return true;
  }
};

struct PriorCost {
  Eigen::Quaterniond q_z_inv;
  Eigen::Vector3d t_z;
  Matrix6d sqrt_info;
  template <class T>
  bool operator()(const T* q, const T* t, T* r) const {
    const Eigen::Map<const Eigen::Quaternion<T>> Q(q);
    const Eigen::Map<const Vec3<T>> Tt(t);
    const Eigen::Quaternion<T> q_e = Q * q_z_inv.cast<T>();
    Eigen::Matrix<T, 6, 1> e;
    const T sign = q_e.w() < T(0) ? T(-2) : T(2);
    e << sign * q_e.x(), sign * q_e.y(), sign * q_e.z(), Tt - t_z.cast<T>();
    Eigen::Map<Eigen::Matrix<T, 6, 1>> out(r);
    out = sqrt_info.cast<T>() * e;
    return true;
  }
};

void check_information(const Matrix6d& information, const std::string& what) {
  if (!information.allFinite()) throw InputError("pose graph: non-finite information matrix (" + what + ")");
}

ceres::CostFunction* make_cost(const PoseGraphEdge& e) {
  const Eigen::Quaterniond q_z(e.z.linear());
  if (e.kind == EdgeKind::prior)
    return new ceres::AutoDiffCostFunction<PriorCost, 6, 4, 3>(
        new PriorCost{q_z.conjugate(), e.z.translation(), sqrt_information(e.information)});
  return new ceres::AutoDiffCostFunction<RelativeCost, 6, 4, 3, 4, 3>(
      new RelativeCost{q_z.conjugate(), e.z.translation(), sqrt_information(e.information)});
}

}  // namespace

Matrix6d adjoint(const Eigen::Isometry3d& T) {
  const Eigen::Matrix3d R = T.linear();
  const Eigen::Vector3d t = T.translation();
  Eigen::Matrix3d t_hat;
  t_hat << 0, -t.z(), t.y(), t.z(), 0, -t.x(), -t.y(), t.x(), 0;
  Matrix6d A = Matrix6d::Zero();
  A.topLeftCorner<3, 3>() = R;
  A.bottomLeftCorner<3, 3>() = t_hat * R;
  A.bottomRightCorner<3, 3>() = R;
  return A;
}

Matrix6d diagonal_information(const Eigen::Vector3d& sigma_rotation, const Eigen::Vector3d& sigma_translation) {
  Eigen::Matrix<double, 6, 1> d;
  d << sigma_rotation.cwiseAbs2().cwiseInverse(), sigma_translation.cwiseAbs2().cwiseInverse();
  return d.asDiagonal();
}

Matrix6d cap_information(const Matrix6d& information, double min_sigma_rotation, double min_sigma_translation) {
  const Eigen::SelfAdjointEigenSolver<Matrix6d> es(0.5 * (information + information.transpose()));
  Eigen::Matrix<double, 6, 1> lambda = es.eigenvalues();
  for (int k = 0; k < 6; ++k) {
    const Eigen::Matrix<double, 6, 1> v = es.eigenvectors().col(k);
    const double var = v.head<3>().squaredNorm() * min_sigma_rotation * min_sigma_rotation +
                       v.tail<3>().squaredNorm() * min_sigma_translation * min_sigma_translation;
    lambda[k] = std::clamp(lambda[k], 0.0, 1.0 / var);
  }
  return es.eigenvectors() * lambda.asDiagonal() * es.eigenvectors().transpose();
}

int PoseGraph::add_node(const Eigen::Isometry3d& T) {
  if (!T.matrix().allFinite()) throw InputError("pose graph: non-finite node pose");
  const Eigen::Quaterniond q(T.linear());
  q_.push_back(q.normalized().coeffs());
  t_.push_back(T.translation());
  return num_nodes() - 1;
}

void PoseGraph::add_relative(EdgeKind kind, int i, int j, const Eigen::Isometry3d& z, const Matrix6d& information) {
  if (i < 0 || j < 0 || i >= num_nodes() || j >= num_nodes() || i == j)
    throw InputError("pose graph: edge between invalid nodes " + std::to_string(i) + " and " + std::to_string(j));
  if (!z.matrix().allFinite()) throw InputError("pose graph: non-finite relative measurement");
  check_information(information, "relative edge");
  edges_.push_back({.kind = kind, .i = i, .j = j, .z = z, .information = information});
}

void PoseGraph::add_prior(int j, const Eigen::Isometry3d& z, const Matrix6d& information) {
  if (j < 0 || j >= num_nodes()) throw InputError("pose graph: prior on invalid node " + std::to_string(j));
  if (!z.matrix().allFinite()) throw InputError("pose graph: non-finite prior");
  check_information(information, "prior");
  edges_.push_back({.kind = EdgeKind::prior, .i = -1, .j = j, .z = z, .information = information});
  has_priors_ = true;
}

Eigen::Isometry3d PoseGraph::pose(int i) const {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::Quaterniond(q_[i]).normalized().toRotationMatrix();
  T.translation() = t_[i];
  return T;
}

PoseGraphSummary PoseGraph::optimize(int first_free, int max_iterations) {
  PoseGraphSummary summary;
  if (num_nodes() == 0 || max_iterations <= 0) return summary;
  first_free = std::clamp(first_free, has_priors_ ? 0 : 1, num_nodes());
  if (first_free >= num_nodes()) return summary;
  ceres::Problem::Options options;
  options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(options);
  ceres::EigenQuaternionManifold quaternion;
  std::vector<char> added(num_nodes(), 0);
  auto use = [&](int n) {
    if (added[n]) return;
    added[n] = 1;
    problem.AddParameterBlock(q_[n].data(), 4, &quaternion);
    problem.AddParameterBlock(t_[n].data(), 3);
    if (n < first_free) {
      problem.SetParameterBlockConstant(q_[n].data());
      problem.SetParameterBlockConstant(t_[n].data());
    }
  };
  for (const PoseGraphEdge& e : edges_) {
    if (std::max(e.i, e.j) < first_free) continue;
    if (e.kind == EdgeKind::prior) {
      use(e.j);
      problem.AddResidualBlock(make_cost(e), nullptr, q_[e.j].data(), t_[e.j].data());
    } else {
      use(e.i);
      use(e.j);
      problem.AddResidualBlock(make_cost(e), nullptr, q_[e.i].data(), t_[e.i].data(), q_[e.j].data(), t_[e.j].data());
    }
  }
  ceres::Solver::Options solver;
  solver.max_num_iterations = max_iterations;
  solver.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  if (!ceres::IsSparseLinearAlgebraLibraryTypeAvailable(solver.sparse_linear_algebra_library_type))
    solver.linear_solver_type = ceres::DENSE_QR;
  solver.num_threads = 1;
  solver.logging_type = ceres::SILENT;
  ceres::Solver::Summary s;
  ceres::Solve(solver, &problem, &s);
  summary.usable = s.IsSolutionUsable();
  summary.iterations = static_cast<int>(s.iterations.size());
  summary.initial_cost = s.initial_cost;
  summary.final_cost = s.final_cost;
  for (auto& q : q_) q.normalize();
  return summary;
}

double PoseGraph::cost(EdgeKind kind) const {
  double total = 0.0;
  for (const PoseGraphEdge& e : edges_) {
    if (e.kind != kind) continue;
    std::unique_ptr<ceres::CostFunction> f(make_cost(e));
    double r[6];
    if (e.kind == EdgeKind::prior) {
      const double* p[] = {q_[e.j].data(), t_[e.j].data()};
      f->Evaluate(p, r, nullptr);
    } else {
      const double* p[] = {q_[e.i].data(), t_[e.i].data(), q_[e.j].data(), t_[e.j].data()};
      f->Evaluate(p, r, nullptr);
    }
    for (double v : r) total += v * v;
  }
  return total;
}

}  // namespace cairn
