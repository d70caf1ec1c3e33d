#pragma once
// Registration of a simulator run's drone cloud into a LiDAR map, scored against the run's truth
// (the paper's protocol, Sec. 6.2): shared by `cairn pipeline` and `cairn protocol`.
#include <nlohmann/json.hpp>

#include "cairn/core/io/run_dir.hpp"
#include "cairn/eval/map_scoring.hpp"
#include "cairn/mapping/mapper.hpp"
#include "cairn/registration/global_registration.hpp"
#include "cairn/registration/scale_recovery.hpp"
#include "cairn/segmentation/evaluation.hpp"

namespace cairn::eval {

/// The drone cloud of a run, scaled into the metric (VINS) frame by scale recovery (Sec. 4.1),
/// and the true map-from-metric similarity (truth/drone.json composed with the recovered scale).
struct MetricDrone {
  PointCloud cloud;
  ScaleRecoveryResult scale;
  Similarity T_map_metric_true;
  double scale_error = 0.0;  // T_map_metric_true.scale - 1 (what scale recovery missed)
};
/// Throws InputError when the run has no drone survey.
[[nodiscard]] MetricDrone load_metric_drone(const io::RunDirectory& run, const ScaleRecoveryConfig& config);

/// Truth of a run for scoring registrations: the labelled dense snapshot and the site centre.
struct RegistrationTruth {
  PointCloud snapshot;  // truth/map_snapshot.ply (labels: stone index, -1 terrain)
  int num_stones = 0;
  Vec3d site_centre = Vec3d::Zero();  // mean of the stones' points: where the error is measured
};
[[nodiscard]] RegistrationTruth load_registration_truth(const io::RunDirectory& run, int num_stones);

/// A scored point takes the truth label of the nearest truth-snapshot point within this distance
/// (the map's 3 cm voxels plus range noise); farther points count as none.
inline constexpr double kTruthTransferDistance = 0.06;  // [m]
/// A stone is a single object when one segment holds this share of its points.
inline constexpr double kSingleObjectShare = 0.95;

/// A segmentation of `cloud` (`labels`, one per point) scored against the run's truth.
[[nodiscard]] SegmentationScore score_against_truth(const PointCloud& cloud, const std::vector<std::int32_t>& labels,
                                                    const RegistrationTruth& truth);

/// One registration scored as in the paper's protocol: accepted (RMSE < e_icp over the overlap),
/// every stone a single object of the registered scene (GlobalRegistrationResult::objects: the
/// merged pairs plus the segments only one cloud holds), and the error against the truth.
struct ScoredRegistration {
  bool accepted = false;
  std::size_t single_stones = 0;  // stones that are exactly one object (>= 95 % of their points in it)
  bool every_stone_single = false;
  bool success = false;           // accepted && every_stone_single
  RegistrationError error;
  nlohmann::json objects_score;   // per-stone completeness and purity over the objects
  [[nodiscard]] nlohmann::json to_json() const;
};
[[nodiscard]] ScoredRegistration score_registration(const GlobalRegistrationResult& r, const MetricDrone& drone,
                                                    const RegistrationTruth& truth);

/// A registration's error against the map as built: the truth moved by the map's own rigid
/// offset at the stones (ObjectSurfaceTruth::map_offset; the GNSS/INS error no relative
/// constraint observes), measured at the site centre; and that offset's displacement there.
struct MapRelativeError {
  RegistrationError error;
  double map_offset_m = 0.0;
};
[[nodiscard]] MapRelativeError error_against_map(const Eigen::Isometry3d& T_map_source, const MetricDrone& drone,
                                                 const RegistrationTruth& truth, const ObjectSurfaceTruth& true_objects,
                                                 const PointCloud& map);

}  // namespace cairn::eval
