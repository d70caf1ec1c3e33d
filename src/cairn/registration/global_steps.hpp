#pragma once
// The steps of segment-based global registration (paper Sec. 4.4) that register_global runs in
// order, each testable alone (tests/registration/test_global_steps.cpp): the object segments of
// a cloud, centroid hypotheses, the mutual-overlap measure, the acceptance test, the one
// refine-and-accept loop both registration paths share, and the merge of the registered scene.
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <vector>

#include "cairn/core/kdtree.hpp"
#include "cairn/registration/global_registration.hpp"

namespace cairn {

/// The object segments of one cloud, in the cloud's local coordinates (levelled for the source).
struct SegmentSet {
  std::vector<Vec3f> points;               // all object-segment points
  std::vector<std::int32_t> segment_of;    // segment index (into ids) per point
  std::vector<std::int32_t> ids;           // segment id per segment index
  std::vector<std::vector<std::uint32_t>> members;  // per segment index: indices into points
  std::vector<Vec3f> centroids;            // per segment index
  std::vector<Vec3f> normals;              // per point, oriented away from its segment's centroid
  std::vector<std::uint32_t> keypoints;    // indices into points
  ShotDescriptors descriptors;
  std::unique_ptr<KdTree> tree;
};

/// Step 1's output as sets: the non-planar segments of `seg` (planar ones are not objects,
/// Sec. 4.3) with their centroids.
[[nodiscard]] SegmentSet collect_segments(std::span<const Vec3f> points, const SegmentationResult& seg);

/// The whole cloud as one set (registration without segments).
[[nodiscard]] SegmentSet whole_cloud(std::span<const Vec3f> points);

/// The mutually overlapping points of two sets, the source moved by T: source points within
/// `distance` of a target point and target points within it of a moved source point. `rmse` over
/// their nearest distances (+inf when none), `share` = their count / all points of both.
struct Overlap {
  double rmse = 0.0, share = 0.0;
};
[[nodiscard]] Overlap mutual_overlap(std::span<const Vec3f> source, std::span<const Vec3f> target,
                                     const Eigen::Isometry3d& T, double distance);

/// Step 5's acceptance test: overlap RMSE < e_icp, overlap share >= min_overlap and, when
/// segments were matched (nullopt: registration of whole clouds), >= min_matched_segments pairs.
[[nodiscard]] bool passes_acceptance(const Overlap& overlap, std::optional<int> matched_segments,
                                     const RegistrationAcceptanceConfig& config);

/// Beyond the paper: yaw + translation hypotheses from pairs of centroids — source pair (i, j)
/// onto target pair (k, l) when their horizontal lengths agree within d_match and the source
/// pair is at least min_centroid_baseline long — each verified against all centroids
/// (match_centroids). Kept with >= acceptance.min_matched_segments inliers; sorted by inliers,
/// then smaller largest distance; distinct (0.5 d_match, 5 deg) and at most
/// max_centroid_candidates.
[[nodiscard]] std::vector<std::pair<Eigen::Isometry3d, CentroidMatch>> centroid_hypotheses(
    std::span<const Vec3f> source_centroids, std::span<const Vec3f> target_centroids,
    const GlobalRegistrationConfig& config);

/// One refined candidate: its transform, the ICP's RMSE, the overlap there and, with segments,
/// the centroid matching after refinement (a refined transform may pair the centroids otherwise).
struct Refinement {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  double icp_rmse = 0.0;
  Overlap overlap;
  std::optional<CentroidMatch> matched;
};

/// Which candidate the loop returns: the first accepted in rank order (and stop there unless
/// `refine_all`), or the accepted one with the largest overlap (all refined).
struct RefineRule {
  bool largest_overlap = false;
  bool refine_all = false;
  int max_refinements = 1;
};

/// Step 5 for both paths: refines the reports in rank order — skipping a candidate that starts
/// where an earlier one started or ended (one ICP basin) — until max_refinements were refined or
/// `eligible(rank)` is false (the reports are sorted: none after it is), records each refinement
/// in its report (refined, T_target_source, T_world = to_world(T), rmse, overlap, icp_rmse,
/// accepted) and returns the chosen accepted rank. `refined` counts the refinements.
[[nodiscard]] std::optional<std::size_t> refine_and_accept(
    std::vector<CandidateReport>& reports, const std::function<bool(std::size_t)>& eligible,
    const std::function<Refinement(std::size_t, const Eigen::Isometry3d&)>& refine,
    const std::function<Eigen::Isometry3d(const Eigen::Isometry3d&)>& to_world,
    const RegistrationAcceptanceConfig& acceptance, const RefineRule& rule, int& refined);

/// Step 6's objects: every matched pair (source moved by T) concatenated and voxelised into
/// `merged_segments` and `objects`; an unmatched segment that touches a merged object
/// (absorb_min_points within absorb_distance) joins it, the others are objects of their own.
void merge_objects(const SegmentSet& src, const SegmentSet& tgt, const CentroidMatch& matched,
                   const Eigen::Isometry3d& T, const Vec3d& origin, const GlobalRegistrationConfig& config,
                   GlobalRegistrationResult& result);

}  // namespace cairn
