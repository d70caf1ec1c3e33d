#pragma once
// SHOT352 — Signature of Histograms of OrienTations (Tombari, Salti, Di Stefano 2010, "Unique
// Signatures of Histograms for Local Surface Description"), numerically equivalent to PCL 1.13's
// SHOTEstimation / SHOTEstimationOMP with its default SHOTLocalReferenceFrameEstimation.
//
// Sec. 4.4, step 2: the ISS keypoints of both segmented clouds are described with SHOT, search
// radius R_shot = 10 cm (Table 3).
//
// Local reference frame (Tombari 2010, Sec. 4): distance-weighted scatter Σ w (q − p)(q − p)ᵀ / Σ w,
// w = R − |q − p|, over the neighbours q ≠ p within R; x = eigenvector of the largest eigenvalue,
// z = of the smallest, each signed towards the majority of the neighbours (ties: the 5 neighbours
// around the median distance decide), y = z × x. Descriptor: 32 spatial volumes (8 azimuth × 2
// elevation × 2 radial shells) × 11 bins of cos(angle between the neighbour's normal and z),
// quadrilinear interpolation, L2 normalisation.
#include <Eigen/Core>
#include <cstdint>
#include <span>
#include <vector>

#include "cairn/core/kdtree.hpp"
#include "cairn/core/point_cloud.hpp"

namespace cairn {

inline constexpr int kShotSize = 352;
inline constexpr int kShotVolumes = 32;                           // spatial volumes (PCL maxAngularSectors_)
inline constexpr int kShotBinsPerVolume = kShotSize / kShotVolumes;  // 11 cosine bins each (PCL nr_shape_bins_ + 1)

struct ShotConfig {
  double radius = 0.10;  // R_shot [m], Table 3 (also the local-reference-frame radius, as PCL's default)

  template <class V>
  void visit(V&& v) {
    v("radius", radius, "SHOT support radius R_shot, also the local reference frame radius [m] (Table 3)");
  }

  /// Throws ConfigError naming the key if a value is out of range.
  void validate() const;
};

struct ShotDescriptors {
  std::vector<float> data;           // size() × 352, row-major; NaN rows where !valid
  std::vector<Eigen::Matrix3f> lrf;  // rows = x, y, z axes of the local reference frame (NaN if invalid)
  std::vector<std::uint8_t> valid;   // 0 where PCL would output NaN (too few neighbours / bad LRF)
  [[nodiscard]] std::size_t size() const { return valid.size(); }
  [[nodiscard]] std::size_t num_valid() const;
  [[nodiscard]] std::span<const float> descriptor(std::size_t i) const {
    return {data.data() + i * std::size_t(kShotSize), std::size_t(kShotSize)};
  }
};

/// Descriptors at `keypoints`, computed from the neighbourhood in `surface` (with its normals and a
/// KdTree over it). Normals that are zero or not finite (cairn's "no normal", PCL's NaN) are
/// skipped, as PCL skips NaN normals. A keypoint is invalid when the LRF has fewer than 5
/// neighbours distinct from the keypoint, or the histogram is empty (all neighbour normals
/// missing). TBB-parallel, deterministic. Throws ConfigError on a bad config, InputError when the
/// sizes of surface, normals and tree disagree.
[[nodiscard]] ShotDescriptors compute_shot(std::span<const Vec3f> keypoints, std::span<const Vec3f> surface,
                                           std::span<const Vec3f> surface_normals, const KdTree& surface_tree,
                                           const ShotConfig& cfg);

}  // namespace cairn
