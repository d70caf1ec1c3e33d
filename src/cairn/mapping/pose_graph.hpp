#pragma once
// Sec. 4.2, Eq. 1: pose-graph SLAM. Nodes are sensor poses T_world_node; edges are relative
// measurements z_ij = T_i^-1 T_j with information Ω_ij (odometry from state estimation,
// scan matching from ICP) and absolute priors (the GNSS/INS state estimate, weak because its
// error is a slowly varying bias). X* = argmin Σ e_ijᵀ Ω_ij e_ij, solved with Ceres
// (Levenberg–Marquardt, sparse Cholesky). The paper uses iSAM2; here "incremental" means that
// after each new node only a window of the newest nodes is re-optimised (older ones held fixed),
// and `optimize(0, n)` re-solves everything.
//
// Error vectors are [rotation; translation] (rotation first, as IcpResult::hessian):
//   relative: e = [2 vec(q_E); t_E] of E = z^-1 T_i^-1 T_j  (≈ a right perturbation of T_j)
//   prior:    e = [2 vec(q_P); t - t_z] of q_P = q q_z^-1    (world axes: Ω diag has yaw on z)
#include <Eigen/Geometry>
#include <vector>

namespace cairn {

using Matrix6d = Eigen::Matrix<double, 6, 6>;

enum class EdgeKind { odometry, scan_matching, prior };

struct PoseGraphEdge {
  EdgeKind kind = EdgeKind::odometry;
  int i = -1, j = -1;  // prior: i = -1, j = node
  Eigen::Isometry3d z = Eigen::Isometry3d::Identity();
  Matrix6d information = Matrix6d::Identity();
};

struct PoseGraphSummary {
  bool usable = false;  // Ceres returned a usable solution
  int iterations = 0;
  double initial_cost = 0.0, final_cost = 0.0;
};

class PoseGraph {
 public:
  /// Adds a node with an initial estimate; returns its index.
  int add_node(const Eigen::Isometry3d& T_world_node);
  /// Throws InputError on bad indices or a non-finite / non-positive-semidefinite information.
  void add_relative(EdgeKind kind, int i, int j, const Eigen::Isometry3d& z_ij, const Matrix6d& information);
  void add_prior(int j, const Eigen::Isometry3d& z_world_j, const Matrix6d& information);
  /// Optimises nodes >= first_free (older ones fixed; without priors node 0 is always fixed).
  PoseGraphSummary optimize(int first_free, int max_iterations);

  [[nodiscard]] int num_nodes() const { return static_cast<int>(q_.size()); }
  [[nodiscard]] Eigen::Isometry3d pose(int i) const;
  [[nodiscard]] const std::vector<PoseGraphEdge>& edges() const { return edges_; }
  /// Σ e_ᵀ Ω e over edges of one kind at the current estimate.
  [[nodiscard]] double cost(EdgeKind kind) const;

 private:
  std::vector<Eigen::Vector4d> q_;  // x y z w
  std::vector<Eigen::Vector3d> t_;
  std::vector<PoseGraphEdge> edges_;
  bool has_priors_ = false;
};

/// Makes an information matrix usable for an edge: symmetric, eigenvalues >= 0 and capped so that
/// no direction is more certain than sigma_rot [rad] / sigma_trans [m].
[[nodiscard]] Matrix6d cap_information(const Matrix6d& information, double min_sigma_rotation,
                                       double min_sigma_translation);
/// Diagonal information from standard deviations (rotation first).
[[nodiscard]] Matrix6d diagonal_information(const Eigen::Vector3d& sigma_rotation, const Eigen::Vector3d& sigma_translation);
/// Adjoint of T for [ω; v] twists: exp(Ad_T ξ) T = T exp(ξ).
[[nodiscard]] Matrix6d adjoint(const Eigen::Isometry3d& T);

}  // namespace cairn
