#pragma once
// Segment-based global registration (paper Sec. 4.4): aligns a source map (the drone's
// photogrammetry cloud, metric) to a target map (the LiDAR map) through their segments.
//
//   1 voxel grid on the source (res_voxel) · segmentation of both maps (Sec. 4.3)
//   2 ISS keypoints (R_iss) + SHOT descriptors (R_shot) on the object segments only
//   3 nearest neighbours in descriptor space (kd-tree)
//   4 geometric-consistency grouping → the b most-voted transforms; centroid verification: source
//     segment centroids moved by each candidate, matched to the nearest target centroid within
//     d_match; most inlier centroids wins, ties → smaller largest centroid distance
//   5 ICP on the matched segments only; accepted by the overlap-RMSE test (below)
//   6 merge: every matched segment pair concatenated and voxelised; the source joins the map
//
// Beyond the paper:
// - The source need not be gravity-aligned: unless `gravity_aligned`, it is levelled for the
//   segmentation (its dominant plane — the ground seen from above — turned to z up) and the
//   descriptor stages are 6-DoF anyway. With `gravity_aligned`, candidates that tilt z are
//   dropped and ICP estimates yaw + translation only.
// - Up to `max_refinements` candidates are refined in the verification order until one passes
//   the acceptance test (the paper refines only the first one).
// - Acceptance test. The drone sees the stones' tops, the LiDAR mostly their sides: an RMSE over
//   all points of the matched segments mixes in points without a counterpart and exceeds 3 cm at
//   the true pose. The test uses the *mutually overlapping* points instead: source points within
//   `overlap_distance` of the target's matched segments and target points within it of the
//   source's. Accepted when their RMSE < e_icp, they are at least `min_overlap` of all matched
//   points, and at least `min_matched_segments` segments matched (docs/registration.md shows the
//   distributions for right and wrong candidates).
#include <optional>
#include <span>
#include <vector>

#include "cairn/core/log.hpp"
#include "cairn/core/normals.hpp"
#include "cairn/core/point_cloud.hpp"
#include "cairn/core/transform.hpp"
#include "cairn/core/voxel_grid.hpp"
#include "cairn/features/iss.hpp"
#include "cairn/features/matching.hpp"
#include "cairn/features/shot.hpp"
#include "cairn/registration/consistency_grouping.hpp"
#include "cairn/registration/max_clique.hpp"
#include "cairn/registration/icp.hpp"
#include "cairn/registration/scale_check.hpp"
#include "cairn/segmentation/segmenter.hpp"

namespace cairn {

struct RegistrationAcceptanceConfig {
  double e_icp = 0.03;            // Table 3: RMSE threshold e*_icp [m]
  double overlap_distance = 0.05; // a point overlaps when its nearest counterpart is closer [m]
  // Right candidates overlap 0.53-0.82 on the simulator, wrong ones (incl. a mirrored site that
  // does not exist) 0.02-0.33 with RMSEs of 2.8-3.3 cm: 0.25 let 8 of 90 mirrored-site candidates
  // through (docs/registration.md).
  double min_overlap = 0.45;      // share of the matched segments' points that must overlap
  int min_matched_segments = 3;   // fewer matched segment pairs: refused

  template <class V>
  void visit(V& v) {
    v("e_icp", e_icp, "ICP RMSE threshold e*_icp over the mutually overlapping points [m] (Table 3)");
    v("overlap_distance", overlap_distance, "a point overlaps when its nearest counterpart is closer than this [m]");
    v("min_overlap", min_overlap,
      "minimum share of the compared points that overlap (the matched segments'; without segments the whole clouds')");
    v("min_matched_segments", min_matched_segments, "minimum number of matched segment pairs");
  }
};

/// Levelling of a source in an arbitrary frame (not gravity-aligned): its ground plane is turned
/// onto the target's.
struct LevellingConfig {
  double plane_distance = 0.10;  // RANSAC inlier threshold of the ground plane [m] (Table 3 d_plane)
  double min_share = 0.2;        // a ground plane must hold this share of the points
  double refit_band = 0.3;       // least-squares refits use points within this of the plane [m]
  int refits = 3;
  double sign_cell = 2.0;        // cell size of the up/down vote [m] (larger than a stone's half width)
  std::size_t sign_min_points = 20;  // cells with fewer points do not vote
  double sign_min_tail = 0.15;   // a cell votes when its 5-95 % height tail exceeds this [m] ...
  double sign_tail_ratio = 2.0;  // ... and is this many times longer on one side than the other

  template <class V>
  void visit(V& v) {
    v("plane_distance", plane_distance, "RANSAC inlier threshold of the ground plane [m]");
    v("min_share", min_share, "minimum share of points on the ground plane");
    v("refit_band", refit_band, "band of the least-squares refits of the ground plane [m]");
    v("refits", refits, "number of least-squares refits");
    v("sign_cell", sign_cell, "cell size of the up/down vote [m]");
    v("sign_min_points", sign_min_points, "points a cell needs to vote");
    v("sign_min_tail", sign_min_tail, "minimum height tail of a voting cell [m]");
    v("sign_tail_ratio", sign_tail_ratio, "ratio of the long to the short height tail of a voting cell");
  }
};

struct GlobalRegistrationConfig {
  /// Sec. 4.4 segments both clouds and describes their object segments only. false: keypoints
  /// and descriptors on the whole (voxelised) clouds, no levelling, and up to max_refinements
  /// distinct candidates (in vote order; one that starts where an earlier one started or ended is
  /// skipped) are refined by ICP on the whole clouds; the accepted one with the largest overlap wins (scenes without a ground plane or objects, e.g. indoor RGB-D fragments).
  /// Normals then point towards normals.viewpoint (a sensor at each cloud's origin).
  bool segments = true;
  VoxelGridConfig source_voxel;  // step 1 (res_voxel, Table 3)
  NormalConfig normals{.radius = 0.1, .k = 0};  // for SHOT (surface normals of the segments)
  IssConfig iss;
  ShotConfig shot;
  MatchConfig matching;
  // Drone vs LiDAR keypoints repeat to about R_shot, not to PCL's few millimetres: a 10 cm
  // consensus, clusters of more than 3 votes, and the 30 most-voted groups (Table 3's b = 10
  // lost the right group among wrong ones on the simulator; centroid verification is cheap).
  GroupingConfig grouping{.consensus_size = 0.1, .min_votes = 3, .max_candidates = 30};
  /// Candidates from the descriptor correspondences: the paper's geometric consistency grouping
  /// (Sec. 4.4 step 4: the b most-voted clusters), or with max_clique.enabled (beyond the paper,
  /// TEASER++'s inlier selection) the largest pairwise-consistent set, one candidate.
  MaxCliqueConfig max_clique;
  double d_match = 1.0;          // Table 3: max. distance between matched centroids [m]
  int max_refinements = 5;       // candidates refined until one is accepted
  /// Refine all max_refinements candidates even after one is accepted (the first accepted one is
  /// still the answer): for studying the acceptance test on right and wrong candidates.
  bool refine_all = false;
  /// Beyond the paper: also hypothesise yaw + translation from pairs of segment centroids (the
  /// levelled source is gravity-aligned up to the levelling error), verified like the descriptor
  /// candidates. Stones seen from above (drone) and from the side (LiDAR) share few repeatable
  /// keypoints; their centroids still form the same constellation (within d_match).
  bool centroid_hypotheses = true;
  double min_centroid_baseline = 1.0;  // [m] centroid pairs closer than this give no hypothesis
  int max_centroid_candidates = 30;    // best-verified centroid hypotheses kept
  IcpConfig icp{.objective = "point_to_plane", .kernel = "huber", .kernel_scale = 0.03,
                .max_correspondence_distance = 0.15, .max_iterations = 40};
  /// ICP runs twice: first with this correspondence distance (the coarse transform from a
  /// consistency group is decimetres off), then with icp.max_correspondence_distance.
  double coarse_correspondence_distance = 0.4;
  /// The first pass only brings the candidate into the second one's basin: it runs on the source
  /// thinned by a voxel grid of this size (0: every point); the second pass uses every point.
  double coarse_source_voxel = 0.05;  // [m]
  RegistrationAcceptanceConfig acceptance;
  bool gravity_aligned = false;  // source z is up: 4-DoF candidates and ICP
  LevellingConfig levelling;     // when not gravity_aligned
  double max_tilt_deg = 10.0;    // gravity_aligned: candidates tilting z more than this are dropped
  double merge_voxel = 0.03;     // step 6 voxel (res_voxel)
  /// The source (a drone cloud) is seen from above: a rounded stone shows few steep sides. Drone
  /// stones measured 0.03-0.6 as stacked fraction on the simulator, terrain pieces at the cloud's
  /// border 0.0; this threshold replaces segmentation.verticality.min_stacked_fraction for the
  /// source (negative: the segmentation's own).
  double source_min_stacked_fraction = 0.02;
  /// An unmatched segment with at least absorb_min_points points within absorb_distance of a
  /// merged object (after alignment) is a piece of it and joins it (clustering tolerance).
  double absorb_distance = 0.1;  // [m]
  std::size_t absorb_min_points = 10;

  /// Beyond the paper: the accepted alignment's matched segments must not fit a similarity of
  /// another scale (a source whose scale is off is refused; scale_check.estimate: register_drone
  /// rescales and registers again).
  ScaleCheckConfig scale_check;

  template <class V>
  void visit(V& v) {
    v("segments", segments,
      "segment both clouds and describe their object segments (Sec. 4.4); false: descriptors on the whole clouds, "
      "candidates verified by ICP overlap (scenes without ground or objects)");
    v("source_voxel", source_voxel, "voxel grid applied to the source before segmentation (Sec. 4.4 step 1)");
    v("normals", normals, "surface normals for the SHOT descriptors");
    v("iss", iss, "ISS keypoints (R_iss, Table 3)");
    v("shot", shot, "SHOT descriptors (R_shot, Table 3)");
    v("matching", matching, "descriptor matching");
    v("grouping", grouping, "geometric-consistency grouping (b, Table 3)");
    v("max_clique", max_clique, "maximum-clique inlier selection instead of the grouping (when enabled)");
    v("d_match", d_match, "max. distance between matched segment centroids [m] (Table 3)");
    v("max_refinements", max_refinements, "candidates refined by ICP (in verification order) until one is accepted");
    v("refine_all", refine_all, "refine all max_refinements candidates (acceptance-test study); the first accepted wins");
    v("centroid_hypotheses", centroid_hypotheses,
      "also hypothesise yaw + translation from pairs of segment centroids (beyond the paper)");
    v("min_centroid_baseline", min_centroid_baseline, "centroid pairs closer than this give no hypothesis [m]");
    v("max_centroid_candidates", max_centroid_candidates, "best-verified centroid hypotheses kept");
    v("icp", icp, "ICP refinement on the matched segments");
    v("coarse_correspondence_distance", coarse_correspondence_distance,
      "correspondence distance of the first ICP pass from the coarse transform [m]");
    v("coarse_source_voxel", coarse_source_voxel,
      "voxel size thinning the source for the first ICP pass (0: every point) [m]");
    v("acceptance", acceptance, "acceptance test of a refined candidate");
    v("scale_check", scale_check, "refusing a source whose scale is off (a similarity fits the matches better)");
    v("gravity_aligned", gravity_aligned, "the source's z axis is up: 4-DoF candidates and ICP");
    v("levelling", levelling, "turning an arbitrarily rotated source's ground onto the target's");
    v("max_tilt_deg", max_tilt_deg, "gravity_aligned: drop candidates tilting z by more than this [deg]");
    v("merge_voxel", merge_voxel, "voxel size of the merged segments and map [m]");
    v("source_min_stacked_fraction", source_min_stacked_fraction,
      "terrain check threshold for the source seen from above (negative: the segmentation's)");
    v("absorb_distance", absorb_distance, "unmatched segments this close to a merged object join it [m]");
    v("absorb_min_points", absorb_min_points, "points an unmatched segment needs within absorb_distance to join");
  }
  void validate() const;
};

/// One refined or verified candidate (for diagnostics and the acceptance-test study).
struct CandidateReport {
  std::string origin = "descriptors"; // "descriptors" (consistency group) or "centroids"
  std::size_t votes = 0;             // correspondences in its consistency group
  int centroid_inliers = 0;          // matched centroids within d_match
  double max_centroid_distance = 0;  // [m] largest distance among them
  bool refined = false;
  double rmse = 0;                   // [m] overlap RMSE after ICP
  double overlap = 0;                // share of matched-segment points that overlap
  double icp_rmse = 0;               // [m] the ICP's own RMSE over its inliers
  bool accepted = false;
  Eigen::Isometry3d T_target_source = Eigen::Isometry3d::Identity();  // coarse, or refined when refined
  Eigen::Isometry3d T_world = Eigen::Isometry3d::Identity();  // the same between the clouds' world frames
};

struct GlobalRegistrationResult {
  bool success = false;
  std::string reason;  // why not, when !success
  Eigen::Isometry3d T_target_source = Eigen::Isometry3d::Identity();  // world coordinates (origins honoured)
  double rmse = 0;     // [m] overlap RMSE of the accepted candidate
  /// The similarity fit of the accepted candidate's matched segments (scale_check): a scale
  /// beyond 1 ± max_scale_error refuses it (reason "scale ...").
  ScaleFit scale_fit;
  double overlap = 0;
  std::vector<std::pair<std::int32_t, std::int32_t>> matched_segments;  // (source id, target id)
  std::size_t candidates = 0;           // transforms from the grouping
  std::size_t centroid_candidates = 0;  // transforms from centroid pairs
  std::vector<CandidateReport> reports; // verification order
  std::size_t source_points = 0, target_points = 0;  // after the source voxel grid
  std::size_t source_segments = 0, target_segments = 0;
  std::size_t source_keypoints = 0, target_keypoints = 0, correspondences = 0;
  /// segmentation_source, segmentation_target, keypoints, descriptors, matching, verification,
  /// refinement, merge (total = sum; the paper's Table 1 stages).
  Timings timings;
  PointCloud source_voxelised;            // the source after step 1 (source frame)
  SegmentationResult source_segmentation, target_segmentation;
  std::vector<PointCloud> merged_segments;  // per matched pair (target frame), when success
  /// Every object of the registered scene (target frame), when success: the merged pairs first
  /// (same order as merged_segments, plus unmatched pieces that touch them), then the source
  /// segments without a match (e.g. stones only the drone saw), then the target segments without
  /// one. Ids of the segments, -1 where none.
  struct Object {
    PointCloud cloud;
    std::int32_t source_segment = -1, target_segment = -1;
  };
  std::vector<Object> objects;
  PointCloud merged_map;                    // target + aligned source, voxelised, when success
};

/// Registers `source` to `target`. Both must be metric. Throws InputError on empty or non-finite
/// input, ConfigError on a bad config. Never reports success for a candidate that fails the
/// acceptance test.
[[nodiscard]] GlobalRegistrationResult register_global(const PointCloud& source, const PointCloud& target,
                                                       const SegmentationConfig& segmentation,
                                                       const GlobalRegistrationConfig& config);

/// Centroid verification (Sec. 4.4): the source centroids moved by T, each matched one-to-one
/// (closest pairs first) to a target centroid within d_match. A candidate with more `inliers`
/// wins; ties go to the smaller `max_distance`. `pairs` are (source index, target index), sorted.
struct CentroidMatch {
  int inliers = 0;
  double max_distance = 0.0;  // [m]
  std::vector<std::pair<std::int32_t, std::int32_t>> pairs;
};
[[nodiscard]] CentroidMatch match_centroids(std::span<const Vec3f> source_centroids,
                                            std::span<const Vec3f> target_centroids, const Eigen::Isometry3d& T,
                                            double d_match);

/// Error of an estimated source-to-target similarity against the truth, where it matters: the
/// rotation angle of E = estimate · truth⁻¹ (≈ identity on the target) and the displacement E
/// gives to `at`, a target point such as the site centre (a bare translation difference would
/// charge the rotation error times the distance to the source frame's far-away origin).
struct RegistrationError {
  double rotation_deg = 0.0;
  double translation_m = 0.0;
  double scale_ratio = 1.0;  // estimate.scale / truth.scale
};
[[nodiscard]] RegistrationError registration_error(const Similarity& estimate, const Similarity& truth, const Vec3d& at);

/// Normal of the dominant plane of `points` (the ground): RANSAC, then least-squares refits over
/// a wider band; oriented so that objects stand on it (cells whose heights have a long upward
/// tail outvote those with a long downward tail). nullopt when no plane holds `min_share`.
[[nodiscard]] std::optional<Vec3d> ground_normal(std::span<const Vec3f> points, const LevellingConfig& config = {});

/// The rotation that turns the ground normal of `points` onto `up` (yaw stays free). Identity
/// when no ground plane is found.
[[nodiscard]] Eigen::Matrix3d levelling_rotation(std::span<const Vec3f> points, const Vec3d& up = Vec3d::UnitZ(),
                                                 const LevellingConfig& config = {});

}  // namespace cairn
