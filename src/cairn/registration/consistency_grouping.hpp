#pragma once
// Geometric consistency grouping of keypoint correspondences (Chen & Bhanu 2007, "3D free-form
// object recognition in range images using local surface patches"), with the semantics of PCL
// 1.13's pcl::GeometricConsistencyGrouping.
//
// Sec. 4.4, step 4: among the descriptor correspondences (features/matching.hpp), clusters of
// geometrically consistent pairs are found; each cluster gives a rigid transform candidate
// T_MS^coarse, the b most-voted candidates (Table 3) are refined by ICP and verified (step 5).
//
// Clustering (exactly PCL's): the correspondences are sorted by descriptor distance (std::sort,
// as PCL); each not-yet-taken correspondence in that order seeds a cluster, and every other
// not-taken correspondence j (in sorted order) joins when, for every member k already in the
// cluster, | |s_k − s_j| − |t_k − t_j| | ≤ consensus_size (s source, t target keypoints; float
// arithmetic as PCL). A cluster with MORE than min_votes members is accepted and its members are
// taken (PCL's gc_threshold semantics: size > threshold).
//
// Deviations from PCL (documented in docs/features.md):
// - Transform: PCL returns the best 3-point RANSAC model of pcl::CorrespondenceRejectorSampleConsensus
//   (10000 iterations, inlier threshold gc_size) and its inliers. cairn fits the rigid
//   least-squares transform (Umeyama) to the whole cluster and, with `refine`, refits twice on the
//   members whose residual is below consensus_size (deterministic, no sampling). refine = false
//   keeps the plain cluster fit.
// - Output: candidates sorted by votes (cluster size, stable: discovery order on ties) and cut at
//   max_candidates; PCL returns every cluster in discovery order. A cluster whose keypoints are
//   collinear (no unique rotation) yields no candidate.
#include <Eigen/Geometry>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "cairn/core/point_cloud.hpp"
#include "cairn/features/matching.hpp"

namespace cairn {

struct GroupingConfig {
  double consensus_size = 0.05;  // gc_size [m]: tolerance on pairwise keypoint distances
  int min_votes = 5;             // gc_threshold: a cluster is kept when it has MORE than this many pairs (PCL)
  int max_candidates = 10;       // b, Table 3: keep the b most-voted clusters
  bool refine = true;            // refit on the members with residual < consensus_size (PCL: RANSAC)

  template <class V>
  void visit(V&& v) {
    v("consensus_size", consensus_size,
      "geometric consistency tolerance on pairwise keypoint distances [m] (PCL gc_size)");
    v("min_votes", min_votes, "a cluster is accepted when it has more correspondences than this (PCL gc_threshold)");
    v("max_candidates", max_candidates, "b: number of most-voted transform candidates kept (Table 3)");
    v("refine", refine, "refit each cluster's transform on its members within consensus_size of the first fit");
  }

  /// Throws ConfigError naming the key if a value is out of range.
  void validate() const;
};

struct TransformCandidate {
  Eigen::Isometry3d T_target_source = Eigen::Isometry3d::Identity();  // rigid, from the cluster's keypoint pairs (SVD/Umeyama)
  std::vector<Correspondence> inliers;  // the cluster (with refine: its members within consensus_size of the fit)
  std::size_t votes = 0;                // cluster size (the ranking key)
  double rms = 0.0;                     // [m] RMS keypoint residual of the inliers under T_target_source
};

/// Clusters of geometrically consistent correspondences, most votes first, at most max_candidates.
/// Correspondence::source indexes source_keypoints, ::target target_keypoints. Deterministic.
/// Throws ConfigError on a bad config, InputError on an out-of-range keypoint index.
[[nodiscard]] std::vector<TransformCandidate> geometric_consistency_grouping(std::span<const Vec3f> source_keypoints,
                                                                           std::span<const Vec3f> target_keypoints,
                                                                           std::span<const Correspondence> matches,
                                                                           const GroupingConfig& cfg);

/// Throws InputError naming `what` when a correspondence indexes past the keypoints.
void check_correspondence_indices(std::span<const Vec3f> source_keypoints, std::span<const Vec3f> target_keypoints,
                                  std::span<const Correspondence> matches, const std::string& what);

/// The rigid transform of a set of correspondences (Umeyama over all members), then `refits`
/// times refitted on those of all the members the current fit places within `tolerance` of their partner
/// (stops early when fewer than 3 remain). Nothing when the members are collinear or fewer than 3.
/// votes = the members given; inliers = the members of the last fit.
[[nodiscard]] std::optional<TransformCandidate> fit_candidate(std::span<const Vec3f> source_keypoints,
                                                              std::span<const Vec3f> target_keypoints,
                                                              std::vector<Correspondence> members, double tolerance,
                                                              int refits);

/// The clusters alone (PCL's clustering, in discovery order, all of them), as lists of
/// correspondences in sorted-by-distance order. Exposed for the PCL cross-check and diagnostics.
[[nodiscard]] std::vector<std::vector<Correspondence>> consistency_clusters(std::span<const Vec3f> source_keypoints,
                                                                           std::span<const Vec3f> target_keypoints,
                                                                           std::span<const Correspondence> matches,
                                                                           const GroupingConfig& cfg);

}  // namespace cairn
