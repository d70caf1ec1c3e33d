#pragma once
// Metric scale of a drone photogrammetry reconstruction (paper Sec. 4.1): the SfM model (COLMAP)
// is up to a similarity; the drone's visual-inertial odometry (VINS-like, metric and gravity
// aligned) saw the same camera centres. The similarity T_metric_sfm between the two sets of
// camera centres (Umeyama, inside a seeded RANSAC so a few bad camera poses do not bias it)
// brings the dense cloud into the metric frame; its residuals say how well it fits.
#include <span>
#include <vector>

#include "cairn/core/io/colmap.hpp"
#include "cairn/core/io/trajectory.hpp"
#include "cairn/core/transform.hpp"
#include "cairn/registration/umeyama.hpp"

namespace cairn {

struct ScaleRecoveryConfig {
  int min_cameras = 5;  // fewer associated cameras: refused
  /// RANSAC inlier threshold on camera-centre residuals in the metric frame [m] (VINS drifts
  /// and SfM poses are noisy at the decimetre level over a flight; a wrong match is metres off).
  double inlier_threshold = 0.25;
  /// Refused when fewer than this share of the cameras are inliers.
  double min_inlier_fraction = 0.6;
  /// Camera centres whose spread has σ₂/σ₁ below this (a straight flight line) leave the rotation
  /// about the line undetermined: refused (σ = singular values of the centred positions).
  double degeneracy_ratio = 1e-3;
  int iterations = 500;
  std::uint64_t seed = 42;

  template <class V>
  void visit(V& v) {
    v("min_cameras", min_cameras, "minimum number of cameras seen in both the SfM model and the metric trajectory");
    v("inlier_threshold", inlier_threshold, "RANSAC inlier threshold on camera-centre residuals [m]");
    v("min_inlier_fraction", min_inlier_fraction, "refuse when fewer cameras than this share are inliers");
    v("degeneracy_ratio", degeneracy_ratio,
      "refuse camera centres on a line: singular values sigma2/sigma1 of their spread below this");
    v("iterations", iterations, "RANSAC iterations (random camera triplets)");
    v("seed", seed, "seed of the RANSAC sampler");
  }
  void validate() const;
};

struct ScaleRecoveryResult {
  Similarity T_metric_sfm;             // metric ≈ T_metric_sfm * sfm
  std::size_t cameras = 0;             // associated camera pairs
  std::vector<std::uint32_t> inliers;  // indices into the association (image order by name)
  std::vector<double> residuals;       // [m] per camera, |metric − T(sfm)|
  double rms = 0.0;                    // [m] over the inliers
  double max_residual = 0.0;           // [m] over the inliers
};

/// Camera centres in the SfM frame, images sorted by name (capture order for the usual
/// frame_0000.png, … or timestamped names).
[[nodiscard]] std::vector<Vec3d> sfm_camera_centres(const io::ColmapModel& model);

/// Similarity from the SfM frame into the metric frame. `sfm[i]` and `metric[i]` are the same
/// camera. Throws InputError when the counts differ, there are fewer than min_cameras, the
/// positions are non-finite or degenerate (coincident or on a line), or too few are inliers.
[[nodiscard]] ScaleRecoveryResult recover_scale(std::span<const Vec3d> sfm, std::span<const Vec3d> metric,
                                                const ScaleRecoveryConfig& config = {});

/// The same from a COLMAP model and a metric TUM trajectory: images sorted by name are associated
/// with the trajectory's poses in time order (one pose per image; different counts are an
/// InputError naming both).
[[nodiscard]] ScaleRecoveryResult recover_scale(const io::ColmapModel& model,
                                                std::span<const io::TrajectoryPose> metric,
                                                const ScaleRecoveryConfig& config = {});

}  // namespace cairn
