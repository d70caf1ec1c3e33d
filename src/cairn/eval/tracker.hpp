#pragma once
// The machine that keeps an object database true while it moves stones (Sec. 4.5), shared by the
// object-tracking experiment (object_tracking.hpp: rigid carries) and the paper's experiments
// end to end (experiment.hpp: planned grasps executed in the physics). One settled world, one
// Mapper, one database; every move is grasp → carry → release (Eq. 3) → rescan → re-align, scored
// against the truth in the map's frame (the map's own rigid offset at the stones removed).
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <span>
#include <vector>

#include "cairn/eval/object_tracking.hpp"
#include "cairn/eval/scanned_site.hpp"
#include "cairn/objects/object_db.hpp"
#include "cairn/objects/updates.hpp"

namespace cairn::eval {

/// The cumulative transform of an object's history after its creation (world frame).
[[nodiscard]] Eigen::Isometry3d db_motion(const std::vector<PoseUpdate>& history);

/// The gripper T_MG of a rigid carry (the object-tracking experiment's grasps are not planned):
/// top down on the object's top above its centroid (x down, y across).
[[nodiscard]] Eigen::Isometry3d top_down_hold(const ObjectRecord& obj);

class Tracker {
 public:
  /// A stone and the object that stands for it, with the truth needed to score the object.
  struct Tracked {
    int stone = 0;
    std::int64_t object = 0;
    Vec3d created_centroid = Vec3d::Zero();
    Eigen::Isometry3d E0 = Eigen::Isometry3d::Identity();  // map offset when the object was created
    Eigen::Isometry3d M = Eigen::Isometry3d::Identity();   // true motion since then (world)
    double purity = 0.0;                                   // share of its points on its stone
  };

  /// `duration`: the simulated time the machine's state estimate and sweeps must cover.
  Tracker(const ObjectTrackingConfig& c, const TrackingProgress& progress, double duration);
  ~Tracker();
  Tracker(const Tracker&) = delete;
  Tracker& operator=(const Tracker&) = delete;

  void initial_scan();
  /// Segments the map, fills the database and matches every object to its stone (truth).
  void populate();
  /// Moves every tracked stone once (rigid carries to free slots), then re-segments.
  void run_round(int round);
  /// The round's re-segmentation of the rescanned map: every segment should be a known object.
  void resegment(RoundRecord& rr);
  /// Objects of the database not yet tracked that lie on a stone no object tracks (truth), the
  /// only one on it, are tracked from now on (a pile's stone that came out merged with its
  /// neighbour and stands alone after the neighbour was picked). Returns how many.
  int adopt_new_objects();

  // Steps shared by every kind of move.
  /// The true surfaces now: computed again only when a stone moved or the base did (the
  /// experiments ask for them several times per move; scoring only). Not thread-safe (a cache).
  [[nodiscard]] std::shared_ptr<const SurfaceTruth> truth() const;
  /// Both grasp edits counted on `map`, the grasp committed, its map edit applied, the stone's
  /// true surface remembered where it was (ghost scoring). Returns the committed operation.
  Operation commit_grasp(MoveRecord& m, const Tracked& tr, const Eigen::Isometry3d& T_MG_grasp, const PointCloud& map,
                         const SurfaceTruth& before, const Eigen::Isometry3d& E);
  /// The world moved every stone j by poses[j] (world frame): the truth of the tracked objects follows.
  void world_moved(std::span<const Eigen::Isometry3d> poses);
  /// Scores the object's stored pose against the truth (E: map -> world at scoring time).
  void score(MoveRecord& m, const Tracked& tr, const Eigen::Isometry3d& E, bool predicted) const;
  /// One rescan from t0, the object relocated and committed, scored, ghosts counted.
  RealignResult rescan_and_realign(MoveRecord& m, const Tracked& tr, double t0);
  [[nodiscard]] double ghost_share(const PointCloud& map, const SurfaceTruth& now, const Eigen::Isometry3d& E) const;
  /// Scans while the machine carries the grasped stone (issue #15 item 2) over [t_from, t_to):
  /// the sensors' world holds stone tr.stone in the gripper at T_world_G (the true gripper pose at
  /// closing, relative to the stone where the site has it now), the mapper's self-filter gets the
  /// object's database cloud attached to the gripper link through the commanded T_MG (unless
  /// filter_carried is off); afterwards the stone is back in the world where the site has it and
  /// the attachment ends. Returns the floating map points the scan added (on no true surface and
  /// floating_height above the ground: the carried stone remapped), or -1 when carry_scan is 0
  /// or the window is empty.
  long scan_while_carrying(const Tracked& tr, const Eigen::Isometry3d& T_world_G, const Eigen::Isometry3d& T_MG,
                           double t_from, double t_to);
  /// True when no other stone's bounding box comes within half + slot_clearance of xy.
  [[nodiscard]] bool slot_clear(const Eigen::Vector2d& xy, int stone, double half) const;

  [[nodiscard]] ScanningMachine& machine() { return machine_; }
  [[nodiscard]] const ScanningMachine& machine() const { return machine_; }
  [[nodiscard]] ObjectDatabase& db() { return *db_; }
  [[nodiscard]] const ObjectDatabase& db() const { return *db_; }
  [[nodiscard]] std::vector<Tracked>& tracked() { return tracked_; }
  [[nodiscard]] const ObjectTrackingConfig& config() const { return cfg_; }

  ObjectTrackingResult result;

 private:
  [[nodiscard]] RemovalCounts removal(const PointCloud& map, const MapEdit& edit, const SurfaceTruth& t,
                                      const Eigen::Isometry3d& E, int stone) const;
  [[nodiscard]] int stone_of(const PointCloud& cloud, const SurfaceTruth& t, const Eigen::Isometry3d& E,
                             double* share = nullptr) const;
  void plan_slots();
  [[nodiscard]] std::optional<Vec3d> free_slot(int round, int stone) const;
  bool move(int round, Tracked& tr);  // false: no free slot

  const ObjectTrackingConfig& cfg_;
  const TrackingProgress& progress_;
  ScanningMachine machine_;
  std::unique_ptr<ObjectDatabase> db_;
  std::vector<Tracked> tracked_;
  std::vector<Vec3d> slots_odd_, slots_even_;  // flattest first
  PointCloud former_;  // true surfaces of moved stones at their earlier poses (world)
  std::filesystem::path temporary_;  // the default database, removed with the tracker
  mutable std::shared_ptr<const SurfaceTruth> truth_;  // truth() for the world state truth_key_
  mutable std::vector<double> truth_key_;
};

/// Simulated settings of a tracking run: validated, the world at rest (settle_in_physics on).
[[nodiscard]] sim::SimulationConfig at_rest(const ObjectTrackingConfig& c);

}  // namespace cairn::eval
