#pragma once
// Parameters of grasp pose planning (paper Sec. 5). The paper's Table 3 gives none for this stage;
// its text gives the ranking's sizes (best 40 by alignment, then best 20 by enclosing, Sec. 5.4).
// Every length derives from the gripper (robot/gripper.hpp) and the planning cloud's voxel, so
// the same settings plan for a 1 m jaw on boulders and for a scaled gripper on GPD's small
// objects (docs/grasp.md).
#include <vector>
#include <string>

namespace cairn::grasp {

/// Sec. 5.2: the planning point cloud.
struct PlanningCloudConfig {
  /// Crop: the map within the object's horizontal extent grown by margin_factor times the
  /// gripper's full width (its widest part fully open), around the object's centroid.
  double margin_factor = 1.0;
  double voxel = 0.05;  // [m] uniform density after merging (the collision and contact resolution)
  /// Map points within this many voxels of the object's model are the object's points.
  double object_distance_voxels = 1.5;
  bool ground_fill = true;  // fill unobserved ground with points of a RANSAC ground plane (Fig. 6c)
  /// Beyond the paper: the fill follows the seen ground next to it (its height above the plane
  /// carried into the unseen columns) instead of lying on the plane. Off by default: over fresh
  /// seeds 5-20 the physics trials held 103 / 201 grasps with it and 98 / 201 without (McNemar
  /// p ~ 0.46, docs/grasp.md): no measurable gain.
  bool fill_follows_ground = false;
  double ground_distance = 0.10;  // [m] RANSAC inlier distance (Table 3's d_plane)
  double ground_max_tilt_deg = 30.0;  // the ground plane is within this of horizontal
  /// Normals: PCA over this many voxels' radius, oriented away from the object's centroid on the
  /// object and upwards elsewhere (GPD's trap: viewpoint-oriented normals point into occluded
  /// sides).
  double normal_radius_voxels = 3.0;
  template <class V>
  void visit(V& v) {
    v("margin_factor", margin_factor, "crop margin around the object in full gripper widths");
    v("voxel", voxel, "uniform density of the planning cloud [m]");
    v("object_distance_voxels", object_distance_voxels, "map points this many voxels from the model are object points");
    v("ground_fill", ground_fill, "fill unobserved ground with a RANSAC ground plane");
    v("fill_follows_ground", fill_follows_ground, "the fill follows the seen ground next to it (else: on the plane)");
    v("ground_distance", ground_distance, "RANSAC ground plane inlier distance [m] (Table 3 d_plane)");
    v("ground_max_tilt_deg", ground_max_tilt_deg, "largest tilt of the ground plane [deg]");
    v("normal_radius_voxels", normal_radius_voxels, "normal estimation radius in voxels");
  }
};

/// Sec. 5.3: candidates.
struct CandidateConfig {
  int samples = 100;  // N sample points on the object
  double lrf_radius_voxels = 4.0;  // r of Eq. 4's r-ball, in voxels
  /// Rotations of the local frame about its y and z axes (Sec. 5.3) and, beyond the paper, about
  /// the approach axis x (the closing direction of a top-down grasp on a flat stone) [deg].
  std::vector<double> rotations_y_deg = {-30.0, 0.0, 30.0};
  std::vector<double> rotations_z_deg = {-30.0, 0.0, 30.0};
  std::vector<double> rotations_x_deg = {0.0, 90.0};
  /// Beyond the paper: per sample, also approach along -n_ground (the direction Eq. 5 ranks
  /// best; GPD's approach-direction filter turned into sampling), closing along the object's
  /// shortest horizontal extent turned about the approach by these yaws [deg] (empty: off). A
  /// sample at the estimated centre of mass's top is added for them.
  std::vector<double> vertical_yaws_deg = {-30.0, 0.0, 30.0, 90.0};
  /// Pre-grasp openings as shares of the gripper's largest opening. Closing from fully open swings
  /// the tips 18 cm further along the approach (1 m jaws, 35 deg), into the ground under a low
  /// stone; from parallel jaws (0.55: 1.40 m, the pivots' spacing) the tips close upwards.
  std::vector<double> openings = {1.0, 0.55};
  /// Also try, per pose, the opening that clears the object's width across the approach axis by
  /// the padding on both sides (jaws that start close to the stone meet it together).
  bool fit_opening = true;
  /// The push collides the gripper with the planning cloud downsampled to this many voxels (the
  /// jaws are 12 cm thick: a 10 cm collision cloud touches within ~5 cm of the first contact,
  /// and costs a quarter); the closing uses the full resolution.
  double collision_voxels = 2.0;
  double clearance_voxels = 1.0;  // pushed until contact, then backed off by this many voxels
  /// The gripper's boxes are grown across the approach by this many voxels for the push: the map
  /// is off by the state estimate's drift (2-3 cm) and the object's unseen side is unknown, so the
  /// open jaws keep this much room to everything they pass on their way down.
  double padding_voxels = 2.0;
  /// The push starts with the jaw tips this many collision voxels before the sample point, so the whole
  /// approach from there is checked for collisions.
  double start_margin_voxels = 4.0;
  std::size_t min_object_points = 5;  // object points in the closing region (non-empty, Sec. 5.3)
  /// Back-offs along the approach tried in turn when the closing jaws would sweep into the
  /// environment (the tips into the ground under a flat stone), in voxels (0: the pushed pose
  /// itself); none goes behind the push's start.
  std::vector<double> backoff_voxels = {0.0, 2.0, 4.0, 6.0};
  /// The closing jaws keep this many voxels from every non-object point (the tips from the
  /// ground: the RANSAC plane is only d_plane certain; the centred baseline keeps 5 cm from the
  /// true terrain).
  double tip_clearance_voxels = 1.0;
  unsigned seed = 1;                  // sampling of the N points
  template <class V>
  void visit(V& v) {
    v("samples", samples, "N: sample points on the object (Sec. 5.3)");
    v("lrf_radius_voxels", lrf_radius_voxels, "r-ball of Eq. 4 in voxels");
    v("rotations_y_deg", rotations_y_deg, "rotations about the local frame's y axis [deg]");
    v("rotations_z_deg", rotations_z_deg, "rotations about the local frame's z axis [deg]");
    v("rotations_x_deg", rotations_x_deg, "rotations about the approach axis [deg] (beyond the paper)");
    v("backoff_voxels", backoff_voxels, "back-offs along the approach tried when the closing jaws hit the environment [voxels]");
    v("vertical_yaws_deg", vertical_yaws_deg,
      "approach along -n_ground too, closing along the shortest horizontal extent turned by these yaws [deg] (empty: off)");
    v("openings", openings, "pre-grasp openings as shares of the largest opening");
    v("fit_opening", fit_opening, "also try the opening fitted to the object's width per pose");
    v("collision_voxels", collision_voxels, "resolution of the collision cloud in voxels");
    v("clearance_voxels", clearance_voxels, "back-off after the first contact in voxels");
    v("padding_voxels", padding_voxels, "the gripper's boxes grown across the approach by this many voxels for the push");
    v("start_margin_voxels", start_margin_voxels, "the push starts this many voxels before the sample");
    v("tip_clearance_voxels", tip_clearance_voxels, "the closing jaws keep this far from non-object points [voxels]");
    v("min_object_points", min_object_points, "object points needed in the closing region");
    v("seed", seed, "seed of the sample selection");
  }
};

/// Sec. 5.4, decided analytically (the paper uses GPD's CNN): two soft contacts in force closure
/// when the line between them lies in both friction cones (Nguyen 1988), and robust when most
/// small perturbations of the pose and of mu keep it so (Dex-Net 2.0's robust force closure).
struct ForceClosureConfig {
  double mu = 0.6;  // friction coefficient rock-steel (the physics' default)
  /// Force closure is decided with mu / mu_safety: rock friction varies, and a contact loaded
  /// near its cone's edge creeps (MuJoCo's soft contacts do; the jaws' wire encoder then reports
  /// slip). 1.5: the contact line stays ~9 deg inside the 31 deg cone of mu = 0.6.
  double mu_safety = 1.5;
  /// Contact patch: object points within this many voxels of the first-touched point.
  double patch_voxels = 1.0;
  int perturbations = 16;  // robustness samples per grasp
  double sigma_translation_voxels = 1.0;  // pose noise (Gaussian, per axis), in voxels
  double sigma_rotation_deg = 3.0;        // pose noise (Gaussian, per axis)
  double sigma_mu = 0.1;                  // relative noise of mu (Gaussian)
  double min_robustness = 0.75;  // share of perturbations in force closure to keep a grasp
  /// Beyond the paper: two jaws resist turning about the line between their contacts only by
  /// torsional friction over their patches, so the centre of mass must lie close to the vertical
  /// plane through that line. Largest horizontal distance, in jaw heights (0.2: 10 cm).
  double max_lever_jaw_heights = 0.2;
  /// Beyond the paper: the angular jaws' squeeze pushes the object along the approach, towards
  /// the palm when the jaws converge at contact (angle < 0) and out past the tips when they
  /// diverge. Largest jaw angle at contact [deg] (0: parallel).
  double max_contact_angle_deg = 0.0;
  /// Beyond the paper: the coupled jaws touch one after the other unless the object sits midway
  /// between them; the first pushes it along the closing axis, sliding it over the ground and
  /// turning it. Largest predicted slide, in voxels. Executed in the physics, a 2-voxel limit
  /// rejected grasps that held (exp1 + exp2 seeds 1-2: 15/28 held with it, 20/28 without it;
  /// docs/grasp.md): the default only rejects slides as long as the jaw (20 voxels, 1 m).
  double max_shift_voxels = 20.0;
  unsigned seed = 7;
  template <class V>
  void visit(V& v) {
    v("mu", mu, "friction coefficient of the jaw contacts");
    v("mu_safety", mu_safety, "force closure is decided with mu / mu_safety");
    v("patch_voxels", patch_voxels, "contact patch radius in voxels");
    v("perturbations", perturbations, "robustness: perturbed copies of each grasp");
    v("sigma_translation_voxels", sigma_translation_voxels, "robustness: pose noise per axis in voxels");
    v("sigma_rotation_deg", sigma_rotation_deg, "robustness: rotation noise per axis [deg]");
    v("sigma_mu", sigma_mu, "robustness: relative noise of mu");
    v("min_robustness", min_robustness, "share of perturbations that must stay in force closure");
    v("max_lever_jaw_heights", max_lever_jaw_heights, "largest gravity lever about the contact line in jaw heights");
    v("max_shift_voxels", max_shift_voxels, "largest slide of the object while the jaws close, in voxels");
    v("max_contact_angle_deg", max_contact_angle_deg, "largest jaw angle at contact [deg] (> 0: diverging jaws)");
    v("seed", seed, "seed of the perturbations");
  }
};

/// Sec. 5.4: hierarchical ranking (Eq. 5-7).
struct RankingConfig {
  /// "hierarchical": the paper's (Sec. 5.4, Eq. 5-7). "closest" (beyond the paper): ordered by
  /// c_enc + c_dist, the palm's distance to the centre of mass along the approach plus the
  /// approach axis' distance from it, without the alignment filter. Executed in the physics
  /// (docs/grasp.md), the alignment filter did not predict success and the palm's closeness did.
  std::string method = "closest";
  int keep_align = 40;    // best by c_align (Eq. 5); keep_* apply to the hierarchical method only
  int keep_enclose = 20;  // of those, best by c_enc (Eq. 6); then ordered by c_dist (Eq. 7)
  int output = 10;        // ranked grasps returned
  template <class V>
  void visit(V& v) {
    v("method", method, "hierarchical (the paper's Eq. 5-7) | closest (by c_enc + c_dist, beyond the paper)");
    v("keep_align", keep_align, "grasps kept by the alignment cost (Eq. 5)");
    v("keep_enclose", keep_enclose, "grasps kept by the enclosing cost (Eq. 6)");
    v("output", output, "ranked grasps returned");
  }
};

struct GraspConfig {
  PlanningCloudConfig cloud;
  CandidateConfig candidates;
  ForceClosureConfig force_closure;
  RankingConfig ranking;
  template <class V>
  void visit(V& v) {
    v("cloud", cloud, "planning point cloud (Sec. 5.2)");
    v("candidates", candidates, "grasp candidates (Sec. 5.3)");
    v("force_closure", force_closure, "force closure and robustness (Sec. 5.4)");
    v("ranking", ranking, "hierarchical ranking (Sec. 5.4, Eq. 5-7)");
  }
  /// Throws ConfigError naming the first invalid field.
  void validate() const;
};

}  // namespace cairn::grasp
