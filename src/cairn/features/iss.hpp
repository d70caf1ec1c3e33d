#pragma once
// Intrinsic Shape Signatures keypoints (Zhong 2009, "Intrinsic shape signatures: A shape
// descriptor for 3D object recognition"), with the semantics of PCL's ISSKeypoint3D (1.13).
//
// Sec. 4.4, step 2: keypoints are extracted from the segmented point clouds with the ISS
// detector, salient radius R_iss = 6 cm (Table 3), and described with SHOT (shot.hpp).
//
// For every point p: the scatter matrix Σ (q − p)(q − p)ᵀ of its neighbours q within the salient
// radius (p included, not normalised, about p itself rather than the centroid — as PCL), with
// eigenvalues λ1 ≥ λ2 ≥ λ3. p is salient when it has ≥ min_neighbors neighbours,
// λ2/λ1 < gamma_21 and λ3/λ2 < gamma_32; its saliency is λ3. A salient point is a keypoint
// when no neighbour within non_max_radius has a larger saliency (ties are all kept) and it has
// ≥ min_neighbors neighbours there (itself included).
// Not implemented: PCL's optional border removal (border_radius > 0, off by default in PCL).
#include <cstdint>
#include <span>
#include <vector>

#include "cairn/core/kdtree.hpp"
#include "cairn/core/point_cloud.hpp"

namespace cairn {

struct IssConfig {
  double salient_radius = 0.06;  // R_iss [m], Table 3
  double non_max_radius = 0.04;  // non-maximum suppression radius [m]
  double gamma_21 = 0.975;       // threshold on lambda2 / lambda1
  double gamma_32 = 0.975;       // threshold on lambda3 / lambda2
  int min_neighbors = 5;         // neighbours (the point included) needed for both radii

  template <class V>
  void visit(V&& v) {
    v("salient_radius", salient_radius, "ISS salient radius R_iss: scatter-matrix neighbourhood [m] (Table 3)");
    v("non_max_radius", non_max_radius, "ISS non-maximum suppression radius [m]");
    v("gamma_21", gamma_21, "ISS: a point is salient only if lambda2/lambda1 is below this");
    v("gamma_32", gamma_32, "ISS: a point is salient only if lambda3/lambda2 is below this");
    v("min_neighbors", min_neighbors, "ISS: minimum neighbours (point included) within each radius");
  }

  /// Throws ConfigError naming the key if a value is out of range.
  void validate() const;
};

/// Indices into `points` of the ISS keypoints, ascending. `tree` is a KdTree built over
/// `points`. Deterministic (TBB-parallel, independent of the thread count). Throws ConfigError on
/// a bad config, InputError if the tree does not index `points`.
[[nodiscard]] std::vector<std::uint32_t> iss_keypoints(std::span<const Vec3f> points, const KdTree& tree,
                                                       const IssConfig& cfg);

/// Per-point saliency λ3 (0 where the point is not salient), the quantity ISS suppresses
/// non-maxima of; exposed for diagnostics and tests.
[[nodiscard]] std::vector<double> iss_saliency(std::span<const Vec3f> points, const KdTree& tree,
                                               const IssConfig& cfg);

}  // namespace cairn
