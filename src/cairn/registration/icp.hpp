#pragma once
// Iterative Closest Point: point-to-point and point-to-plane objectives, robust kernels (IRLS),
// optional 4-DoF (yaw + translation) mode, deterministic TBB-parallel linearisation.
//
// Used by the LiDAR mapping front-end (Sec. 4.2, step 3: scan pair S_k against a submap of the m
// previous scan pairs) and by the global registration (Sec. 4.4, step 5: refinement of
// T_MS^coarse, accepted when the RMSE is below e_icp* = 3 cm, Table 3). A target is prepared once
// (kd-tree + normals), then any number of sources can be registered against it, concurrently.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "cairn/core/kdtree.hpp"
#include "cairn/core/normals.hpp"
#include "cairn/core/point_cloud.hpp"

namespace cairn {

struct IcpConfig {
  std::string objective = "point_to_plane";  // "point_to_plane" (needs target normals) | "point_to_point"
  std::string kernel = "none";               // "none" | "huber" | "cauchy" | "tukey" | "geman_mcclure"
  double kernel_scale = 0.05;                // [m] residual scale of the robust kernel
  double max_correspondence_distance = 0.5;  // [m] nearest neighbours farther away are not paired
  int max_iterations = 50;
  double translation_tolerance = 1e-4;  // [m]   converged when the increment's translation and
  double rotation_tolerance = 1e-4;     // [rad] rotation are both below these
  int min_correspondences = 10;         // fewer pairs: stop, converged = false
  bool four_dof = false;  // optimise yaw about the target's z axis + translation only (gravity-aligned
                          // map frames: roll and pitch of the initial guess are kept)
  bool parallel = true;   // TBB; the result is bit-identical to the serial path

  template <class V>
  void visit(V& v) {
    v("objective", objective, "point_to_plane (target normals) or point_to_point");
    v("kernel", kernel, "robust kernel: none, huber, cauchy, tukey or geman_mcclure");
    v("kernel_scale", kernel_scale, "residual scale of the robust kernel [m]");
    v("max_correspondence_distance", max_correspondence_distance,
      "nearest neighbours farther than this are not paired [m]");
    v("max_iterations", max_iterations, "maximum number of Gauss-Newton iterations");
    v("translation_tolerance", translation_tolerance, "convergence: translation increment below this [m]");
    v("rotation_tolerance", rotation_tolerance, "convergence: rotation increment below this [rad]");
    v("min_correspondences", min_correspondences, "fewer correspondences than this: registration fails");
    v("four_dof", four_dof, "estimate yaw + translation only (gravity-aligned frames)");
    v("parallel", parallel, "parallel correspondence search (same result as serial)");
  }

  /// Throws ConfigError naming the key if a value is out of range or unknown.
  void validate() const;
};

/// A registration target prepared once: its points (owned), a kd-tree over them and, for the
/// point-to-plane objective, unit normals (zero vector = no normal; such points are skipped).
/// Points are stored in Morton (Z-curve) order for cache locality: points()[i] is input point
/// input_index(i). Immutable after construction, so concurrent registrations are safe.
class IcpTarget {
 public:
  /// Without normals: point-to-point only.
  explicit IcpTarget(std::vector<Vec3f> points);
  /// With given normals (one per point; normalised here, zero vectors allowed).
  IcpTarget(std::vector<Vec3f> points, std::vector<Vec3f> normals);
  /// With PCA normals estimated from the points themselves.
  IcpTarget(std::vector<Vec3f> points, const NormalConfig& normal_config);
  /// From a cloud: its normals if it has them, else PCA normals; keeps the cloud's origin.
  [[nodiscard]] static IcpTarget from_cloud(const PointCloud& cloud, const NormalConfig& normal_config = {.k = 20});

  IcpTarget(IcpTarget&&) noexcept = default;
  IcpTarget& operator=(IcpTarget&&) noexcept = default;
  IcpTarget(const IcpTarget&) = delete;
  IcpTarget& operator=(const IcpTarget&) = delete;

  [[nodiscard]] std::size_t size() const { return points_.size(); }
  [[nodiscard]] bool has_normals() const { return !normals_.empty(); }
  [[nodiscard]] std::span<const Vec3f> points() const { return points_; }
  [[nodiscard]] std::span<const Vec3f> normals() const { return normals_; }
  [[nodiscard]] const KdTree& tree() const { return *tree_; }
  /// Index in the constructor's input of stored point i.
  [[nodiscard]] std::uint32_t input_index(std::size_t i) const { return order_[i]; }
  /// World position of the target's local frame (see PointCloud::origin); zero for span inputs.
  [[nodiscard]] const Vec3d& origin() const { return origin_; }

 private:
  IcpTarget(std::vector<Vec3f> points, std::vector<Vec3f> normals, bool with_normals);
  std::vector<std::uint32_t> order_;
  std::vector<Vec3f> points_;
  std::vector<Vec3f> normals_;
  std::unique_ptr<KdTree> tree_;  // indexes points_ (the vector's buffer survives moves)
  Vec3d origin_ = Vec3d::Zero();
};

enum class IcpStatus {
  converged,               // increment below the tolerances
  max_iterations,          // iteration limit reached first (the result may still be usable)
  too_few_correspondences, // fewer than min_correspondences pairs within the distance
  degenerate,              // the normal equations could not be solved (non-finite increment)
};
[[nodiscard]] const char* to_string(IcpStatus s);

/// Diagnostics in the style of small_gicp. Statistics are evaluated at the returned transform.
struct IcpResult {
  Eigen::Isometry3d T_target_source = Eigen::Isometry3d::Identity();
  bool converged = false;
  IcpStatus status = IcpStatus::max_iterations;
  int iterations = 0;          // Gauss-Newton updates applied
  std::size_t num_inliers = 0; // correspondences within max_correspondence_distance (with a valid normal)
  double rmse = 0.0;           // [m] RMS point-to-point distance over the inliers (the paper's e_icp)
  double fitness = 0.0;        // num_inliers / number of source points
  double error = 0.0;          // final objective: Σ ρ(r) (robust kernel applied)
  /// Gauss-Newton Hessian JᵀWJ at the result, for the left perturbation [ω; v] (rotation first),
  /// in units of the objective: use it (divided by the residual variance) as the information
  /// matrix of a pose-graph edge. Always the full 6×6, also in 4-DoF mode.
  Eigen::Matrix<double, 6, 6> hessian = Eigen::Matrix<double, 6, 6>::Zero();
};

/// Registers `source` (points in the source frame) to `target`, starting from T_init
/// (T_target_source). Both in the same units; the target's origin is ignored (span interface).
/// Throws InputError on an empty source or non-finite points, ConfigError on a bad config or a
/// point-to-plane objective against a target without normals.
[[nodiscard]] IcpResult register_icp(std::span<const Vec3f> source, const IcpTarget& target,
                                     const Eigen::Isometry3d& T_init, const IcpConfig& config);

/// Cloud interface: T_init and the result map world coordinates of the source (origin + point)
/// into world coordinates of the target, so georeferenced clouds keep their precision.
[[nodiscard]] IcpResult register_icp(const PointCloud& source, const IcpTarget& target,
                                     const Eigen::Isometry3d& T_init, const IcpConfig& config);

/// Nearest-neighbour statistics of `source` transformed by T_target_source against `target`
/// without optimising: num_inliers, rmse, fitness, and error + hessian of the point-to-point
/// objective (iterations = 0, status = converged).
[[nodiscard]] IcpResult evaluate_alignment(std::span<const Vec3f> source, const IcpTarget& target,
                                           const Eigen::Isometry3d& T_target_source,
                                           double max_correspondence_distance);

}  // namespace cairn
