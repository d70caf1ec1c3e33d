#include "cairn/features/shot.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

#include "cairn/core/error.hpp"
#include "cairn/features/search_radius.hpp"

// The arithmetic below follows PCL 1.13 (features/impl/shot.hpp, shot_lrf.hpp) expression by
// expression, with the same Eigen types (Vector4f dot products, a column-major n × 4 double matrix
// for the LRF), so that the descriptors agree with PCL's to float rounding.

namespace cairn {

void ShotConfig::validate() const {
  if (!(radius > 0.0) || !std::isfinite(radius)) throw ConfigError("shot.radius must be positive");
}

std::size_t ShotDescriptors::num_valid() const {
  return std::size_t(std::count(valid.begin(), valid.end(), std::uint8_t(1)));
}

namespace {

constexpr int kShapeBins = 10;         // cosine bins per spatial volume (PCL nr_shape_bins_)
static_assert(kShapeBins + 1 == kShotBinsPerVolume);
constexpr int kAngularSectors = kShotVolumes;
constexpr double kRad45 = 0.78539816339744830961566084581988;
constexpr double kRad90 = 1.5707963267948966192313216916398;
constexpr double kRad135 = 2.3561944901923449288469825374596;
constexpr double kRadPi78 = 2.7488935718910690836548129603691;
constexpr int kMinNeighbors = 5;

struct Neighbor {
  float d2;
  std::uint32_t index;
  bool operator<(const Neighbor& o) const { return d2 < o.d2 || (d2 == o.d2 && index < o.index); }
};

/// Per-task scratch buffers, reused across keypoints.
struct Scratch {
  std::vector<Neighbor> neighbors;
  std::vector<double> vij;           // column-major n × 4 (PCL's Eigen::Matrix<double, Dynamic, 4>)
  std::vector<double> bin_distance;  // per neighbour: position in the cosine histogram, NaN = no normal
};

Eigen::Vector4f homogeneous(const Vec3f& p) { return {p.x(), p.y(), p.z(), 1.0f}; }

/// SHOT local reference frame (PCL SHOTLocalReferenceFrameEstimation::getLocalRF). `neighbors`
/// sorted by (distance, index). Returns false when it is undefined (< 5 neighbours ≠ p).
bool local_reference_frame(const Vec3f& center, std::span<const Vec3f> surface, std::span<const Neighbor> neighbors,
                           double radius, std::vector<double>& vij_buffer, Eigen::Matrix3f& rf) {
  const Eigen::Vector4f central_point = homogeneous(center);
  const auto n = Eigen::Index(neighbors.size());
  vij_buffer.resize(std::size_t(n) * 4);
  Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, 4>> vij(vij_buffer.data(), n, 4);
  Eigen::Matrix3d cov_m = Eigen::Matrix3d::Zero();
  double sum = 0.0;
  int valid_nn_points = 0;
  for (const Neighbor& nb : neighbors) {
    const Eigen::Vector4f pt = homogeneous(surface[nb.index]);
    if (pt.head<3>() == central_point.head<3>()) continue;
    vij.row(valid_nn_points).matrix() = (pt - central_point).cast<double>();
    vij(valid_nn_points, 3) = 0;
    const double distance = radius - std::sqrt(double(nb.d2));
    cov_m += distance * (vij.row(valid_nn_points).head<3>().transpose() * vij.row(valid_nn_points).head<3>());
    sum += distance;
    valid_nn_points++;
  }
  if (valid_nn_points < kMinNeighbors) return false;
  cov_m /= sum;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(cov_m);
  const Eigen::Vector3d& ev = solver.eigenvalues();
  if (!std::isfinite(ev[0]) || !std::isfinite(ev[1]) || !std::isfinite(ev[2])) return false;

  // Sign disambiguation: each axis points towards the majority of the neighbours.
  Eigen::Vector4d v1 = Eigen::Vector4d::Zero();
  Eigen::Vector4d v3 = Eigen::Vector4d::Zero();
  v1.head<3>() = solver.eigenvectors().col(2);
  v3.head<3>() = solver.eigenvectors().col(0);
  int plus_x = 0, plus_z = 0;
  for (int ne = 0; ne < valid_nn_points; ne++) {
    if (vij.row(ne).dot(v1) >= 0) plus_x++;
    if (vij.row(ne).dot(v3) >= 0) plus_z++;
  }
  const auto disambiguate = [&](int plus, Eigen::Vector4d& axis) {
    plus = 2 * plus - valid_nn_points;
    if (plus == 0) {  // tie: the 5 neighbours around the median distance decide
      constexpr int points = 5;
      const int median = valid_nn_points / 2;
      for (int i = -points / 2; i <= points / 2; i++)
        if (vij.row(median - i).dot(axis) > 0) plus++;
      if (plus < points / 2 + 1) axis *= -1;
    } else if (plus < 0) {
      axis *= -1;
    }
  };
  disambiguate(plus_x, v1);
  disambiguate(plus_z, v3);
  rf.row(0).matrix() = v1.head<3>().cast<float>();
  rf.row(2).matrix() = v3.head<3>().cast<float>();
  rf.row(1) = rf.row(2).cross(rf.row(0));
  return true;
}

/// The SHOT histogram (PCL SHOTEstimationBase::createBinDistanceShape + interpolateSingleChannel
/// + normalizeHistogram). Returns false when the histogram is empty (normalisation undefined).
bool shot_histogram(const Vec3f& center, const Eigen::Matrix3f& rf, std::span<const Vec3f> surface,
                    std::span<const Vec3f> normals, std::span<const Neighbor> neighbors, double radius,
                    std::vector<double>& bin_distance, float* shot) {
  const Eigen::Vector4f frame_x(rf(0, 0), rf(0, 1), rf(0, 2), 0.0f);
  const Eigen::Vector4f frame_y(rf(1, 0), rf(1, 1), rf(1, 2), 0.0f);
  const Eigen::Vector4f frame_z(rf(2, 0), rf(2, 1), rf(2, 2), 0.0f);
  const Eigen::Vector4f central_point = homogeneous(center);
  const double radius1_2 = radius / 2, radius3_4 = (radius * 3) / 4, radius1_4 = radius / 4;

  bin_distance.resize(neighbors.size());
  for (std::size_t i = 0; i < neighbors.size(); ++i) {
    const Vec3f& n = normals[neighbors[i].index];
    if (!n.allFinite() || n.isZero(0.0f)) {
      bin_distance[i] = std::numeric_limits<double>::quiet_NaN();
      continue;
    }
    const Eigen::Vector4f normal_vec(n.x(), n.y(), n.z(), 0.0f);
    double cosine = normal_vec.dot(frame_z);
    cosine = std::clamp(cosine, -1.0, 1.0);
    bin_distance[i] = ((1.0 + cosine) * kShapeBins) / 2;
  }

  std::fill(shot, shot + kShotSize, 0.0f);
  for (std::size_t i = 0; i < neighbors.size(); ++i) {
    if (!std::isfinite(bin_distance[i])) continue;
    Eigen::Vector4f delta = homogeneous(surface[neighbors[i].index]) - central_point;
    delta[3] = 0;
    const double distance = std::sqrt(double(neighbors[i].d2));
    if (std::abs(distance - 0.0) < 1e-15) continue;

    double x = delta.dot(frame_x);
    double y = delta.dot(frame_y);
    double z = delta.dot(frame_z);
    if (std::abs(y) < 1E-30) y = 0;
    if (std::abs(x) < 1E-30) x = 0;
    if (std::abs(z) < 1E-30) z = 0;

    // Spatial volume: azimuth sector (8), elevation (2), shell (2).
    const int bit4 = ((y > 0) || ((y == 0.0) && (x < 0))) ? 1 : 0;
    const int bit3 = ((x > 0) || ((x == 0.0) && (y > 0))) ? !bit4 : bit4;
    int desc_index = ((bit4 << 3) + (bit3 << 2)) << 1;
    if ((x * y > 0) || (x == 0.0))
      desc_index += (std::abs(x) >= std::abs(y)) ? 0 : 4;
    else
      desc_index += (std::abs(x) > std::abs(y)) ? 4 : 0;
    desc_index += z > 0 ? 1 : 0;
    desc_index += (distance > radius1_2) ? 2 : 0;

    const int step_index = static_cast<int>(std::floor(bin_distance[i] + 0.5));
    const int volume_index = desc_index * kShotBinsPerVolume;

    // Interpolation on the cosine (adjacent bins of the histogram).
    const double bin_offset = bin_distance[i] - step_index;
    double weight = 1 - std::abs(bin_offset);
    if (bin_offset > 0)
      shot[volume_index + ((step_index + 1) % kShapeBins)] += static_cast<float>(bin_offset);
    else
      shot[volume_index + ((step_index - 1 + kShapeBins) % kShapeBins)] += -static_cast<float>(bin_offset);

    // Interpolation on the distance (adjacent shells).
    if (distance > radius1_2) {
      const double radius_distance = (distance - radius3_4) / radius1_2;
      if (distance > radius3_4) {
        weight += 1 - radius_distance;
      } else {
        weight += 1 + radius_distance;
        shot[(desc_index - 2) * kShotBinsPerVolume + step_index] -= static_cast<float>(radius_distance);
      }
    } else {
      const double radius_distance = (distance - radius1_4) / radius1_2;
      if (distance < radius1_4) {
        weight += 1 + radius_distance;
      } else {
        weight += 1 - radius_distance;
        shot[(desc_index + 2) * kShotBinsPerVolume + step_index] += static_cast<float>(radius_distance);
      }
    }

    // Interpolation on the inclination (adjacent elevation volumes).
    const double inclination = std::acos(std::clamp(z / distance, -1.0, 1.0));
    if (inclination > kRad90 || (std::abs(inclination - kRad90) < 1e-30 && z <= 0)) {
      const double inclination_distance = (inclination - kRad135) / kRad90;
      if (inclination > kRad135) {
        weight += 1 - inclination_distance;
      } else {
        weight += 1 + inclination_distance;
        shot[(desc_index + 1) * kShotBinsPerVolume + step_index] -= static_cast<float>(inclination_distance);
      }
    } else {
      const double inclination_distance = (inclination - kRad45) / kRad90;
      if (inclination < kRad45) {
        weight += 1 + inclination_distance;
      } else {
        weight += 1 - inclination_distance;
        shot[(desc_index - 1) * kShotBinsPerVolume + step_index] += static_cast<float>(inclination_distance);
      }
    }

    // Interpolation on the azimuth (adjacent azimuth sectors).
    if (y != 0.0 || x != 0.0) {
      const double azimuth = std::atan2(y, x);
      const int sel = desc_index >> 2;
      double azimuth_distance = (azimuth - (-kRadPi78 + kRad45 * sel)) / kRad45;
      azimuth_distance = std::max(-0.5, std::min(azimuth_distance, 0.5));
      if (azimuth_distance > 0) {
        weight += 1 - azimuth_distance;
        const int interp = (desc_index + 4) % kAngularSectors;
        shot[interp * kShotBinsPerVolume + step_index] += static_cast<float>(azimuth_distance);
      } else {
        const int interp = (desc_index - 4 + kAngularSectors) % kAngularSectors;
        weight += 1 + azimuth_distance;
        shot[interp * kShotBinsPerVolume + step_index] -= static_cast<float>(azimuth_distance);
      }
    }
    shot[volume_index + step_index] += static_cast<float>(weight);
  }

  // L2 normalisation (PCL normalizeHistogram: float squares accumulated in double).
  double acc_norm = 0;
  for (int j = 0; j < kShotSize; j++) acc_norm += shot[j] * shot[j];
  acc_norm = std::sqrt(acc_norm);
  if (!(acc_norm > 0.0)) return false;
  for (int j = 0; j < kShotSize; j++) shot[j] /= static_cast<float>(acc_norm);
  return true;
}

}  // namespace

ShotDescriptors compute_shot(std::span<const Vec3f> keypoints, std::span<const Vec3f> surface,
                             std::span<const Vec3f> surface_normals, const KdTree& surface_tree, const ShotConfig& cfg) {
  cfg.validate();
  if (surface_normals.size() != surface.size())
    throw InputError("compute_shot: " + std::to_string(surface.size()) + " surface points but " +
                     std::to_string(surface_normals.size()) + " normals");
  if (surface_tree.points().data() != surface.data() || surface_tree.size() != surface.size())
    throw InputError("compute_shot: the kd-tree does not index the surface points");

  const std::size_t n = keypoints.size();
  constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
  ShotDescriptors out;
  out.data.assign(n * std::size_t(kShotSize), kNaN);
  out.lrf.assign(n, Eigen::Matrix3f::Constant(kNaN));
  out.valid.assign(n, 0);
  const float search_radius = detail::pcl_equivalent_radius(cfg.radius);

  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 8), [&](const auto& range) {
    Scratch s;
    for (std::size_t k = range.begin(); k != range.end(); ++k) {
      const Vec3f& p = keypoints[k];
      if (!p.allFinite()) continue;
      s.neighbors.clear();
      surface_tree.for_each_in_radius(p, search_radius,
                                      [&](std::uint32_t i, float d2) { s.neighbors.push_back({d2, i}); });
      if (s.neighbors.size() < std::size_t(kMinNeighbors)) continue;
      std::sort(s.neighbors.begin(), s.neighbors.end());  // PCL's LRF uses sorted results
      Eigen::Matrix3f rf;
      if (!local_reference_frame(p, surface, s.neighbors, cfg.radius, s.vij, rf)) continue;
      out.lrf[k] = rf;
      float* row = out.data.data() + k * std::size_t(kShotSize);
      if (!shot_histogram(p, rf, surface, surface_normals, s.neighbors, cfg.radius, s.bin_distance, row)) {
        std::fill(row, row + kShotSize, kNaN);
        continue;
      }
      out.valid[k] = 1;
    }
  });
  return out;
}

}  // namespace cairn
