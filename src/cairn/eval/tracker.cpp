#include "cairn/eval/tracker.hpp"

#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <numbers>

#include "cairn/core/error.hpp"
#include "cairn/core/kdtree.hpp"
#include "cairn/core/transform.hpp"
#include "cairn/mapping/mapper.hpp"
#include "cairn/objects/pipeline.hpp"
#include "cairn/core/units.hpp"

namespace cairn::eval {
namespace {

using Eigen::Isometry3d;

Isometry3d yaw_pose(const Vec3d& p, double yaw) {
  Isometry3d T = pure_translation(p.x(), p.y(), p.z());
  T.rotate(Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()));
  return T;
}

/// Height range of the terrain over a disc of radius r: slope and bumps together (a stone put
/// down where this is small stays where it is put).
double ground_unevenness(const sim::Terrain& t, const Eigen::Vector2d& c, double r) {
  double lo = INFINITY, hi = -INFINITY;
  for (int i = -4; i <= 4; ++i)
    for (int j = -4; j <= 4; ++j) {
      const Eigen::Vector2d q = c + r / 4.0 * Eigen::Vector2d(i, j);
      if ((q - c).norm() > r) continue;
      const double h = t.height(q.x(), q.y());
      lo = std::min(lo, h), hi = std::max(hi, h);
    }
  return hi - lo;
}

}  // namespace

Isometry3d db_motion(const std::vector<PoseUpdate>& history) {
  Isometry3d A = Isometry3d::Identity();
  for (const PoseUpdate& h : history)
    if (h.cause != PoseCause::created) A = h.transform * A;
  return A;
}

sim::SimulationConfig at_rest(const ObjectTrackingConfig& c) {
  c.objects.validate();
  if (c.rounds < 1 || !(c.initial_scan > 0) || !(c.rescan > 0) || !(c.carry_time >= 0))
    throw ConfigError("object tracking: rounds >= 1 and positive scan times are required");
  sim::SimulationConfig s = c.simulation;
  s.settle_in_physics = true;  // one world at rest for the sensors, the physics and the truth
  return s;
}

Tracker::~Tracker() {
  db_.reset();
  if (temporary_.empty()) return;
  std::error_code ec;
  for (const char* side : {"", "-wal", "-shm"}) std::filesystem::remove(temporary_.string() + side, ec);
}

Tracker::Tracker(const ObjectTrackingConfig& c, const TrackingProgress& progress, double duration)
    : cfg_(c), progress_(progress), machine_(at_rest(c), c.seed, duration, c.mapping) {
  std::filesystem::path file = c.database;
  if (file.empty()) {
    file = std::filesystem::temp_directory_path() / ("cairn_tracking_" + std::to_string(::getpid()) + ".db");
    temporary_ = file;
  }
  if (std::filesystem::exists(file))  // never overwrite a database someone kept
    throw InputError(file.string() + ": exists; the experiment writes a new object database (remove it or choose another)");
  db_ = std::make_unique<ObjectDatabase>(file, ObjectDatabase::Mode::create);
  result.scenario = c.scenario;
  result.seed = c.seed;
  result.stones = int(machine_.world().site.stones.size());
  plan_slots();
}

std::shared_ptr<const SurfaceTruth> Tracker::truth() const {
  // The truth's inputs that a run can change: the stones' world-frame meshes (every move goes
  // through them; their triangles, the terrain, the spacing and the seed are fixed). The base is
  // fixed today and in the key all the same.
  const sim::Site& site = machine_.world().site;
  const Vec3d base = machine_.base();
  std::vector<double> key{base.x(), base.y(), base.z()};
  for (const sim::Stone& s : site.stones)
    for (std::size_t i = 0; i < s.mesh.vertices.size(); ++i) {
      const Vec3d v = s.mesh.vertices.world(i);
      key.insert(key.end(), {v.x(), v.y(), v.z()});
    }
  if (truth_ == nullptr || key != truth_key_) {
    truth_ = std::make_shared<const SurfaceTruth>(site, base, kTruthRadius, cfg_.truth_spacing, cfg_.seed);
    truth_key_ = std::move(key);
  }
  return truth_;
}

void Tracker::initial_scan() {
  if (progress_) progress_("initial scan", 0, 1);
  machine_.scan(0.0, cfg_.initial_scan);
}

int Tracker::stone_of(const PointCloud& cloud, const SurfaceTruth& t, const Isometry3d& E, double* share) const {
  return t.stone_of(cloud, E, cfg_.score_near, machine_.world().site.stones.size(), share);
}

void Tracker::populate() {
  const PointCloud map = machine_.mapper().map();
  const std::vector<PointCloud> segments = object_segments(map, segment(map, cfg_.segmentation));
  const ObjectsUpdate u = update_objects(*db_, map, segments, cfg_.objects.association, machine_.now(), "segmentation");
  const auto t = truth();
  const Isometry3d E0 = t->offset->map_offset(map);
  // Each object to the stone most of its points lie on (world = E0 · map).
  std::vector<int> objects_per_stone(machine_.world().site.stones.size(), 0);
  std::vector<Tracked> candidates;
  for (const ObjectRecord& r : db_->objects()) {
    double purity = 0.0;
    const int k = stone_of(r.cloud, *t, E0, &purity);
    if (k < 0) {
      result.unmatched.push_back("object " + std::to_string(r.id) + " lies on no stone");
      continue;
    }
    ++objects_per_stone[std::size_t(k)];
    candidates.push_back({.stone = k, .object = r.id, .created_centroid = r.centroid, .E0 = E0,
                          .M = Isometry3d::Identity(), .purity = purity});
  }
  for (const Tracked& c : candidates) {
    if (objects_per_stone[std::size_t(c.stone)] == 1) tracked_.push_back(c);
    else result.unmatched.push_back("stone " + std::to_string(c.stone) + " has several objects");
  }
  for (std::size_t k = 0; k < objects_per_stone.size(); ++k)
    if (objects_per_stone[k] == 0) result.unmatched.push_back("stone " + std::to_string(k) + " has no object");
  result.objects_created = int(u.association.new_segments.size());
  result.stones_tracked = int(tracked_.size());
}

RemovalCounts Tracker::removal(const PointCloud& map, const MapEdit& edit, const SurfaceTruth& t, const Isometry3d& E,
                               int stone) const {
  RemovalCounts c;
  const MapEditRegion region(edit);
  for (std::size_t i = 0; i < map.size(); ++i) {
    const Vec3d p = map.world(i);
    const std::int32_t l = t.label_near(E * p, cfg_.score_near);
    const bool removed = region.removes(p);
    if (l == stone) (removed ? c.object : c.object_left)++;
    else if (removed && l >= 0) ++c.neighbours;
    else if (removed) ++c.ground;  // terrain, or nothing true near (noise on the ground)
  }
  return c;
}

void Tracker::plan_slots() {
  const double heading = cfg_.simulation.excavator.base_yaw_deg / kDegPerRad;
  std::vector<std::pair<double, Vec3d>> outer, inner;
  const double s = cfg_.slot_spacing;
  for (double x = -cfg_.slot_max_distance; x <= cfg_.slot_max_distance; x += s)
    for (double y = -cfg_.slot_max_distance; y <= cfg_.slot_max_distance; y += s) {
      const Eigen::Vector2d xy = machine_.base().head<2>() + Eigen::Rotation2Dd(heading) * Eigen::Vector2d(x, y);
      const double d = Eigen::Vector2d(x, y).norm(), angle = std::abs(std::atan2(y, x)) * kDegPerRad;
      if (d < cfg_.slot_min_distance || d > cfg_.slot_max_distance || angle > cfg_.slot_max_angle_deg) continue;
      const Vec3d p(xy.x(), xy.y(), machine_.world().site.terrain.height(xy.x(), xy.y()));
      (d >= cfg_.slot_split_distance ? outer : inner)
          .emplace_back(ground_unevenness(machine_.world().site.terrain, xy, cfg_.slot_footprint), p);
    }
  for (auto* v : {&outer, &inner}) std::sort(v->begin(), v->end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  for (const auto& [_, p] : outer) slots_odd_.push_back(p);
  for (const auto& [_, p] : inner) slots_even_.push_back(p);
}

bool Tracker::slot_clear(const Eigen::Vector2d& xy, int stone, double half) const {
  for (std::size_t j = 0; j < machine_.world().site.stones.size(); ++j) {
    if (int(j) == stone) continue;
    const auto& b = machine_.world().site.stones[j].bounds;
    const Eigen::Vector2d q = xy.cwiseMax(b.min().head<2>()).cwiseMin(b.max().head<2>());
    if ((q - xy).norm() <= half + cfg_.slot_clearance) return false;
  }
  return true;
}

std::optional<Vec3d> Tracker::free_slot(int round, int stone) const {
  const sim::Stone& s = machine_.world().site.stones[std::size_t(stone)];
  const double half = 0.5 * (s.bounds.max() - s.bounds.min()).head<2>().norm();
  // The round's slots first, then the others (stones that rolled may sit on the round's slots).
  for (const auto* slots : round % 2 == 1 ? std::array{&slots_odd_, &slots_even_} : std::array{&slots_even_, &slots_odd_})
    for (const Vec3d& slot : *slots)
      if (slot_clear(slot.head<2>(), stone, half) && (slot - s.centroid).head<2>().norm() > 2.0 * half) return slot;
  return std::nullopt;
}

void Tracker::score(MoveRecord& m, const Tracked& tr, const Isometry3d& E, bool predicted) const {
  const Isometry3d A = db_motion(db_->history(tr.object));
  const Isometry3d A_true = E.inverse() * tr.M * tr.E0;  // the truth's motion in the map frame
  const double e_m = (A * tr.created_centroid - A_true * tr.created_centroid).norm();
  const double e_deg = rotation_angle(A.linear().transpose() * A_true.linear()) * kDegPerRad;
  (predicted ? m.predicted_error_m : m.error_m) = e_m;
  (predicted ? m.predicted_error_deg : m.error_deg) = e_deg;
}

double Tracker::ghost_share(const PointCloud& map, const SurfaceTruth& now, const Isometry3d& E) const {
  if (former_.empty() || map.empty()) return 0.0;
  const KdTree former(former_.points);
  std::size_t ghosts = 0;
  const float near2 = float(cfg_.score_near * cfg_.score_near);
  for (std::size_t i = 0; i < map.size(); ++i) {
    const Vec3d w = E * map.world(i);
    if (now.label_near(w, cfg_.score_near) != kLabelNone) continue;  // on a true surface
    float d2 = 0.0f;
    (void)former.nearest_within((w - former_.origin).cast<float>(), near2, &d2);
    ghosts += d2 <= near2;
  }
  return double(ghosts) / double(map.size());
}

Operation Tracker::commit_grasp(MoveRecord& m, const Tracked& tr, const Isometry3d& T_MG_grasp, const PointCloud& map,
                                const SurfaceTruth& before, const Isometry3d& E) {
  const ObjectRecord obj = *db_->object(tr.object);
  GraspRemovalConfig sphere = cfg_.objects.grasp_removal, voxels = cfg_.objects.grasp_removal;
  sphere.method = "sphere";
  voxels.method = "object_voxels";
  m.sphere = removal(map, grasp_map_edit(obj, sphere), before, E, tr.stone);
  m.object_voxels = removal(map, grasp_map_edit(obj, voxels), before, E, tr.stone);
  Operation grasp = grasp_operation(obj, T_MG_grasp, machine_.now(), cfg_.objects.grasp_removal);
  (void)db_->commit(grasp);
  for (const MapEdit& e : grasp.map_edits) (void)machine_.mapper().apply_edit(e);
  for (std::size_t i = 0; i < before.cloud.size(); ++i)
    if (before.cloud.labels[i] == tr.stone) former_.points.push_back((before.cloud.world(i) - former_.origin).cast<float>());
  return grasp;
}

void Tracker::world_moved(std::span<const Isometry3d> poses) {
  for (Tracked& t : tracked_) t.M = poses[std::size_t(t.stone)] * t.M;
}

namespace {

/// Map points (E: map -> world) floating: farther than `near` from every true surface and higher
/// than `height` above the terrain (not the ground's own noise, but what hangs in the air).
std::size_t floating(const PointCloud& map, const SurfaceTruth& truth, const sim::Terrain& terrain,
                     const Isometry3d& E, double near, double height) {
  std::size_t n = 0;
  for (std::size_t i = 0; i < map.size(); ++i) {
    const Vec3d w = E * map.world(i);
    n += w.z() > terrain.height(w.x(), w.y()) + height && truth.label_near(w, near) == kLabelNone;
  }
  return n;
}

}  // namespace

Isometry3d top_down_hold(const ObjectRecord& obj) {
  Eigen::Matrix3d R;
  R.col(0) = -Vec3d::UnitZ();
  R.col(1) = Vec3d::UnitY();
  R.col(2) = R.col(0).cross(R.col(1));
  double top = obj.centroid.z();
  for (std::size_t i = 0; i < obj.cloud.size(); ++i) top = std::max(top, obj.cloud.world(i).z());
  Isometry3d T_MG = Isometry3d::Identity();
  T_MG.linear() = R;
  T_MG.translation() = Vec3d(obj.centroid.x(), obj.centroid.y(), top);
  return T_MG;
}

long Tracker::scan_while_carrying(const Tracked& tr, const Isometry3d& T_world_G, const Isometry3d& T_MG,
                                  double t_from, double t_to) {
  // The arm moves after the last joint reading the mapper has (so none of the parked arm is read
  // as carrying).
  const double t_hold = std::max(t_from, std::nextafter(machine_.joints_fed_until(), INFINITY));
  if (!(cfg_.carry_scan > 0.0) || !(t_to > t_hold)) return -1;
  sim::SimulatedWorld& world = machine_.world();
  const auto truth_now = truth();  // the stone where the site has it; it is in the air meanwhile
  const PointCloud before = machine_.mapper().map();
  const Isometry3d E = truth_now->offset->map_offset(before);
  const sim::Terrain& ground = world.site.terrain;
  const std::size_t floating_before = floating(before, *truth_now, ground, E, cfg_.score_near, cfg_.floating_height);
  sim::hold_stone(world, std::size_t(tr.stone), T_world_G, t_hold, machine_.config());
  const auto let_go = [&] {  // after the last joint reading of the carry, too
    const double t = std::max(t_to, std::nextafter(machine_.joints_fed_until(), INFINITY));
    machine_.mapper().detach(t);
    (void)sim::release_stone(world, t, machine_.config());
  };
  try {
    if (cfg_.filter_carried) {
      const ObjectRecord obj = *db_->object(tr.object);
      std::vector<Vec3d> in_gripper;
      in_gripper.reserve(obj.cloud.size());
      const Isometry3d T_GM = T_MG.inverse();
      for (std::size_t i = 0; i < obj.cloud.size(); ++i) in_gripper.push_back(T_GM * obj.cloud.world(i));
      if (!in_gripper.empty())
        machine_.mapper().attach(kGripperLink, bounding_box_shape("carried_object", in_gripper), t_hold);
    }
    machine_.scan(t_hold, t_to);
  } catch (...) {  // the world lets go of the stone whatever happened
    let_go();
    throw;
  }
  let_go();
  const PointCloud after = machine_.mapper().map();
  return long(floating(after, *truth_now, ground, E, cfg_.score_near, cfg_.floating_height)) - long(floating_before);
}

RealignResult Tracker::rescan_and_realign(MoveRecord& m, const Tracked& tr, double t0) {
  machine_.scan(t0, t0 + cfg_.rescan);
  const PointCloud rescanned = machine_.mapper().map();
  const auto after = truth();
  const Isometry3d E_after = after->offset->map_offset(rescanned);
  const RealignResult r =
      relocate_object(*db_->object(tr.object), rescanned, db_->objects(), cfg_.objects, cfg_.segmentation);
  (void)db_->commit(realign_operation(*db_->object(tr.object), r, machine_.now()));
  m.found = r.found;
  m.fitness = r.fitness;
  m.rmse = r.rmse;
  m.reason = r.reason;
  score(m, tr, E_after, /*predicted=*/false);
  m.ghost_share = ghost_share(rescanned, *after, E_after);
  m.map_points = rescanned.size();
  return r;
}

bool Tracker::move(int round, Tracked& tr) {
  const ObjectRecord obj = *db_->object(tr.object);
  if (obj.status == ObjectStatus::lost) {  // the machine does not grasp what it has lost
    result.unmatched.push_back("round " + std::to_string(round) + ": object " + std::to_string(tr.object) +
                               " (stone " + std::to_string(tr.stone) + ") is lost, not moved");
    return false;
  }
  const std::optional<Vec3d> free = free_slot(round, tr.stone);
  if (!free) {
    result.unmatched.push_back("round " + std::to_string(round) + ": no free slot for stone " + std::to_string(tr.stone));
    return false;
  }
  const Vec3d slot = *free;
  MoveRecord m{.round = round, .stone = tr.stone, .object = tr.object, .purity = tr.purity, .time = machine_.now()};
  const PointCloud map = machine_.mapper().map();
  const auto before = truth();
  const Isometry3d E = before->offset->map_offset(map);
  // Grasp (Sec. 4.5): the gripper at the object's centroid.
  const Isometry3d T_MG_grasp = yaw_pose(obj.centroid, 0.0);
  (void)commit_grasp(m, tr, T_MG_grasp, map, *before, E);
  // Carry: commanded in the map frame, executed where the state estimate puts the gripper.
  const double t_grasp = machine_.now(), t_release = t_grasp + cfg_.carry_time;
  // Lifted by a top-down gripper on the object's top, the sensors scanning meanwhile.
  const Isometry3d T_MG_hold = top_down_hold(obj);
  m.carried_in_map = scan_while_carrying(tr, machine_.E_state(t_grasp) * T_MG_hold, T_MG_hold, t_grasp,
                                         t_grasp + std::min(cfg_.carry_scan, cfg_.carry_time));
  // The stone keeps its seat: tilted with the ground from under it to under the slot, then turned.
  const sim::Terrain& ground = machine_.world().site.terrain;
  const Eigen::Quaterniond tilt = Eigen::Quaterniond::FromTwoVectors(ground.normal(obj.centroid.x(), obj.centroid.y()),
                                                                     ground.normal(slot.x(), slot.y()));
  Isometry3d T_MG_release = yaw_pose(Vec3d(slot.x(), slot.y(), obj.centroid.z()), cfg_.turn_deg / kDegPerRad);
  T_MG_release.linear() = tilt.toRotationMatrix() * T_MG_release.linear();
  const Isometry3d commanded = machine_.E_state(t_release) * T_MG_release * T_MG_grasp.inverse() * machine_.E_state(t_grasp).inverse();
  const sim::CarryResult carry = sim::carry_and_release(machine_.world(), std::size_t(tr.stone), commanded,
                                                          machine_.config().drop_height, machine_.config());
  std::vector<Isometry3d> poses = carry.settling;
  poses[std::size_t(tr.stone)] = carry.total;
  world_moved(poses);
  const Isometry3d settle = carry.total * carry.carried.inverse();
  const Vec3d c_now = machine_.world().site.stones[std::size_t(tr.stone)].centroid;  // after the settling
  m.settle_m = (c_now - settle.inverse() * c_now).norm();
  m.settle_deg = rotation_angle(settle.linear()) * kDegPerRad;
  m.moved_m = (c_now - carry.total.inverse() * c_now).norm();
  m.turned_deg = rotation_angle(carry.total.linear()) * kDegPerRad;
  spdlog::debug("objects track: stone {} to slot ({:.2f}, {:.2f}): lift {:.3f} m, settled {} by {:.3f} m {:.1f} deg",
                tr.stone, slot.x(), slot.y(), carry.lift, carry.settled, m.settle_m, m.settle_deg);
  // Release (Eq. 3): the arm lowered the stone by `lift` until it touched the ground.
  T_MG_release = Eigen::Translation3d(0.0, 0.0, carry.lift) * T_MG_release;
  (void)db_->commit(release_operation(*db_->object(tr.object), T_MG_release, t_release));
  score(m, tr, E, /*predicted=*/true);
  // Rescan, re-align (Sec. 4.5), score.
  (void)rescan_and_realign(m, tr, t_release);
  result.moves.push_back(m);
  return true;
}

void Tracker::run_round(int round) {
  RoundRecord rr{.round = round};
  const int n = cfg_.max_moves_per_round > 0 ? std::min<int>(cfg_.max_moves_per_round, int(tracked_.size()))
                                             : int(tracked_.size());
  for (int i = 0; i < n; ++i) {
    if (progress_) progress_("round " + std::to_string(round), i, n);
    if (!move(round, tracked_[std::size_t(i)])) continue;
    const MoveRecord& m = result.moves.back();
    ++rr.moves;
    rr.within_tolerance += m.error_m <= 0.02 && m.error_deg <= 1.0;
    rr.max_error_m = std::max(rr.max_error_m, m.error_m);
    rr.max_error_deg = std::max(rr.max_error_deg, m.error_deg);
  }
  resegment(rr);
  result.rounds.push_back(rr);
}

int Tracker::adopt_new_objects() {
  const PointCloud map = machine_.mapper().map();
  const auto t = truth();
  const Isometry3d E = t->offset->map_offset(map);
  const auto is_tracked = [&](auto pred) { return std::any_of(tracked_.begin(), tracked_.end(), pred); };
  std::map<int, std::vector<Tracked>> on_stone;  // untracked objects per stone
  for (const ObjectRecord& r : db_->objects()) {
    if (r.status == ObjectStatus::lost || is_tracked([&](const Tracked& x) { return x.object == r.id; })) continue;
    double purity = 0.0;
    const int k = stone_of(r.cloud, *t, E, &purity);
    if (k < 0 || is_tracked([&](const Tracked& x) { return x.stone == k; })) continue;
    // Scored from now on (score: the stored motion since creation A against the truth's): as if
    // created where A takes it back to, the truth's motion since then equal to A.
    const Isometry3d A = db_motion(db_->history(r.id));
    on_stone[k].push_back({.stone = k, .object = r.id, .created_centroid = A.inverse() * r.centroid, .E0 = E * A,
                           .M = Isometry3d::Identity(), .purity = purity});
  }
  int adopted = 0;
  for (const auto& [k, objects] : on_stone)
    if (objects.size() == 1) tracked_.push_back(objects.front()), ++adopted;
  result.stones_tracked = int(tracked_.size());
  return adopted;
}

void Tracker::resegment(RoundRecord& rr) {
  const PointCloud map = machine_.mapper().map();
  const std::vector<PointCloud> segments = object_segments(map, segment(map, cfg_.segmentation));
  const ObjectsUpdate u = update_objects(*db_, map, segments, cfg_.objects.association, machine_.now(), "segmentation");
  rr.matched = u.association.matched.size();
  rr.new_objects = u.association.new_segments.size();
  rr.vanished = u.association.vanished.size();
  rr.moved_unexpectedly = u.association.moved.size();
  rr.objects = db_->objects(false).size();
  const auto t = truth();
  const Isometry3d E = t->offset->map_offset(map);
  for (std::size_t seg : u.association.new_segments) {
    const int k = stone_of(segments[seg], *t, E);
    const bool tracked = std::any_of(tracked_.begin(), tracked_.end(), [&](const Tracked& x) { return x.stone == k; });
    (k < 0 ? rr.new_on_terrain : tracked ? rr.new_on_tracked : rr.new_on_untracked)++;
  }
}

}  // namespace cairn::eval
