#include "cairn/eval/registration_scoring.hpp"

#include "cairn/core/error.hpp"
#include "cairn/core/io/io.hpp"
#include "cairn/core/io/trajectory.hpp"
#include "cairn/segmentation/evaluation.hpp"
#include "cairn/sim/simulation.hpp"

namespace cairn::eval {

MetricDrone load_metric_drone(const io::RunDirectory& run, const ScaleRecoveryConfig& config) {
  if (run.drone_cloud.empty() || run.drone_sparse.empty() || run.drone_vins.empty())
    throw InputError("run directory " + run.root.string() + " holds no drone survey (drone/cloud.ply, drone/sparse, "
                     "drone/vins_trajectory.tum)");
  MetricDrone d;
  d.scale = recover_scale(io::read_colmap_text(run.drone_sparse), io::read_tum_trajectory(run.drone_vins), config);
  d.cloud = io::load_cloud(run.drone_cloud);
  transform_cloud(d.cloud, d.scale.T_metric_sfm);
  d.T_map_metric_true = sim::read_drone_truth(run.root) * d.scale.T_metric_sfm.inverse();
  d.scale_error = d.T_map_metric_true.scale - 1.0;
  return d;
}

RegistrationTruth load_registration_truth(const io::RunDirectory& run, int num_stones) {
  RegistrationTruth t;
  t.snapshot = io::load_cloud(run.truth_dir() / "map_snapshot.ply");
  if (t.snapshot.labels.size() != t.snapshot.size())
    throw InputError("truth/map_snapshot.ply carries no per-point labels");
  t.num_stones = num_stones;
  std::size_t n = 0;
  for (std::size_t i = 0; i < t.snapshot.size(); ++i)
    if (t.snapshot.labels[i] >= 0) {
      t.site_centre += t.snapshot.world(i);
      ++n;
    }
  if (n > 0) t.site_centre /= double(n);
  return t;
}

ScoredRegistration score_registration(const GlobalRegistrationResult& r, const MetricDrone& drone,
                                      const RegistrationTruth& truth) {
  ScoredRegistration s;
  s.accepted = r.success;
  s.error = registration_error(Similarity::from_isometry(r.T_target_source), drone.T_map_metric_true, truth.site_centre);
  if (!r.success || r.objects.empty()) return s;
  // The scene's objects after registration: merged pairs, and the segments only one cloud holds
  // (a stone out of the LiDAR's view so far is still an object of the drone cloud).
  PointCloud all;
  std::vector<std::int32_t> labels;
  all.origin = r.objects.front().cloud.origin;
  for (std::size_t k = 0; k < r.objects.size(); ++k) {
    const PointCloud& seg = r.objects[k].cloud;
    for (std::size_t i = 0; i < seg.size(); ++i) {
      all.points.push_back((seg.world(i) - all.origin).cast<float>());
      labels.push_back(std::int32_t(k));
    }
  }
  const SegmentationScore score = score_against_truth(all, labels, truth);
  s.single_stones = score.found(kSingleObjectShare);
  s.objects_score = score.to_json(kSingleObjectShare);
  s.every_stone_single = int(s.single_stones) == truth.num_stones;
  s.success = s.accepted && s.every_stone_single;
  return s;
}

SegmentationScore score_against_truth(const PointCloud& cloud, const std::vector<std::int32_t>& labels,
                                      const RegistrationTruth& truth) {
  return score_segmentation(labels, transfer_labels(truth.snapshot, cloud, kTruthTransferDistance), truth.num_stones);
}

nlohmann::json ScoredRegistration::to_json() const {
  return {{"accepted", accepted},
          {"single_stones", single_stones},
          {"every_stone_single", every_stone_single},
          {"success", success},
          {"rotation_error_deg", error.rotation_deg},
          {"translation_error_m", error.translation_m},
          {"objects_score", objects_score}};
}

MapRelativeError error_against_map(const Eigen::Isometry3d& T_map_source, const MetricDrone& drone,
                                   const RegistrationTruth& truth, const ObjectSurfaceTruth& true_objects,
                                   const PointCloud& map) {
  const Similarity T_map_world = Similarity::from_isometry(true_objects.map_offset(map).inverse());
  const Vec3d centre_in_map = T_map_world * truth.site_centre;
  return {.error = registration_error(Similarity::from_isometry(T_map_source), T_map_world * drone.T_map_metric_true,
                                      centre_in_map),
          .map_offset_m = (centre_in_map - truth.site_centre).norm()};
}

}  // namespace cairn::eval
