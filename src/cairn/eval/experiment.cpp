#include "cairn/eval/experiment.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <numbers>
#include <optional>
#include <set>

#include "cairn/core/error.hpp"
#include "cairn/core/stats.hpp"
#include "cairn/core/transform.hpp"
#include "cairn/eval/tracker.hpp"
#include "cairn/mapping/mapper.hpp"
#include "cairn/objects/pipeline.hpp"
#include "cairn/objects/support.hpp"
#include "cairn/registration/scale_recovery.hpp"
#include "cairn/sim/drone.hpp"
#include "cairn/sim/physics/grasp_json.hpp"
#include "cairn/mapping/map_edit.hpp"
#include "cairn/sim/world.hpp"
#include "cairn/core/units.hpp"
#include "cairn/core/voxel_grid.hpp"

namespace cairn::eval {
namespace {

using Eigen::Isometry3d;
using Vec2d = Eigen::Vector2d;

// The ground under a target (Experiment::ground_height): the search radius grows to at most this
// many times experiment.ground_radius until this many map points lie within it; the plane is
// fitted to the points this close to it (stones, ghosts left out), this many times.
constexpr double kGroundWidening = 4.0;
constexpr std::size_t kMinGroundPoints = 10;
constexpr double kGroundTrim = 0.1;  // [m]
constexpr int kGroundTrimPasses = 3;

/// Least-squares plane z = a + b x + c y through the points (at least 3, not collinear): (a, b, c);
/// a flat plane at the median height when the fit is degenerate.
Eigen::Vector3d fit_height_plane(const std::vector<Vec3d>& p) {
  Eigen::MatrixXd A(p.size(), 3);
  Eigen::VectorXd z(p.size());
  for (std::size_t i = 0; i < p.size(); ++i) {
    A.row(Eigen::Index(i)) << 1.0, p[i].x(), p[i].y();
    z[Eigen::Index(i)] = p[i].z();
  }
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(A);
  if (qr.rank() == 3) return qr.solve(z);
  return {median(std::vector<double>(z.data(), z.data() + z.size())), 0.0, 0.0};
}

/// The cloud thinned to `voxel` (the report's scene): positions only.
PointCloud thin(const PointCloud& c, double voxel) {
  PointCloud p;
  p.points = c.points;
  p.origin = c.origin;
  return p.empty() ? p : voxel_downsample(p, {.res_voxel = voxel, .n_min = 1});
}

void validate(const ExperimentConfig& c) {
  if (c.experiment != "exp1" && c.experiment != "exp2" && c.experiment != "pile")
    throw ConfigError("experiment must be 'exp1', 'exp2' or 'pile', not '" + c.experiment + "'");
  if (c.experiment == "pile" && c.rounds > 1) throw ConfigError("experiment pile: one round (the pile is cleared once)");
  if (!(c.pile_shift > 0)) throw ConfigError("experiment: pile_shift must be > 0");
  if (c.rounds < 0 || c.max_attempts < 1) throw ConfigError("experiment: rounds >= 0 and max_attempts >= 1 required");
  if (!(c.registration_period > 0) || !(c.registration_timeout >= c.registration_period))
    throw ConfigError("experiment: registration_period > 0 and registration_timeout >= registration_period required");
  if (!(c.row_spacing > 0) || !(c.lift_height > 0) || !(c.place_depth >= 0) || !(c.ground_radius > 0) ||
      !std::isfinite(c.ground_radius))
    throw ConfigError("experiment: row_spacing, lift_height, ground_radius > 0 (finite) and place_depth >= 0 required");
  if (!(c.row_distance > 0) || !(c.row_distance_even > 0) || !(c.row_min_distance > 0) ||
      !std::isfinite(c.row_distance + c.row_distance_even + c.row_min_distance + c.row_spacing) ||
      !std::isfinite(c.tracking.mapping.local_map.R_map))
    throw ConfigError("experiment: row_distance, row_distance_even, row_min_distance, row_spacing and R_map must be "
                      "> 0 and finite");
  const SlipDetectionConfig& d = c.detection;
  if (!(d.min_load >= 0) || !(d.load_drop > 0 && d.load_drop < 1) || !(d.jaw_travel > 0) || !(d.target_tolerance > 0))
    throw ConfigError("experiment detection: min_load >= 0, load_drop in (0, 1), positive jaw_travel and target_tolerance");
  if (c.inject_friction < 0) throw ConfigError("experiment: inject_friction must be >= 0");
  if (!(c.scene_voxel > 0)) throw ConfigError("experiment: scene_voxel must be > 0");
  c.grasp.validate();
}

int rounds_of(const ExperimentConfig& c) { return c.rounds > 0 ? c.rounds : c.experiment == "exp2" ? 4 : 1; }

/// Every stone's mesh vertices (world): the truth's surfaces, to measure how far stones moved.
std::vector<std::vector<Vec3d>> surfaces(const sim::Site& site) {
  std::vector<std::vector<Vec3d>> v;
  for (const sim::Stone& s : site.stones) {
    v.emplace_back();
    for (std::size_t i = 0; i < s.mesh.vertices.size(); ++i) v.back().push_back(s.mesh.vertices.world(i));
  }
  return v;
}

/// The largest surface displacement since `before` of the stones not `skip`ped.
double largest_motion(const sim::Site& site, const std::vector<std::vector<Vec3d>>& before, const std::vector<bool>& skip) {
  double d = 0.0;
  const std::vector<std::vector<Vec3d>> now = surfaces(site);
  for (std::size_t s = 0; s < now.size(); ++s)
    for (std::size_t i = 0; !skip[s] && i < now[s].size() && i < before[s].size(); ++i)
      d = std::max(d, (now[s][i] - before[s][i]).norm());
  return d;
}

/// Simulated time the machine's estimate and sweeps must cover: the registration, then every
/// attempt's trial (at most ~carry_time) and rescan.
double duration(const ExperimentConfig& c) {
  const ObjectTrackingConfig& t = c.tracking;
  return std::max(t.initial_scan, c.registration_timeout) +
         rounds_of(c) * t.simulation.site.stones.count * c.max_attempts * (2.0 * t.carry_time + t.rescan) + 1.0;
}

/// The mean of a phase's samples of `f` over [t0, t1] (NaN when none).
template <class F>
double trace_mean(const std::vector<sim::TraceSample>& trace, double t0, double t1, F f) {
  double sum = 0.0;
  int n = 0;
  for (const sim::TraceSample& s : trace)
    if (s.time >= t0 && s.time <= t1) sum += f(s), ++n;
  return n > 0 ? sum / n : std::nan("");
}

const sim::PhaseTiming* find_phase(const sim::GraspTrialResult& r, const std::string& name) {
  for (const sim::PhaseTiming& p : r.phases)
    if (p.name == name) return &p;
  return nullptr;
}

}  // namespace

GraspDetection detect_grasp_failure(const sim::GraspTrialResult& r, const SlipDetectionConfig& c) {
  GraspDetection d;
  const sim::PhaseTiming* close = find_phase(r, "close");
  const sim::PhaseTiming* hold = find_phase(r, "hold");  // the first: hanging still after the lift
  const sim::PhaseTiming* place = find_phase(r, "place");
  if (!close || !hold) {  // the machine stopped before lifting (contact on the approach or closing)
    d.failed = true;
    d.signs.push_back("not_lifted");
    return d;
  }
  const auto load = [](const sim::TraceSample& s) { return s.arm_load; };
  const auto opening = [](const sim::TraceSample& s) { return s.opening; };
  const double lowering = place ? place->start : r.phases.back().start;
  d.lifted_load = trace_mean(r.trace, hold->start, hold->end, load);
  d.release_load = trace_mean(r.trace, lowering - 0.3, lowering, load);  // the last samples carried
  double closed = trace_mean(r.trace, close->end - 0.1, close->end, opening), tightest = closed;
  for (const sim::TraceSample& s : r.trace)
    if (s.time > close->end && s.time <= lowering) tightest = std::min(tightest, s.opening);
  d.jaw_travel = std::isfinite(closed) ? closed - tightest : 0.0;
  if (!(d.lifted_load >= c.min_load)) d.signs.push_back("nothing_lifted");
  if (d.jaw_travel > c.jaw_travel) d.signs.push_back("jaws_closed_further");
  if (r.arm_stalled) d.signs.push_back("arm_stalled");  // the arm's controller knows it stopped
  if (d.lifted_load >= c.min_load && !(d.release_load >= (1.0 - c.load_drop) * d.lifted_load))
    d.signs.push_back("load_dropped");
  d.held_at_release = d.lifted_load >= c.min_load && d.release_load >= (1.0 - c.load_drop) * d.lifted_load;
  d.failed = !d.signs.empty();
  return d;
}

bool seen_at_target(ObjectStatus status, const Eigen::Isometry3d& moved, const Vec3d& mass_centroid, const Vec2d& target,
                    const SlipDetectionConfig& c) {
  return status != ObjectStatus::lost && ((moved * mass_centroid).head<2>() - target).norm() <= c.target_tolerance;
}

namespace {

/// The experiment on one Tracker: registration while scanning, then the rounds of planned moves.
class Experiment {
 public:
  Experiment(const ExperimentConfig& c, const ExperimentProgress& progress)
      : c_(c), progress_(progress), tracker_(c.tracking, progress_, duration(c)) {
    out.experiment = c.experiment;
    out.seed = c.tracking.seed;
    out.stones = int(tracker_.machine().world().site.stones.size());
  }
  void register_while_scanning();
  void populate();
  void run_round(int round);
  void clear_pile();
  ExperimentResult out;

 private:
  [[nodiscard]] std::vector<Vec2d> row(int round) const;
  [[nodiscard]] std::optional<Vec2d> free_target(int round, const ObjectRecord& obj, std::vector<bool>& used) const;
  [[nodiscard]] double ground_height(const PointCloud& map, const Vec2d& xy, double fallback) const;
  [[nodiscard]] const PointCloud& planning_model(const ObjectRecord& obj) const;
  [[nodiscard]] GraspPlan command(const grasp::GraspPlanning& p, const ObjectRecord& obj, const PointCloud& map,
                                 const Vec2d& target, int stone, double t0, GraspRecord& g) const;
  sim::GraspTrialResult execute(const GraspPlan& plan, int attempt, GraspRecord& g, std::vector<Isometry3d>& motion);
  long scan_carried(const sim::GraspTrialResult& r, const GraspPlan& cmd, const Isometry3d& T_MG_grasp,
                    const Isometry3d& moved, const Tracker::Tracked& tr, double t0);
  grasp::GraspPlanning plan(const ObjectRecord& obj, const PointCloud& map, int stone, GraspRecord& g);
  void write_trial(const sim::GraspTrialResult& r, const GraspRecord& g) const;
  void release_and_rescan(int round, int attempt, Tracker::Tracked& tr, const sim::GraspTrialResult& r,
                          const Isometry3d& T_MG_grasp, double t0, MoveRecord& mv, const Isometry3d& E,
                          const GraspDetection& d);
  bool attempt(int round, int attempt, Tracker::Tracked& tr, const Vec2d& target);
  void move_stone(int round, Tracker::Tracked& tr, std::vector<bool>& used);
  void search_lost(int round, int attempt, const Tracker::Tracked& tr);
  void capture_after(int round, int move, int moves);
  [[nodiscard]] Tracker::Tracked* next_off_pile(const std::set<std::int64_t>& picked, int& loaded);
  void score_round(int round, const RoundRecord& rr);
  void capture(const std::string& label, int round, int move);
  void capture(const std::string& label, int round, int move, const PointCloud& map, const Isometry3d& E);
  void capture_trajectory();
  void progress(const std::string& what, int done, int total) const {
    if (progress_) progress_(what, done, total);
  }

  const ExperimentConfig& c_;
  const ExperimentProgress& progress_;
  Tracker tracker_;
  std::optional<PointCloud> drone_;     // registered drone cloud (map frame), grasped objects cut out
  std::vector<PointCloud> merged_;      // registration's objects (LiDAR + drone, map frame)
  std::vector<bool> moved_;             // per stone: moved since the drone flew
  std::map<int, Vec2d> targets_;        // this round's target per stone (map frame)
  int moves_ = 0;
  double planning_ms_ = 0.0, physics_ms_ = 0.0, realign_ms_ = 0.0;

 public:
  void finish(double total_ms);
};

void Experiment::register_while_scanning() {
  Stopwatch total;
  ScanningMachine& m = tracker_.machine();
  const sim::SimulatedWorld& w = m.world();
  progress("drone survey", 0, 1);
  const sim::DroneSurvey survey = sim::simulate_drone(w.site, w.scene, m.config().drone, c_.tracking.seed);
  const ScaleRecoveryResult scale = recover_scale(sim::to_colmap_model(survey), sim::vins_trajectory(survey));
  PointCloud cloud = survey.cloud;
  cloud.labels.clear();  // the survey's labels are truth: never seen by the machine
  transform_cloud(cloud, scale.T_metric_sfm);
  out.timings.add("drone", total.lap_ms());
  Vec3d centre = Vec3d::Zero();  // where the error is measured: the stones' mean centroid
  for (const sim::Stone& s : w.site.stones) centre += s.centroid / double(w.site.stones.size());
  RegistrationOutcome& reg = out.registration;
  double mapping_ms = 0.0, registration_ms = 0.0;
  for (double t = c_.registration_period; t <= c_.registration_timeout + 1e-9; t += c_.registration_period) {
    progress("scanning and registering", int(t), int(c_.registration_timeout));
    Stopwatch sw;
    m.scan(t - c_.registration_period, t);
    mapping_ms += sw.lap_ms();
    const PointCloud map = m.mapper().map();
    if (map.empty()) continue;
    const GlobalRegistrationResult r = register_global(cloud, map, c_.tracking.segmentation, c_.registration);
    RegistrationAttempt a{.time = t, .accepted = r.success, .map_points = map.size(), .ms = sw.lap_ms(), .reason = r.reason};
    registration_ms += a.ms;
    const Isometry3d E = tracker_.truth()->offset->map_offset(map);  // scoring only
    const Similarity truth = Similarity::from_isometry(E.inverse()) * survey.T_world_sfm * scale.T_metric_sfm.inverse();
    const RegistrationError e = registration_error(Similarity::from_isometry(r.T_target_source), truth, E.inverse() * centre);
    a.rotation_error_deg = e.rotation_deg;
    a.translation_error_m = e.translation_m;
    reg.tries.push_back(a);
    ++reg.attempts;
    if (!r.success) continue;
    reg.success = true;
    reg.first_success_s = t;
    reg.rotation_error_deg = e.rotation_deg;
    reg.translation_error_m = e.translation_m;
    reg.timings = r.timings;
    transform_cloud(cloud, r.T_target_source);
    out.scene.drone_points = cloud.size();
    out.scene.drone = thin(cloud, c_.scene_voxel);
    drone_ = std::move(cloud);
    for (const auto& o : r.objects) merged_.push_back(o.cloud);
    break;
  }
  if (!reg.success) out.notes.push_back("registration: no attempt accepted within the timeout; planning without the drone");
  // The database is filled after the initial scan (two swings), as the object tracking does.
  Stopwatch sw;
  if (m.now() < c_.tracking.initial_scan) m.scan(m.now(), c_.tracking.initial_scan);
  mapping_ms += sw.lap_ms();
  out.timings.add("mapping", mapping_ms);
  out.timings.add("registration", registration_ms);
}

void Experiment::populate() {
  Stopwatch sw;
  tracker_.populate();
  out.scene.gripper = tracker_.machine().config().gripper;
  out.scene.voxel = c_.scene_voxel;
  capture("before moving", 0, 0);
  out.stones_tracked = tracker_.result.stones_tracked;
  for (const std::string& u : tracker_.result.unmatched) out.notes.push_back(u);
  moved_.assign(std::size_t(out.stones), false);
  out.timings.add("segmentation", sw.lap_ms());
}

std::vector<Vec2d> Experiment::row(int round) const {
  const ScanningMachine& m = tracker_.machine();
  const double heading = m.config().excavator.base_yaw_deg / kDegPerRad;
  const double d = round % 2 == 1 ? c_.row_distance : c_.row_distance_even;
  return target_places(m.base().head<2>(), heading, d, int(m.world().site.stones.size()), c_);
}

/// The first unused place of the round's rows inside the map that no other object comes near
/// (the database's view): the stone's reach about its centroid plus target_clearance clear of
/// every other object's points. The attempt puts the planner's (or the weighed) centre of mass on
/// the place, a few centimetres from the points' centroid (up to ~0.3 m on a second attempt,
/// docs/experiments.md): the clearance covers the usual case only.
std::optional<Vec2d> Experiment::free_target(int round, const ObjectRecord& obj, std::vector<bool>& used) const {
  const std::vector<Vec2d> places = row(round);
  const double reach = xy_reach(obj.cloud, obj.centroid);
  const std::vector<ObjectRecord> others = tracker_.db().objects();
  const Vec2d axis = tracker_.machine().base().head<2>();
  for (std::size_t i = 0; i < places.size(); ++i) {
    if (used[i] || !place_in_map(places[i], reach, axis, c_) || !place_is_free(places[i], reach, obj.id, others, c_))
      continue;
    used[i] = true;
    return places[i];
  }
  return std::nullopt;
}

/// The ground's height at xy from the map: a plane fitted to the map points within ground_radius
/// (the radius doubled, up to kGroundWidening times, while fewer than kMinGroundPoints lie
/// within it: a target beyond the stones lies in their LiDAR shadow) that lie within kGroundTrim
/// of it (stones and ghosts left out), its height at xy. Without enough points: `fallback`.
double Experiment::ground_height(const PointCloud& map, const Vec2d& xy, double fallback) const {
  std::vector<Vec3d> widest;  // one pass over the map: the points within the largest radius, about xy
  for (std::size_t i = 0; i < map.size(); ++i) {
    const Vec3d p = map.world(i);
    if ((p.head<2>() - xy).norm() <= kGroundWidening * c_.ground_radius)
      widest.emplace_back(p.x() - xy.x(), p.y() - xy.y(), p.z());
  }
  std::vector<Vec3d> near;
  for (double r = c_.ground_radius; r <= kGroundWidening * c_.ground_radius && near.size() < kMinGroundPoints; r *= 2.0) {
    near.clear();
    for (const Vec3d& p : widest)
      if (p.head<2>().norm() <= r) near.push_back(p);
  }
  if (near.size() < kMinGroundPoints) {
    spdlog::debug("demo: ground at ({:.2f}, {:.2f}): {} map points, the object's underside instead", xy.x(), xy.y(),
                  near.size());
    return fallback;
  }
  // z = a + b x + c y about xy, from a flat start at the lower quartile (stones stand above the
  // ground, and may be most of the points), refitted to the points near it.
  std::vector<double> z;
  for (const Vec3d& p : near) z.push_back(p.z());
  std::nth_element(z.begin(), z.begin() + long(z.size() / 4), z.end());
  Eigen::Vector3d plane(z[z.size() / 4], 0.0, 0.0);
  for (int pass = 0; pass < kGroundTrimPasses; ++pass) {
    std::vector<Vec3d> band;
    for (const Vec3d& p : near)
      if (std::abs(p.z() - (plane[0] + plane[1] * p.x() + plane[2] * p.y())) <= kGroundTrim) band.push_back(p);
    if (band.size() < kMinGroundPoints) break;
    plane = fit_height_plane(band);
  }
  spdlog::debug("demo: ground at ({:.2f}, {:.2f}): {} map points, {:.3f} m", xy.x(), xy.y(), near.size(), plane[0]);
  return plane[0];
}

/// The registration's merged object at this object (first move after the drone flew), else the
/// database's own cloud (Sec. 5.2).
const PointCloud& Experiment::planning_model(const ObjectRecord& obj) const {
  const PointCloud* merged = nearest_cloud(merged_, obj.centroid, kMergedNear);
  return merged ? *merged : obj.cloud;
}

/// The lowest points of a cloud: its `share` quantile of z (the object's underside, where it
/// rests on the ground).
double low_z(const PointCloud& c, double share) {
  std::vector<double> z;
  z.reserve(c.size());
  for (std::size_t i = 0; i < c.size(); ++i) z.push_back(c.world(i).z());
  if (z.empty()) return 0.0;
  const auto k = z.begin() + long(share * double(z.size() - 1));
  std::nth_element(z.begin(), k, z.end());
  return *k;
}

/// The drone cloud without what a grasp removed from the map (the stone is no longer there).
void cut(PointCloud& cloud, const std::vector<MapEdit>& edits) {
  for (const MapEdit& e : edits) {
    const MapEditRegion region(e);
    std::size_t kept = 0;
    for (std::size_t i = 0; i < cloud.size(); ++i)
      if (!region.removes(cloud.world(i))) cloud.points[kept++] = cloud.points[i];
    cloud.points.resize(kept);
    cloud.colors.clear(), cloud.normals.clear(), cloud.times.clear(), cloud.labels.clear();
  }
}

/// The truth a placement is scored against (map frame): the stone's centroid and lowest point
/// before the pick, the terrain's height under the target.
struct PlaceTruth {
  Vec3d centroid = Vec3d::Zero();
  Vec3d world_centroid = Vec3d::Zero();  // the same in the world (the weighing's frame)
  double bottom = 0.0, ground = 0.0;
};

PlaceTruth place_truth(const sim::Site& site, int k, const Isometry3d& E, const Vec2d& target) {
  const sim::Stone& stone = site.stones[std::size_t(k)];
  PlaceTruth t{.centroid = E.inverse() * stone.centroid,
               .world_centroid = stone.centroid,
               .bottom = std::numeric_limits<double>::infinity()};
  for (std::size_t i = 0; i < stone.mesh.vertices.size(); ++i)
    t.bottom = std::min(t.bottom, (E.inverse() * stone.mesh.vertices.world(i)).z());
  const Vec3d w = E * Vec3d(target.x(), target.y(), 0.0);
  t.ground = (E.inverse() * Vec3d(w.x(), w.y(), site.terrain.height(w.x(), w.y()))).z();
  return t;
}

/// Where the target error of a carried stone comes from (GraspRecord's placement breakdown).
void score_placement(const PlaceTruth& truth, const Vec3d& mass_centroid, const sim::GraspTrialResult& r,
                     GraspRecord& g) {
  g.place_ground_error_m = g.place_ground_z - truth.ground;
  g.place_bottom_error_m = g.place_bottom_z - truth.bottom;
  if (!r.released_centroid.allFinite()) return;
  g.com_estimate_error_m = (mass_centroid - truth.centroid).head<2>().norm();
  if (r.weighed_com.allFinite()) {
    g.weighed_com_error_m = (r.weighed_com - truth.world_centroid).head<2>().norm();  // the lift is straight up
    g.place_correction_m = r.place_correction;
  }
  g.grip_drift_m = r.grip_drift;
  g.release_drift_m = (r.rest_centroid - r.released_centroid).head<2>().norm();
}

/// The command of one attempt: grasp `best` where it was planned, then the stone's centre of mass
/// as the planner estimates it (Sec. 5.2: the planning cloud with the unseen side completed) over
/// the target, lowered until contact (place_depth below the contact the map predicts: the ground
/// under the target vs the object's underside). Poses in the world, commanded from the map at t0.
GraspPlan Experiment::command(const grasp::GraspPlanning& p, const ObjectRecord& obj, const PointCloud& map,
                              const Vec2d& target, int stone, double t0, GraspRecord& g) const {
  const ScanningMachine& m = tracker_.machine();
  const grasp::Grasp& best = p.grasps.front();
  g.place_bottom_z = low_z(obj.cloud, 0.02);
  g.place_ground_z = ground_height(map, target, g.place_bottom_z);
  const double dz = g.place_ground_z - g.place_bottom_z - c_.place_depth;
  const Vec2d shift = target - p.cloud.mass_centroid.head<2>();
  const Isometry3d T_MG_place = Eigen::Translation3d(shift.x(), shift.y(), dz) * best.T_map_gripper;
  GraspPlan plan = grasp::to_grasp_plan(best, GraspPlan{});
  plan.lift_height = c_.lift_height;
  plan.T_world_gripper = m.E_state(t0) * best.T_map_gripper;
  plan.T_world_place = m.E_state(t0 + c_.tracking.carry_time) * T_MG_place;
  if (c_.place_by_weight)
    plan.place_com_xy = (m.E_state(t0 + c_.tracking.carry_time) * Vec3d(target.x(), target.y(), g.place_ground_z)).head<2>();
  plan.target_stone = stone;  // the physics' truth: grasping another stone is a failure
  spdlog::debug("demo: lowering {:.3f} m (ground {:.3f}, underside {:.3f}); world grasp z {:.3f}, place z {:.3f}", dz,
                g.place_ground_z, g.place_bottom_z, plan.T_world_gripper.translation().z(),
                plan.T_world_place.translation().z());
  return plan;
}

/// Runs the command in the physics and makes its outcome the world the sensors see (stones
/// settled where they came to rest; every stone's motion in `motion`); the truth figures of the
/// attempt go into `g`.
sim::GraspTrialResult Experiment::execute(const GraspPlan& plan, int attempt, GraspRecord& g,
                                          std::vector<Isometry3d>& motion) {
  ScanningMachine& m = tracker_.machine();
  sim::Site& site = m.world().site;
  const std::vector<std::vector<Vec3d>> surfaces_before = surfaces(site);
  sim::PhysicsConfig physics = m.config().physics;
  physics.abort_on_failure = false;  // the machine carries on until it notices itself
  if (c_.inject_friction > 0 && moves_ == c_.inject_move && attempt == 1) physics.friction = c_.inject_friction;
  Stopwatch sw;
  sim::GraspTrialResult r = sim::run_grasp_trial(site, plan, m.config().gripper, physics);
  sim::apply_stone_poses(site, r.stone_poses);
  tracker_.world_moved(r.stone_poses);
  motion = r.stone_poses;
  if (!r.settled) {
    const std::vector<Isometry3d> settling = sim::settle_site(site, m.config().physics).stone_poses;
    tracker_.world_moved(settling);
    for (std::size_t j = 0; j < motion.size(); ++j) motion[j] = settling[j] * motion[j];
  }
  m.world().scene = sim::make_world_scene(site, m.config().terrain_mesh_spacing);
  std::vector<bool> skip = moved_;
  skip[std::size_t(g.stone)] = true;
  g.others_moved_m = largest_motion(site, surfaces_before, skip);
  out.pile_shifts += g.others_moved_m > c_.pile_shift;
  g.sim_time = r.sim_time;
  g.wall_s = sw.lap_ms() / 1000.0;
  physics_ms_ += 1000.0 * g.wall_s;
  g.success = r.success;
  g.failure_reasons = r.failure_reasons;
  g.place_error_m = r.place_error;
  if (!c_.trials_dir.empty()) write_trial(r, g);
  return r;
}

/// The sweeps while the stone hung in the gripper on its way (issue #15 item 2): from the start
/// of the trial's move phase for carry_scan seconds, the stone held where the jaws closed on it
/// (the site's mesh has moved by `moved` since), the object attached to the self-filter through
/// the commanded grasp. -1 when nothing was carried.
long Experiment::scan_carried(const sim::GraspTrialResult& r, const GraspPlan& cmd, const Isometry3d& T_MG_grasp,
                              const Isometry3d& moved, const Tracker::Tracked& tr, double t0) {
  const sim::PhaseTiming* carrying = find_phase(r, "move");
  if (carrying == nullptr || r.grasped_stone != tr.stone) return -1;
  const double from = t0 + carrying->start, to = std::min(from + c_.tracking.carry_scan, t0 + carrying->end);
  const Isometry3d T_world_G = moved * cmd.T_world_gripper;
  return tracker_.scan_while_carrying(tr, T_world_G, T_MG_grasp, from, to);
}

void Experiment::write_trial(const sim::GraspTrialResult& r, const GraspRecord& g) const {
  std::filesystem::create_directories(c_.trials_dir);
  const std::filesystem::path file = c_.trials_dir / trial_file_name(g);
  std::ofstream f(file);
  f << sim::to_json(r).dump() << "\n";
  if (!f) throw InputError(file.string() + ": cannot write the trial");
}

/// Release (Eq. 3): where the arm opened the jaws when the machine measured the stone still held
/// there, else where it was grasped (the machine expects it there and searches); then the rescan,
/// the re-alignment and, for a lost object, the search.
void Experiment::release_and_rescan(int round, int attempt, Tracker::Tracked& tr, const sim::GraspTrialResult& r,
                                    const Isometry3d& T_MG_grasp, double t0, MoveRecord& mv, const Isometry3d& E,
                                    const GraspDetection& d) {
  ScanningMachine& m = tracker_.machine();
  Stopwatch sw;
  const sim::PhaseTiming* opened = find_phase(r, "release");
  const double t_release = t0 + (opened ? opened->start : r.sim_time);
  const Isometry3d T_MG_release = d.held_at_release ? m.E_state(t_release).inverse() * r.T_world_release : T_MG_grasp;
  (void)tracker_.db().commit(release_operation(*tracker_.db().object(tr.object), T_MG_release, t_release));
  tracker_.score(mv, tr, E, /*predicted=*/true);
  sw.lap_ms();  // the re-alignment's time from here
  (void)tracker_.rescan_and_realign(mv, tr, t0 + r.sim_time);
  if (tracker_.db().object(tr.object)->status == ObjectStatus::lost) search_lost(round, attempt, tr);
  realign_ms_ += sw.lap_ms();
  tracker_.result.moves.push_back(mv);
}

/// Plans on what the machine senses (Sec. 5.2: the merged LiDAR + drone object and the drone cloud
/// for a stone's first move, the database's cloud afterwards); the best grasp's figures, or
/// no_grasp, go into `g` (no_grasp: recorded as a detected failure).
grasp::GraspPlanning Experiment::plan(const ObjectRecord& obj, const PointCloud& map, int stone, GraspRecord& g) {
  const bool first = drone_ && !moved_[std::size_t(stone)];
  const PointCloud& model = first ? planning_model(obj) : obj.cloud;
  grasp::GraspPlanning p =
      grasp::plan_grasps(map, model, first ? &*drone_ : nullptr, tracker_.machine().config().gripper, c_.grasp);
  g.planning_ms = p.timings_ms.at("total");
  planning_ms_ += g.planning_ms;
  g.force_closure = p.counts.force_closure;
  if (p.grasps.empty()) {
    g.failure_reasons = {"no_grasp"};
    g.detection.failed = g.detected = true;
    g.detection.signs = {"no_grasp"};
    out.grasps.push_back(g);
    return p;
  }
  const grasp::Grasp& best = p.grasps.front();
  g.costs = best.costs;
  g.normalized_costs = grasp::normalized_costs(p);
  g.T_map_gripper = best.T_map_gripper;
  g.opening = best.opening;
  return p;
}

/// One attempt at moving the stone to `target`: plan on what the machine senses, execute in the
/// physics, update the database (Eq. 3), rescan and re-align. True when the machine sees the
/// object at its target.
bool Experiment::attempt(int round, int attempt, Tracker::Tracked& tr, const Vec2d& target) {
  ScanningMachine& m = tracker_.machine();
  const ObjectRecord obj = *tracker_.db().object(tr.object);
  GraspRecord g{.round = round, .stone = tr.stone, .attempt = attempt, .object = tr.object, .target = target};
  const PointCloud map = m.mapper().map();
  const auto before = tracker_.truth();
  const Isometry3d E = before->offset->map_offset(map);  // scoring only
  const grasp::GraspPlanning p = plan(obj, map, tr.stone, g);
  if (p.grasps.empty()) {  // the machine knows: rescan (one swing) and plan again
    m.scan(m.now(), m.now() + c_.tracking.rescan);
    return false;
  }
  const grasp::Grasp& best = p.grasps.front();
  MoveRecord mv{.round = round, .stone = tr.stone, .object = tr.object, .purity = tr.purity, .time = m.now()};
  const Operation grasp_op = tracker_.commit_grasp(mv, tr, best.T_map_gripper, map, *before, E);
  if (drone_) cut(*drone_, grasp_op.map_edits);
  // The object's stored motion from here on carries the planned centre of mass; the rescan checks where it went.
  const Isometry3d A_before = db_motion(tracker_.db().history(tr.object));
  const double t0 = m.now();
  const PlaceTruth truth = place_truth(m.world().site, tr.stone, E, target);  // scoring only
  // The command from the map without the grasped object (its voxels just removed): a target near
  // the stone's own place would otherwise find the stone for the ground.
  const GraspPlan cmd = command(p, obj, m.mapper().map(), target, tr.stone, t0, g);
  std::vector<Isometry3d> motion;
  const sim::GraspTrialResult r = execute(cmd, attempt, g, motion);
  mv.carried_in_map = scan_carried(r, cmd, best.T_map_gripper, motion[std::size_t(tr.stone)], tr, t0);
  score_placement(truth, p.cloud.mass_centroid, r, g);
  g.detection = detect_grasp_failure(r, c_.detection);
  release_and_rescan(round, attempt, tr, r, best.T_map_gripper, t0, mv, E, g.detection);
  g.move = mv;
  const Isometry3d moved = db_motion(tracker_.db().history(tr.object)) * A_before.inverse();
  const bool at_target = seen_at_target(tracker_.db().object(tr.object)->status, moved, p.cloud.mass_centroid, target,
                                        c_.detection);
  if (!at_target) g.detection.signs.push_back("not_at_target");
  g.detection.failed = g.detected = !g.detection.signs.empty();
  // Truth (scoring): the stone's centroid in the map's frame against the target.
  const Isometry3d E_now = tracker_.truth()->offset->map_offset(m.mapper().map());
  g.target_error_m = ((E_now.inverse() * m.world().site.stones[std::size_t(tr.stone)].centroid).head<2>() - target).norm();
  out.grasps.push_back(g);
  spdlog::debug("demo: round {} stone {} attempt {}: {} ({}), detected {}, target error {:.3f} m", round, tr.stone,
                attempt, r.success ? "held" : "failed", r.message, g.detected, g.target_error_m);
  return at_target;
}

/// Moves one stone to the round's row: a free target, then at most max_attempts grasps.
void Experiment::move_stone(int round, Tracker::Tracked& tr, std::vector<bool>& used) {
  const std::string name = "round " + std::to_string(round) + ": object " + std::to_string(tr.object);
  if (tracker_.db().object(tr.object)->status == ObjectStatus::lost) {
    out.notes.push_back(name + " is lost, not moved");
    return;
  }
  const std::optional<Vec2d> target = free_target(round, *tracker_.db().object(tr.object), used);
  if (!target) {
    const std::optional<ObjectRecord> o = tracker_.db().object(tr.object);
    char extent[96];
    std::snprintf(extent, sizeof extent, " (the object reaches %.2f m from its centroid)", xy_reach(o->cloud, o->centroid));
    out.notes.push_back(name + ": no free place in the rows" + extent);
    return;
  }
  targets_[tr.stone] = *target;
  ++moves_;
  ++out.moves;
  for (int a = 1; a <= c_.max_attempts; ++a) {
    if (tracker_.db().object(tr.object)->status == ObjectStatus::lost) break;  // searched for in attempt()
    if (attempt(round, a, tr, *target)) break;
  }
  moved_[std::size_t(tr.stone)] = true;
}

/// A stone the rescan's re-alignment did not find may have fallen over or rolled beyond its
/// search radius (or the re-alignment refused a fit at its target): the machine re-segments its
/// map, which tries every lost object's model, every face down, against every segment
/// (objects/association.cpp). Found again, its pose is then checked against the target, and
/// when not there it can be tried once more.
void Experiment::search_lost(int round, int attempt, const Tracker::Tracked& tr) {
  const std::string after = "round " + std::to_string(round) + ": object " + std::to_string(tr.object) +
                            " was lost after attempt " + std::to_string(attempt);
  RoundRecord scratch;
  tracker_.resegment(scratch);
  if (tracker_.db().object(tr.object)->status == ObjectStatus::lost) {
    out.notes.push_back(after + ", and the re-segmented map did not find it");
    return;
  }
  out.notes.push_back(after + ", found again by re-segmenting the map");
  ++out.found_again;
}

void Experiment::run_round(int round) {
  std::vector<Tracker::Tracked*> order;  // largest first (Sec. 5.1): the database's point counts
  for (Tracker::Tracked& t : tracker_.tracked()) order.push_back(&t);
  std::vector<std::size_t> points;
  for (const Tracker::Tracked* t : order) points.push_back(tracker_.db().object(t->object)->num_points);
  std::vector<std::size_t> idx(order.size());
  for (std::size_t i = 0; i < idx.size(); ++i) idx[i] = i;
  std::stable_sort(idx.begin(), idx.end(), [&](std::size_t a, std::size_t b) { return points[a] > points[b]; });
  std::vector<bool> used(row(round).size(), false);
  targets_.clear();
  for (std::size_t i = 0; i < idx.size(); ++i) {
    progress("round " + std::to_string(round) + ": moving stones", int(i), int(idx.size()));
    move_stone(round, *order[idx[i]], used);
    capture_after(round, int(i) + 1, int(idx.size()));
  }
  RoundRecord rr{.round = round};
  tracker_.resegment(rr);
  score_round(round, rr);
}

/// The report's scene after the round-1 moves listed in scene_after_moves (not after the last).
void Experiment::capture_after(int round, int move, int moves) {
  const auto& after = c_.scene_after_moves;
  if (round == 1 && move < moves && std::find(after.begin(), after.end(), move) != after.end())
    capture("round 1, after move " + std::to_string(move), round, move);
}

/// The next stone off the pile (objects/support.hpp, the machine's view): among the tracked
/// objects not yet picked and not lost, one no object rests on; nullptr when none is left.
Tracker::Tracked* Experiment::next_off_pile(const std::set<std::int64_t>& picked, int& loaded) {
  std::vector<ObjectRecord> objects = tracker_.db().objects();
  std::erase_if(objects, [](const ObjectRecord& o) { return o.status == ObjectStatus::lost; });
  std::vector<std::size_t> candidates;
  for (std::size_t i = 0; i < objects.size(); ++i) {
    const bool tracked = std::any_of(tracker_.tracked().begin(), tracker_.tracked().end(),
                                     [&](const Tracker::Tracked& t) { return t.object == objects[i].id; });
    if (tracked && !picked.contains(objects[i].id)) candidates.push_back(i);
  }
  if (candidates.empty()) return nullptr;
  const SupportConfig& sc = c_.tracking.objects.support;
  const std::size_t k = next_to_pick(objects, candidates, sc);
  loaded = loads(objects.size(), contacts(objects, sc))[k];
  for (Tracker::Tracked& t : tracker_.tracked())
    if (t.object == objects[k].id) return &t;
  return nullptr;
}

/// A pile's re-segmentations as one round's record: the objects created, vanished and bumped by
/// each, the database's state (objects, matched) after the last.
void add_resegmentation(RoundRecord& round, const RoundRecord& pass) {
  round.new_objects += pass.new_objects;
  round.new_on_tracked += pass.new_on_tracked;
  round.new_on_untracked += pass.new_on_untracked;
  round.new_on_terrain += pass.new_on_terrain;
  round.vanished += pass.vanished;
  round.moved_unexpectedly += pass.moved_unexpectedly;
  round.matched = pass.matched;
  round.objects = pass.objects;
}

/// Clears the pile into the row (issue #21): re-segments after every move, so a stone that came
/// out merged with a neighbour becomes an object once the neighbour is gone, and picks next a
/// stone no other object rests on.
void Experiment::clear_pile() {
  std::vector<bool> used(row(1).size(), false);
  targets_.clear();
  std::set<std::int64_t> picked;
  const int stones = out.stones;
  RoundRecord round{.round = 1};  // every re-segmentation's new, vanished and bumped objects; the last's state
  for (int move = 1;; ++move) {
    if (move > 1) {
      RoundRecord rr{.round = 1};
      tracker_.resegment(rr);
      add_resegmentation(round, rr);
      tracker_.adopt_new_objects();
      ++out.resegmentations;
    }
    int loaded = 0;
    Tracker::Tracked* tr = next_off_pile(picked, loaded);
    if (!tr) break;
    progress("clearing the pile", move - 1, stones);
    picked.insert(tr->object);
    const std::size_t first = out.grasps.size();
    move_stone(1, *tr, used);
    for (std::size_t g = first; g < out.grasps.size(); ++g) out.grasps[g].others_loaded = loaded;
    capture_after(1, move, stones);
  }
  if (out.resegmentations == 0) {  // nothing was picked: the one re-segmentation of the round
    tracker_.resegment(round);
    ++out.resegmentations;
  }
  score_round(1, round);
  out.stones_tracked = int(tracker_.tracked().size());  // with the stones adopted on the way
}

void Experiment::score_round(int round, const RoundRecord& rr) {
  ScanningMachine& m = tracker_.machine();
  const PointCloud map = m.mapper().map();
  const auto t = tracker_.truth();
  const Isometry3d E = t->offset->map_offset(map);
  ExperimentRound er{.round = round, .resegmentation = rr};
  for (const Tracker::Tracked& tr : tracker_.tracked()) {
    MoveRecord scored;
    tracker_.score(scored, tr, E, /*predicted=*/false);
    ExperimentObject o{.object = tr.object, .stone = tr.stone, .translation_error_m = scored.error_m,
                       .rotation_error_deg = scored.error_deg};
    if (const auto it = targets_.find(tr.stone); it != targets_.end()) {
      const Vec3d c = E.inverse() * m.world().site.stones[std::size_t(tr.stone)].centroid;
      o.target_error_m = (c.head<2>() - it->second).norm();
      out.placed += o.target_error_m <= c_.detection.target_tolerance;
    }
    er.objects.push_back(o);
  }
  er.ghost_fraction = tracker_.ghost_share(map, *t, E);
  for (const ObjectRecord& o : tracker_.db().objects(false)) er.lost += o.status == ObjectStatus::lost;
  er.duplicated = int(rr.new_on_tracked);
  out.rounds.push_back(er);
  capture("after round " + std::to_string(round), round, int(tracker_.tracked().size()), map, E);
}

/// The map, the database's objects and the stones' true centroids now, for the report.
void Experiment::capture(const std::string& label, int round, int move) {
  const PointCloud map = tracker_.machine().mapper().map();
  capture(label, round, move, map, tracker_.truth()->offset->map_offset(map));  // E: scoring only
}

/// The same with the map and its offset from the truth (map -> world) at hand.
void Experiment::capture(const std::string& label, int round, int move, const PointCloud& map, const Isometry3d& E) {
  ScanningMachine& m = tracker_.machine();
  SceneSnapshot s{.label = label, .round = round, .move = move, .time = m.now(), .map_points = map.size(),
                  .map = thin(map, c_.scene_voxel)};
  for (const ObjectRecord& o : tracker_.db().objects())
    if (o.status != ObjectStatus::lost) s.objects.emplace_back(o.id, thin(o.cloud, 0.5 * c_.scene_voxel));
  for (const sim::Stone& st : m.world().site.stones) s.true_centroids.push_back(E.inverse() * st.centroid);
  out.scene.snapshots.push_back(std::move(s));
}

/// The mapper's trajectory against the truth (world frame, as trajectory_error).
void Experiment::capture_trajectory() {
  const ScanningMachine& m = tracker_.machine();
  const std::vector<StampedPose> est = m.mapper().trajectory();
  const std::vector<StampedPose>& truth = m.state().truth;
  out.scene.trajectory_error = trajectory_error(est, truth);
  out.scene.trajectory = pose_errors(est, truth);
}

void Experiment::finish(double total_ms) {
  capture_trajectory();
  out.timings.add("planning", planning_ms_);
  out.timings.add("physics", physics_ms_);
  out.timings.add("rescan_realign", realign_ms_);
  out.timings.add("total", total_ms);
  // Per stone and round: success at the first attempt, within the attempts (truth: the grasp
  // held and the stone ended at its target).
  const double tol = c_.detection.target_tolerance;
  std::map<std::pair<int, int>, std::vector<const GraspRecord*>> by_move;
  for (const GraspRecord& g : out.grasps) {
    by_move[{g.round, g.stone}].push_back(&g);
    const bool failed = !g.success || !(g.target_error_m >= 0 && g.target_error_m <= tol);
    out.failures += failed;
    out.failures_detected += failed && g.detected;
    out.false_alarms += !failed && g.detected;
  }
  for (const auto& [_, gs] : by_move) {
    const auto ok = [tol](const GraspRecord* g) { return g->success && g->target_error_m >= 0 && g->target_error_m <= tol; };
    out.first_attempt_success += ok(gs.front());
    out.within_attempts += std::any_of(gs.begin(), gs.end(), ok);
  }
}

}  // namespace

std::vector<Vec2d> target_places(const Vec2d& axis, double heading, double distance, int count,
                                 const ExperimentConfig& c) {
  const double R = c.tracking.mapping.local_map.R_map;
  const auto positive = [](double v) { return v > 0 && std::isfinite(v); };
  if (!positive(R) || !positive(c.row_spacing) || !positive(c.row_min_distance) || !std::isfinite(distance))
    throw ConfigError("target_places: R_map, row_spacing and row_min_distance must be > 0 and finite");
  const double shift = count % 2 == 0 ? 0.5 * c.row_spacing : 0.0;  // an even row is centred too
  const Eigen::Rotation2Dd turn(heading);
  std::vector<Vec2d> places;
  // The round's row, the rows nearer the machine down to row_min_distance, then the rows farther
  // out while a stone half a spacing wide (the widest a row is laid out for) fits at the row's
  // middle with target_clearance to spare.
  std::vector<double> rows = {distance};
  for (int k = 1; distance - k * c.row_spacing >= c.row_min_distance - 1e-9; ++k)
    rows.push_back(distance - k * c.row_spacing);
  for (int k = 1; distance + (k + 0.5) * c.row_spacing + c.target_clearance <= R + 1e-9; ++k)
    rows.push_back(distance + k * c.row_spacing);
  for (const double d : rows) {
    // From the middle outwards: 0, -1, +1, -2, +2, ... spacings (even rows: -1/2 + 1/2, then
    // -3/2, +3/2, ...), until both ends leave the map.
    for (int i = 0;; ++i) {
      const double offset = (i % 2 == 0 ? 1.0 : -1.0) * std::ceil(i / 2.0) * c.row_spacing + shift;
      if (std::abs(offset) - c.row_spacing > R) break;
      const Vec2d local(d, offset);
      if (local.norm() <= R) places.push_back(axis + turn * local);
    }
  }
  return places;
}

bool place_in_map(const Vec2d& place, double reach, const Vec2d& axis, const ExperimentConfig& c) {
  return (place - axis).norm() + reach + c.target_clearance <= c.tracking.mapping.local_map.R_map;
}

double xy_reach(const PointCloud& cloud, const Vec3d& centre) {
  double r2 = 0.0;
  for (std::size_t i = 0; i < cloud.size(); ++i) r2 = std::max(r2, (cloud.world(i) - centre).head<2>().squaredNorm());
  return std::sqrt(r2);
}

bool place_is_free(const Vec2d& place, double reach, std::int64_t self, const std::vector<ObjectRecord>& objects,
                   const ExperimentConfig& c) {
  return std::all_of(objects.begin(), objects.end(), [&](const ObjectRecord& o) {
    return o.id == self || o.status == ObjectStatus::lost || xy_gap(o.cloud, place) > reach + c.target_clearance;
  });
}

// A brute-force pass (not KdTree::nearest_within): the distance is horizontal, and a stone's
// cloud is a few thousand points.
double xy_gap(const PointCloud& cloud, const Vec2d& xy) {
  double g2 = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < cloud.size(); ++i) g2 = std::min(g2, (cloud.world(i).head<2>() - xy).squaredNorm());
  return std::sqrt(g2);
}

ExperimentResult run_experiment(const ExperimentConfig& config, const ExperimentProgress& progress) {
  validate(config);
  Stopwatch sw;
  Experiment e(config, progress);
  e.register_while_scanning();
  e.populate();
  if (config.experiment == "pile") e.clear_pile();
  else
    for (int r = 1; r <= rounds_of(config); ++r) e.run_round(r);
  e.finish(sw.lap_ms());
  return std::move(e.out);
}

namespace {
nlohmann::json timings_json(const Timings& t) {
  nlohmann::json j = nlohmann::json::object();
  for (const auto& [stage, ms] : t.stages) j[stage] = ms;
  return j;
}
nlohmann::json detection_json(const GraspDetection& d) {
  return {{"failed", d.failed}, {"signs", d.signs}, {"lifted_load_n", d.lifted_load},
          {"release_load_n", d.release_load}, {"jaw_travel_m", d.jaw_travel}, {"held_at_release", d.held_at_release}};
}
nlohmann::json or_null(double v) { return v >= 0 ? nlohmann::json(v) : nlohmann::json(nullptr); }
nlohmann::json finite_or_null(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }
/// A lowering estimate of the record (map frame z), null where nothing was commanded.
nlohmann::json commanded(const GraspRecord& g, double z) {
  return std::isfinite(g.place_ground_error_m) ? nlohmann::json(z) : nlohmann::json(nullptr);
}
}  // namespace

nlohmann::json to_json(const ExperimentResult& r) {
  const RegistrationOutcome& g = r.registration;
  nlohmann::json tries = nlohmann::json::array();
  for (const RegistrationAttempt& a : g.tries)
    tries.push_back({{"time_s", a.time}, {"accepted", a.accepted}, {"map_points", a.map_points},
                     {"rotation_error_deg", a.rotation_error_deg}, {"translation_error_m", a.translation_error_m},
                     {"ms", a.ms}, {"reason", a.reason}});
  nlohmann::json grasps = nlohmann::json::array();
  for (const GraspRecord& x : r.grasps)
    grasps.push_back({{"round", x.round}, {"object", x.object}, {"stone", x.stone}, {"attempt", x.attempt},
                      {"success", x.success}, {"failure_reasons", x.failure_reasons}, {"detected", x.detected},
                      {"detection", detection_json(x.detection)}, {"planning_ms", x.planning_ms},
                      {"force_closure", x.force_closure},
                      {"costs", {{"align_rad", x.costs.align}, {"enclose_m", x.costs.enclose}, {"dist_m", x.costs.dist}}},
                      {"T_map_gripper", pose_to_json(x.T_map_gripper)}, {"target", {x.target.x(), x.target.y()}},
                      {"target_error_m", or_null(x.target_error_m)}, {"sim_time_s", x.sim_time}, {"wall_s", x.wall_s},
                      {"place_error_m", or_null(x.place_error_m)},
                      {"placement", {{"com_estimate_error_m", or_null(x.com_estimate_error_m)},
                                     {"grip_drift_m", or_null(x.grip_drift_m)},
                                     {"release_drift_m", or_null(x.release_drift_m)},
                                     {"weighed_com_error_m", or_null(x.weighed_com_error_m)},
                                     {"place_correction_m", or_null(x.place_correction_m)},
                                     {"ground_z", commanded(x, x.place_ground_z)},
                                     {"bottom_z", commanded(x, x.place_bottom_z)},
                                     {"ground_error_m", finite_or_null(x.place_ground_error_m)},
                                     {"bottom_error_m", finite_or_null(x.place_bottom_error_m)}}},
                      {"others_moved_m", x.others_moved_m},
                      {"others_loaded", x.others_loaded},
                      {"database", {{"predicted_error_m", x.move.predicted_error_m},
                                    {"predicted_error_deg", x.move.predicted_error_deg},
                                    {"error_m", x.move.error_m}, {"error_deg", x.move.error_deg},
                                    {"found", x.move.found}, {"fitness", x.move.fitness}, {"rmse", x.move.rmse},
                                    {"reason", x.move.reason},
                                    {"ghost_share", x.move.ghost_share},
                                    {"carried_in_map", x.move.carried_in_map}}}});
  nlohmann::json rounds = nlohmann::json::array();
  for (const ExperimentRound& x : r.rounds) {
    nlohmann::json objects = nlohmann::json::array();
    for (const ExperimentObject& o : x.objects)
      objects.push_back({{"object", o.object}, {"stone", o.stone}, {"translation_error_m", o.translation_error_m},
                         {"rotation_error_deg", o.rotation_error_deg}, {"target_error_m", or_null(o.target_error_m)}});
    const RoundRecord& s = x.resegmentation;
    rounds.push_back({{"round", x.round}, {"objects", objects}, {"ghost_fraction", x.ghost_fraction}, {"lost", x.lost},
                      {"duplicated", x.duplicated},
                      {"resegmentation", {{"matched", s.matched}, {"new_objects", s.new_objects},
                                          {"new_on_tracked", s.new_on_tracked}, {"new_on_untracked", s.new_on_untracked},
                                          {"new_on_terrain", s.new_on_terrain}, {"vanished", s.vanished},
                                          {"moved_unexpectedly", s.moved_unexpectedly}, {"objects", s.objects}}}});
  }
  return {{"experiment", r.experiment},
          {"seed", r.seed},
          {"stones", r.stones},
          {"stones_tracked", r.stones_tracked},
          {"registration", {{"success", g.success}, {"first_success_s", or_null(g.first_success_s)},
                            {"attempts", g.attempts}, {"rotation_error_deg", g.rotation_error_deg},
                            {"translation_error_m", g.translation_error_m}, {"timings_ms", timings_json(g.timings)},
                            {"tries", tries}}},
          {"grasps", grasps},
          {"rounds", rounds},
          {"summary", {{"moves", r.moves}, {"placed", r.placed}, {"first_attempt_success", r.first_attempt_success},
                       {"within_attempts", r.within_attempts}, {"failures", r.failures},
                       {"failures_detected", r.failures_detected}, {"false_alarms", r.false_alarms},
                       {"pile_shifts", r.pile_shifts}, {"resegmentations", r.resegmentations},
                       {"found_again", r.found_again}}},
          {"notes", r.notes},
          {"timings_ms", timings_json(r.timings)}};
}

}  // namespace cairn::eval
