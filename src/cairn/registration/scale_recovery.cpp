#include "cairn/registration/scale_recovery.hpp"

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <numeric>

#include "cairn/core/error.hpp"

namespace cairn {
namespace {

std::string fmt_double(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3g", v);
  return buf;
}

/// σ₂/σ₁ of the centred positions (not of their covariance): 0 on a line, 1 for a round cloud.
double spread_ratio(std::span<const Vec3d> p) {
  Vec3d mean = Vec3d::Zero();
  for (const Vec3d& x : p) mean += x;
  mean /= double(p.size());
  Eigen::MatrixXd centred(p.size(), 3);
  for (std::size_t i = 0; i < p.size(); ++i) centred.row(Eigen::Index(i)) = (p[i] - mean).transpose();
  const Eigen::Vector3d s = Eigen::JacobiSVD<Eigen::MatrixXd>(centred).singularValues();
  return s(0) > 0.0 ? s(1) / s(0) : 0.0;
}

}  // namespace

void ScaleRecoveryConfig::validate() const {
  if (min_cameras < 3) throw ConfigError("scale.min_cameras must be at least 3");
  if (!(inlier_threshold > 0.0) || !std::isfinite(inlier_threshold))
    throw ConfigError("scale.inlier_threshold must be a positive number of metres");
  if (!(min_inlier_fraction > 0.0 && min_inlier_fraction <= 1.0))
    throw ConfigError("scale.min_inlier_fraction must be in (0, 1]");
  if (!(degeneracy_ratio >= 0.0 && degeneracy_ratio < 1.0)) throw ConfigError("scale.degeneracy_ratio must be in [0, 1)");
  if (iterations < 1) throw ConfigError("scale.iterations must be at least 1");
}

std::vector<Vec3d> sfm_camera_centres(const io::ColmapModel& model) {
  std::vector<const io::ColmapImage*> images;
  for (const auto& im : model.images) images.push_back(&im);
  std::sort(images.begin(), images.end(), [](const auto* a, const auto* b) { return a->name < b->name; });
  std::vector<Vec3d> centres;
  centres.reserve(images.size());
  for (const auto* im : images) centres.push_back(im->center());
  return centres;
}

ScaleRecoveryResult recover_scale(std::span<const Vec3d> sfm, std::span<const Vec3d> metric,
                                  const ScaleRecoveryConfig& config) {
  config.validate();
  if (sfm.size() != metric.size())
    throw InputError("scale recovery: " + std::to_string(sfm.size()) + " SfM cameras but " +
                     std::to_string(metric.size()) + " metric camera positions");
  if (sfm.size() < std::size_t(config.min_cameras))
    throw InputError("scale recovery: " + std::to_string(sfm.size()) + " cameras, at least " +
                     std::to_string(config.min_cameras) + " needed (scale.min_cameras)");
  for (std::size_t i = 0; i < sfm.size(); ++i)
    if (!sfm[i].allFinite() || !metric[i].allFinite())
      throw InputError("scale recovery: camera " + std::to_string(i) + " has a non-finite position");
  for (const auto& [set, name] : {std::pair{sfm, "SfM"}, std::pair{metric, "metric"}}) {
    const double r = spread_ratio(set);
    if (r < config.degeneracy_ratio)
      throw InputError(std::string("scale recovery: the ") + name + " camera centres lie on a line (spread ratio " +
                       fmt_double(r) + " < scale.degeneracy_ratio " + fmt_double(config.degeneracy_ratio) +
                       "): the rotation about it is undetermined");
  }
  RobustUmeyamaConfig rc;
  rc.inlier_threshold = config.inlier_threshold;
  rc.iterations = config.iterations;
  rc.min_inliers = std::max(3, int(std::ceil(config.min_inlier_fraction * double(sfm.size()))));
  rc.seed = config.seed;
  const RobustUmeyamaResult fit = robust_umeyama(sfm, metric, rc);  // InputError when too few inliers

  ScaleRecoveryResult r;
  r.T_metric_sfm = fit.transform;
  r.cameras = sfm.size();
  r.inliers = fit.inliers;
  r.residuals.resize(sfm.size());
  for (std::size_t i = 0; i < sfm.size(); ++i) r.residuals[i] = (metric[i] - fit.transform * sfm[i]).norm();
  double sq = 0.0;
  for (std::uint32_t i : fit.inliers) {
    sq += r.residuals[i] * r.residuals[i];
    r.max_residual = std::max(r.max_residual, r.residuals[i]);
  }
  r.rms = fit.inliers.empty() ? 0.0 : std::sqrt(sq / double(fit.inliers.size()));
  return r;
}

ScaleRecoveryResult recover_scale(const io::ColmapModel& model, std::span<const io::TrajectoryPose> metric,
                                  const ScaleRecoveryConfig& config) {
  if (model.images.size() != metric.size())
    throw InputError("scale recovery: the SfM model has " + std::to_string(model.images.size()) +
                     " images but the metric trajectory " + std::to_string(metric.size()) +
                     " poses (one pose per image, in capture order, is expected)");
  std::vector<io::TrajectoryPose> sorted(metric.begin(), metric.end());
  std::stable_sort(sorted.begin(), sorted.end(), [](const auto& a, const auto& b) { return a.timestamp < b.timestamp; });
  std::vector<Vec3d> m;
  m.reserve(sorted.size());
  for (const auto& p : sorted) m.push_back(p.position);
  return recover_scale(sfm_camera_centres(model), m, config);
}

}  // namespace cairn
