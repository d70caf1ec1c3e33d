#pragma once
// Parameters of the object database's map updates (Sec. 4.5), Table 3 values as defaults.
#include <string>

#include "cairn/objects/support_config.hpp"

namespace cairn {

/// Which map points a grasp removes (Sec. 4.5).
struct GraspRemovalConfig {
  std::string method = "object_voxels";  // "object_voxels" | "sphere" (the paper)
  double R_obj = 1.0;                    // [m] Table 3: the sphere; the upper bound of object_voxels
  double distance = 0.05;  // [m] object_voxels: map voxels within this of the object's points
                           // (≈ res_voxel·√3, the 3 cm voxel's diagonal: the cloud dilated by a voxel)
  template <class V>
  void visit(V& v) {
    v("method", method, "object_voxels (the object's own voxels, bounded by the sphere) or sphere (the paper)");
    v("R_obj", R_obj, "radius of the removal sphere around the object's centroid [m] (Table 3)");
    v("distance", distance, "object_voxels: map voxels within this distance of the object's points go [m]");
  }
};

/// The ICP that re-aligns a released object's cloud to the rescanned map (Sec. 4.5), and when its
/// result is believed.
struct RealignConfig {
  double crop_margin = 0.3;          // [m] map points within the object's radius + this are used
  double coarse_distance = 0.25;     // [m] first ICP stage: correspondences up to this
  double fine_distance = 0.05;       // [m] second stage
  int max_iterations = 40;           // per stage
  double inlier_distance = 0.03;     // [m] a model point with a map point this close is seen
  double min_fitness = 0.35;         // share of model points seen (the hidden bottom is never seen)
  double max_rmse = 0.02;            // [m] over the inliers (looser lets wrong fits of a rolled stone through)
  double report_translation = 0.05;  // [m] larger corrections are reported (the stone fell or rolled;
                                     // Eq. 3 alone is off by the state estimate's drift, 1-3 cm)
  double report_rotation_deg = 5.0;
  double search_radius = 2.0;        // [m] not found near the prediction: segments this close searched
  double search_min_fitness = 0.7;   // share of a searched segment's points on the model
  double search_max_rmse = 0.03;     // [m] RMS distance of those points (each within the association's
                                     // overlap_distance, 5 cm) to the model's nearest: the model is one
                                     // partial view, the segment another; association.max_rmse (2 cm)
                                     // refused 14 of exp2's searched fits with 70-99 % of the segment on
                                     // the model at 2.1-2.9 cm. Looser only because a segment that is
                                     // another object's is never taken (relocate_object)
  double max_direct_translation = 0.4;  // [m] ICP from the prediction moving farther, or turning
  double max_direct_rotation_deg = 30.0;  //     more, slid off: the search decides instead
  template <class V>
  void visit(V& v) {
    v("crop_margin", crop_margin, "map points within the object's radius plus this are matched [m]");
    v("coarse_distance", coarse_distance, "first ICP stage: maximum correspondence distance [m]");
    v("fine_distance", fine_distance, "second ICP stage: maximum correspondence distance [m]");
    v("max_iterations", max_iterations, "ICP iterations per stage");
    v("inlier_distance", inlier_distance, "a model point with a map point this close counts as seen [m]");
    v("min_fitness", min_fitness, "minimum share of model points seen, else the object is lost");
    v("max_rmse", max_rmse, "maximum RMS distance of the seen points, else the object is lost [m]");
    v("report_translation", report_translation, "corrections above this are reported as fell/rolled [m]");
    v("report_rotation_deg", report_rotation_deg, "corrections above this are reported as fell/rolled [deg]");
    v("search_radius", search_radius, "not found near the prediction: object segments this close are searched [m]");
    v("search_min_fitness", search_min_fitness, "share of a searched segment's points that must lie on the model");
    v("search_max_rmse", search_max_rmse, "RMS distance of a searched segment's points to the model's nearest points [m]");
    v("max_direct_translation", max_direct_translation, "ICP from the prediction moving farther is not believed [m]");
    v("max_direct_rotation_deg", max_direct_rotation_deg, "ICP from the prediction turning more is not believed [deg]");
  }
};

/// Re-segmentation: which segment is which object (Sec. 4.5, extended).
struct AssociationConfig {
  double overlap_distance = 0.05;   // [m] a segment point this close to an object's points is shared
  double min_overlap = 0.5;         // share of a segment's points shared with an object to match it
  double min_support = 0.6;         // share of an object's points with a map point near: still there
                                    // (its lowest points always have ground near them)
  double search_radius = 3.0;       // [m] a segment this close may be an object that moved
  double min_fitness = 0.8;         // moved object: share of the segment's points on the model
  double max_rmse = 0.02;           // [m] moved object: over those points
  int yaw_seeds = 8;                // ICP starts, yaw steps about the vertical
  double in_view_radius = 0.5;      // [m] an object with map points this close to its centroid
  int in_view_min_points = 20;      //     (at least this many) is in view: missing means lost
  int min_segment_points = 50;      // smaller unmatched segments do not become objects
  double distinct_rotation_deg = 30.0;  // [deg] fits turned more than this apart are different poses
  double ambiguity_margin = 0.05;   // a different pose within this fitness of the best: ambiguous
  template <class V>
  void visit(V& v) {
    v("overlap_distance", overlap_distance, "segment points this close to an object's points are shared [m]");
    v("min_overlap", min_overlap, "share of a segment's points shared with an object to match it");
    v("min_support", min_support, "share of an object's points with a map point near it: the object is still there");
    v("search_radius", search_radius, "an unmatched segment this close may be an object that moved [m]");
    v("min_fitness", min_fitness, "a moved object: share of the segment's points on the model");
    v("max_rmse", max_rmse, "a moved object: RMS distance of those points [m]");
    v("yaw_seeds", yaw_seeds, "ICP starting yaws for a moved object");
    v("in_view_radius", in_view_radius, "map points this close to an object's centroid put it in view [m]");
    v("in_view_min_points", in_view_min_points, "at least this many map points put an object in view");
    v("min_segment_points", min_segment_points, "smaller unmatched segments do not become objects");
    v("distinct_rotation_deg", distinct_rotation_deg, "fits turned more than this apart are different poses [deg]");
    v("ambiguity_margin", ambiguity_margin, "a different pose within this share of the best fit's fitness makes it ambiguous");
  }
};

struct ObjectsConfig {
  GraspRemovalConfig grasp_removal;
  RealignConfig realign;
  AssociationConfig association;
  SupportConfig support;
  template <class V>
  void visit(V& v) {
    v("grasp_removal", grasp_removal, "map points removed when an object is grasped (Sec. 4.5)");
    v("realign", realign, "ICP re-alignment of a released object to the rescanned map (Sec. 4.5)");
    v("association", association, "segments of a re-segmentation matched to stored objects");
    v("support", support, "which object rests on which: the pick order on a pile (issue #21)");
  }
  /// Throws ConfigError naming the key of a value out of range.
  void validate() const;
};

}  // namespace cairn
