#include "cairn/mapping/mapper.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>

#include <tbb/task_group.h>

#include "cairn/core/error.hpp"
#include "cairn/core/kdtree.hpp"
#include "cairn/core/voxel_grid.hpp"
#include "cairn/registration/icp.hpp"
#include "cairn/mapping/self_filter.hpp"
#include "cairn/core/units.hpp"

namespace cairn {
namespace {


std::vector<Vec3f> downsample(std::span<const Vec3f> points, double leaf) {
  PointCloud c;
  c.points.assign(points.begin(), points.end());
  return voxel_downsample(c, {.res_voxel = leaf, .n_min = 1}).points;
}

int sensor_slot(const std::string& sensor) {
  if (sensor == "H") return 0;
  if (sensor == "V") return 1;
  throw InputError("mapping: unknown sensor '" + sensor + "' (expected H or V)");
}

}  // namespace

Mapper::Mapper(MapperSetup setup, MappingConfig config)
    : config_(std::move(config)), setup_(std::move(setup)), map_(config_.local_map) {
  config_.validate();
  const auto it = setup_.T_cabin_sensor.find("H");
  if (it == setup_.T_cabin_sensor.end()) throw InputError("mapping: no extrinsic T_cabin_H for the horizontal LiDAR");
  T_cabin_H_ = it->second;
}

void Mapper::add_state_estimate(const StampedPose& p) {
  if (!std::isfinite(p.time) || !p.pose.matrix().allFinite()) {
    spdlog::warn("mapping: non-finite state estimate at t = {} skipped", p.time);
    return;
  }
  if (!state_.empty() && p.time <= state_.back().time) {
    spdlog::warn("mapping: state estimate at t = {} is not after the previous one; skipped", p.time);
    return;
  }
  state_.push_back(p);
}

void Mapper::add_state_estimates(const std::vector<StampedPose>& poses) {
  state_.reserve(state_.size() + poses.size());
  for (const StampedPose& p : poses) add_state_estimate(p);
}

void Mapper::add_joint_state(const JointState& q) {
  if (!joints_.empty() && q.time <= joints_.back().time) return;
  joints_.push_back(q);
}

void Mapper::add_joint_states(const std::vector<JointState>& states) {
  for (const JointState& q : states) add_joint_state(q);
}

void Mapper::attach(const std::string& link, const Shape& shape, double t) {
  const int l = setup_.robot.link_index(link);
  if (l < 0) throw InputError("mapping: cannot attach '" + shape.name + "' to unknown link '" + link + "'");
  if (!std::isfinite(t)) throw InputError("mapping: attach at a non-finite time");
  attached_.push_back({.link = std::size_t(l), .shape = shape, .t_from = t, .t_to = INFINITY});
}

void Mapper::detach(double t) {
  if (!std::isfinite(t)) throw InputError("mapping: detach at a non-finite time");
  for (Attachment& a : attached_) a.t_to = std::min(a.t_to, t);
}

const RobotModel& Mapper::robot_during(double t0, double t1, RobotModel& buffer) const {
  bool any = false;
  for (const Attachment& a : attached_) {
    if (a.t_from > t1 || a.t_to <= t0) continue;  // [t_from, t_to) against the sweep's [t0, t1]
    if (!any) buffer = setup_.robot;
    any = true;
    buffer.links[a.link].shapes.push_back(a.shape);
  }
  return any ? buffer : setup_.robot;
}

Eigen::Isometry3d Mapper::T_world_cabin_estimate(double t) const { return interpolate_pose(state_, t); }

void Mapper::add_sweep(const std::string& sensor, const PointCloud& cloud, double t_start, double t_end) {
  const int s = sensor_slot(sensor);
  if (s == 1 && !setup_.T_cabin_sensor.contains("V"))
    throw InputError("mapping: a V sweep arrived but there is no extrinsic T_cabin_V");
  cloud.check_consistent("sweep " + sensor);
  if (!std::isfinite(t_start) || !std::isfinite(t_end) || t_end < t_start)
    throw InputError("mapping: sweep " + sensor + " has an invalid time span");
  if (state_.empty()) throw InputError("mapping: no state estimate before the first sweep");
  ++stats_.sweeps;
  const double period = std::max(t_end - t_start, 1e-3);
  if (t_start - last_sweep_start_[s] > 1.5 * period + 0.02 && last_sweep_start_[s] > -1e299) {
    ++stats_.time_gaps;
    spdlog::warn("mapping: time gap of {:.3f} s before the {} sweep at t = {:.3f}", t_start - last_sweep_start_[s],
                 sensor, t_start);
  }
  last_sweep_start_[s] = t_start;
  if (t_end > state_.back().time + 0.05 || t_start < state_.front().time - 0.05)
    spdlog::warn("mapping: the {} sweep at t = {:.3f} is not covered by the state estimate ({:.3f} .. {:.3f})",
                 sensor, t_start, state_.front().time, state_.back().time);
  if (cloud.empty()) {
    ++stats_.empty_sweeps;
    spdlog::warn("mapping: empty {} sweep at t = {:.3f} skipped", sensor, t_start);
    return;
  }
  stats_.points_in += cloud.size();
  Stopwatch sw;
  Pending p{.cloud = cloud, .keep = {}, .t_start = t_start, .t_end = t_end};
  if (config_.self_filter.enabled && joints_.empty())
    throw InputError("mapping: no joint states for the self-filter (disable mapping.self_filter.enabled?)");
  RobotModel holding;
  p.keep = self_filter(cloud, robot_during(t_start, t_end, holding), joints_, setup_.T_cabin_sensor.at(sensor), config_.self_filter,
                       0.5 * (t_start + t_end));
  stats_.points_self_filtered += cloud.size() - p.keep.size();
  timings_.add("self_filter", sw.lap_ms());

  auto mid = [](const Pending& x) { return 0.5 * (x.t_start + x.t_end); };
  std::optional<Pending>& mine = s == 0 ? pending_h_ : pending_v_;
  if (mine) {  // the previous sweep of this sensor found no partner: map it alone
    if (s == 0) process_pair(&*mine, nullptr);
    else process_pair(nullptr, &*mine);
    mine.reset();
  }
  mine = std::move(p);
  if (!setup_.T_cabin_sensor.contains("V")) {  // single-sensor setup
    process_pair(&*pending_h_, nullptr);
    pending_h_.reset();
    return;
  }
  if (pending_h_ && pending_v_) {
    if (std::abs(mid(*pending_h_) - mid(*pending_v_)) <= config_.max_pair_gap) {
      process_pair(&*pending_h_, &*pending_v_);
      pending_h_.reset();
      pending_v_.reset();
    } else {  // too far apart: the older one goes alone
      std::optional<Pending>& older = mid(*pending_h_) < mid(*pending_v_) ? pending_h_ : pending_v_;
      if (&older == &pending_h_) process_pair(&*older, nullptr);
      else process_pair(nullptr, &*older);
      older.reset();
    }
  }
}

void Mapper::flush() {
  if (pending_h_) process_pair(&*pending_h_, nullptr);
  if (pending_v_) process_pair(nullptr, &*pending_v_);
  pending_h_.reset();
  pending_v_.reset();
}

void Mapper::process_pair(const Pending* h, const Pending* v) {
  Stopwatch sw;
  auto input = [&](const Pending* p, const char* sensor) {
    return SweepInput{.cloud = &p->cloud, .keep = p->keep, .T_cabin_sensor = setup_.T_cabin_sensor.at(sensor),
                      .t_start = p->t_start, .t_end = p->t_end};
  };
  std::optional<SweepInput> hi, vi;
  if (h) hi = input(h, "H");
  if (v) vi = input(v, "V");
  ScanPair pair = assemble_scan_pair(hi ? &*hi : nullptr, vi ? &*vi : nullptr, T_cabin_H_, state_, config_.deskew);
  timings_.add("assembly", sw.lap_ms());
  ++stats_.pairs;
  if (!h || !v) ++stats_.single_sweep_pairs;
  const std::size_t expected = (h ? h->keep.size() : 0) + (v ? v->keep.size() : 0);
  stats_.points_non_finite += expected - pair.cloud.size();
  if (pair.cloud.empty()) {
    spdlog::warn("mapping: scan pair at t = {:.3f} has no valid points", pair.time);
    return;
  }
  const Eigen::Isometry3d T_raw = T_world_cabin_estimate(pair.time) * T_cabin_H_;
  if (!nodes_.empty() &&
      (T_raw.translation() - nodes_.back().T_world_H_raw.translation()).norm() < config_.d_poses) {
    ++stats_.skipped_pairs;  // Table 3: d_poses
    return;
  }
  add_node(std::move(pair), T_raw);
}

void Mapper::start_submap() {
  const ScanMatchingConfig& sm = config_.scan_matching;
  Stopwatch sw;
  // Table 3: m — the last m scan pairs at their current estimates, relative to an anchor position
  // (float precision far from the world origin).
  const std::size_t last = nodes_.size() - 1;
  const std::size_t first = nodes_.size() > std::size_t(config_.m) ? nodes_.size() - config_.m : 0;
  Submap submap{.center = last, .time = nodes_[last].time, .T_world_center = graph_.pose(int(last)),
                .anchor = graph_.pose(int(last)).translation().array().round().matrix(), .target = nullptr};
  std::vector<Vec3f> merged;
  for (std::size_t i = first; i <= last; ++i) {
    Eigen::Isometry3d T = graph_.pose(int(i));
    T.translation() -= submap.anchor;
    const Eigen::Isometry3f Tf = T.cast<float>();
    for (const Vec3f& p : nodes_[i].submap_points) merged.push_back(Tf * p);
  }
  next_submap_ = std::move(submap);
  next_submap_due_ = nodes_.size() - 1 + std::size_t(sm.submap_latency);
  const double gather_ms = sw.elapsed_ms();
  submap_task_->run([this, merged = std::move(merged), gather_ms] {
    Stopwatch bw;
    const ScanMatchingConfig& c = config_.scan_matching;
    std::vector<Vec3f> points = downsample(merged, c.submap_voxel);
    if (points.size() >= std::size_t(c.icp.min_correspondences))
      next_submap_->target = std::make_shared<const IcpTarget>(std::move(points), NormalConfig{.k = c.normal_k});
    background_submap_ms_ = gather_ms + bw.elapsed_ms();
  });
}

void Mapper::sync_background(bool all) {
  background_->wait();
  if (background_map_ms_ > 0.0) timings_.add("map_update", background_map_ms_);
  background_map_ms_ = 0.0;
  if (next_submap_ && (all || nodes_.size() >= next_submap_due_)) {
    submap_task_->wait();
    if (next_submap_->target) {
      submaps_.push_back(std::move(*next_submap_));
      ++stats_.submaps;
    }
    next_submap_.reset();
    timings_.add("submap", background_submap_ms_);
  }
}

Mapper::~Mapper() {
  background_->wait();
  submap_task_->wait();
}

const Mapper::Submap* Mapper::find_loop_submap(const Eigen::Isometry3d& T, double time) const {
  const ScanMatchingConfig& sm = config_.scan_matching;
  const Submap* best = nullptr;
  double best_d = sm.loop_radius;
  for (const Submap& s : submaps_) {
    if (time - s.time < sm.loop_min_age) continue;
    const Eigen::Isometry3d& Tc = graph_.pose(int(s.center));
    const double d = (Tc.translation() - T.translation()).norm();
    if (d < best_d && rotation_angle(Tc.linear().transpose() * T.linear()) < sm.loop_max_angle_deg * kDeg) {
      best_d = d;
      best = &s;
    }
  }
  return best;
}

Mapper::Match Mapper::match_scan(const std::vector<Vec3f>& source, const Eigen::Isometry3d& T_init,
                                 const Submap& submap, bool loop) const {
  const ScanMatchingConfig& sm = config_.scan_matching;
  Stopwatch sw;
  Match m{.center = submap.center, .loop = loop};
  // The submap holds its nodes at their poses when it was built; the graph has moved them since
  // (window updates, reoptimize()): the guess goes into the submap's frame through its centre.
  Eigen::Isometry3d T_anchor_init = submap.T_world_center * graph_.pose(int(submap.center)).inverse() * T_init;
  T_anchor_init.translation() -= submap.anchor;
  const IcpResult r = register_icp(source, *submap.target, T_anchor_init, sm.icp);
  m.ms = sw.elapsed_ms();
  spdlog::debug("mapping: ICP {} source points, {} target points, {} iterations, fitness {:.2f}, rmse {:.3f}",
                source.size(), submap.target->size(), r.iterations, r.fitness, r.rmse);
  const bool ok_status = r.status == IcpStatus::converged || r.status == IcpStatus::max_iterations;
  const Eigen::Isometry3d correction = T_anchor_init.inverse() * r.T_target_source;
  if (!ok_status || r.fitness < sm.min_fitness || correction.translation().norm() > sm.max_correction ||
      rotation_angle(correction.linear()) > sm.max_correction_deg * kDeg || !r.T_target_source.matrix().allFinite()) {
    spdlog::debug("mapping: ICP rejected (status {}, fitness {:.2f}, correction {:.3f} m)", to_string(r.status),
                  r.fitness, correction.translation().norm());
    return m;
  }
  // Hessian: left perturbation in the anchor frame → right perturbation of T_world_H.
  const double info_scale = loop ? sm.loop_info_scale : sm.info_scale;
  const Matrix6d A = adjoint(r.T_target_source);
  const Matrix6d H = A.transpose() * r.hessian * A * (info_scale / (sm.residual_sigma * sm.residual_sigma));
  m.information = cap_information(H, sm.min_sigma_rotation_deg * kDeg, sm.min_sigma_translation);
  Eigen::Isometry3d T_world_new = r.T_target_source;
  T_world_new.translation() += submap.anchor;
  m.z = submap.T_world_center.inverse() * T_world_new;
  m.ok = true;
  return m;
}

void Mapper::add_node(ScanPair pair, const Eigen::Isometry3d& T_raw) {
  Stopwatch sw;
  const ScanMatchingConfig& sm = config_.scan_matching;
  Node node{.time = pair.time, .T_world_H_raw = T_raw, .map_points = {}, .submap_points = {}};
  // Points beyond 1.5 R_map from the sensor never stay in the local map and are sparse and noisy:
  // they are dropped before the map and the ICP see them.
  const float max_range2 = float(std::pow(1.5 * config_.local_map.R_map, 2));
  std::erase_if(pair.cloud.points, [&](const Vec3f& p) { return p.squaredNorm() > max_range2; });
  pair.cloud.times.clear();
  node.map_points = downsample(pair.cloud.points, config_.local_map.voxel.res_voxel);
  node.submap_points = downsample(node.map_points, sm.submap_voxel);
  const std::vector<Vec3f> source = downsample(node.submap_points, sm.source_voxel);
  timings_.add("downsample", sw.lap_ms());
  sync_background(false);  // the previous node's map update, the submap when it is due
  sw.lap_ms();

  const PoseGraphConfig& g = config_.pose_graph;
  const bool first = nodes_.empty();
  Eigen::Isometry3d T_init = T_raw;
  if (!first) {  // odometry: previous optimised pose + state-estimate motion since then
    const int prev = int(nodes_.size()) - 1;
    T_init = graph_.pose(prev) * nodes_.back().T_world_H_raw.inverse() * T_raw;
  }
  // Sec. 4.2, step 3: scan-to-submap ICP + a loop closure against an older submap of the same
  // view, both from the odometry guess, concurrently.
  Match seq, loop;
  if (!first && sm.enabled && !submaps_.empty()) {
    const Submap* loop_submap = sm.loop_closures ? find_loop_submap(T_init, node.time) : nullptr;
    tbb::task_group icps;
    if (loop_submap) icps.run([&] { loop = match_scan(source, T_init, *loop_submap, true); });
    seq = match_scan(source, T_init, submaps_.back(), false);
    icps.wait();
    for (const Match* m : {&seq, &loop})
      if (m->ms > 0.0) {
        timings_.add("icp", m->ms);
        if (!m->ok) ++stats_.icp_rejected;
      }
    if (seq.ok) T_init = graph_.pose(int(seq.center)) * seq.z;
  }
  timings_.add("icp_wall", sw.lap_ms());

  const int n = graph_.add_node(T_init);
  if (!first) {
    const Node& prev = nodes_.back();
    const double dt = std::abs(node.time - prev.time);
    const double st = g.odometry_sigma_translation + g.odometry_translation_rate * dt;
    const double sr = (g.odometry_sigma_rotation_deg + g.odometry_rotation_rate_deg * dt) * kDeg;
    graph_.add_relative(EdgeKind::odometry, n - 1, n, prev.T_world_H_raw.inverse() * T_raw,
                        diagonal_information(Eigen::Vector3d::Constant(sr), Eigen::Vector3d::Constant(st)));
    if (seq.ok && sm.sequential_edges) {
      graph_.add_relative(EdgeKind::scan_matching, int(seq.center), n, seq.z, seq.information);
      ++stats_.scan_edges;
    }
    if (loop.ok) {
      graph_.add_relative(EdgeKind::scan_matching, int(loop.center), n, loop.z, loop.information);
      ++stats_.loop_edges;
    }
  }
  if (g.priors || first) {
    const double rp = g.prior_sigma_roll_pitch_deg * kDeg;
    graph_.add_prior(n, T_raw,
                     diagonal_information({rp, rp, g.prior_sigma_yaw_deg * kDeg},
                                          Eigen::Vector3d::Constant(g.prior_sigma_translation)));
  }
  graph_.optimize(n - g.window + 1, g.window_iterations);
  timings_.add("pose_graph", sw.lap_ms());
  nodes_.push_back(std::move(node));
  ++stats_.nodes;
  // Map update and submap build overlap with the assembly of the next pair (the other core).
  background_->run([this] {
    Stopwatch bw;
    update_map(nodes_.size() - 1);
    background_map_ms_ = bw.elapsed_ms();
  });
  const std::size_t last_center = next_submap_ ? next_submap_->center
                                  : submaps_.empty()  ? 0
                                                      : submaps_.back().center;
  const bool no_submap = submaps_.empty() && !next_submap_;
  if (sm.enabled && (no_submap || nodes_.size() - 1 - last_center >= std::size_t(sm.submap_every))) {
    if (next_submap_) sync_background(true);  // still building (latency > submap_every)
    start_submap();
  }
}

void Mapper::update_map(std::size_t i) {
  map_.insert(nodes_[i].map_points, graph_.pose(int(i)));
  if ((i + 1) % std::size_t(config_.local_map.crop_every) == 0)
    map_.crop((graph_.pose(int(i)) * T_cabin_H_.inverse()).translation());
}

void Mapper::rebuild_map(bool final_crop) {
  map_.clear();
  auto apply_edits = [&](std::size_t after) {
    for (const Edit& e : edits_) {
      if (e.after_node != after) continue;
      map_.apply(e.edit.transformed(edit_motion(e)));
    }
  };
  for (std::size_t i = 0; i < nodes_.size(); ++i) {
    apply_edits(i);
    update_map(i);
  }
  apply_edits(nodes_.size());
  if (final_crop && !nodes_.empty()) map_.crop(current_pose().translation());
}

void Mapper::solve_all(const char* solve_timing, bool rebuild, bool final_crop, const char* rebuild_timing) {
  Stopwatch sw;
  graph_.optimize(0, config_.pose_graph.final_iterations);
  timings_.add(solve_timing, sw.lap_ms());
  if (rebuild) rebuild_map(final_crop);
  timings_.add(rebuild_timing, sw.lap_ms());
}

void Mapper::finish() {
  flush();
  sync_background(true);
  solve_all("final_optimisation", config_.rebuild_on_finish, /*final_crop=*/true, "map_rebuild");
}

void Mapper::reoptimize() {
  sync_background(false);
  // The same content as the streaming map (cropped every crop_every nodes only), at the new poses.
  solve_all("reoptimisation", /*rebuild=*/true, /*final_crop=*/false, "reoptimisation_rebuild");
}

Eigen::Isometry3d Mapper::edit_motion(const Edit& e) const {
  if (e.after_node == 0) return Eigen::Isometry3d::Identity();
  return graph_.pose(int(e.after_node - 1)) * e.T_world_anchor.inverse();
}

void Mapper::record_edit(Edit e) {
  e.after_node = nodes_.size();
  if (!nodes_.empty()) e.T_world_anchor = graph_.pose(int(nodes_.size() - 1));
  edits_.push_back(std::move(e));
}

std::size_t Mapper::remove_sphere(const Vec3d& center, double radius) {
  return apply_edit(MapEdit::sphere(center, radius));
}

void Mapper::insert(const PointCloud& points) { (void)apply_edit(MapEdit::add(points)); }

std::size_t Mapper::apply_edit(const MapEdit& edit) {
  try {
    edit.validate();
  } catch (const InputError& e) {
    throw InputError(std::string("mapping: ") + e.what());
  }
  sync_background(true);
  record_edit({.edit = edit});
  return map_.apply(edit);
}

std::vector<StampedPose> Mapper::trajectory() const {
  std::vector<StampedPose> out;
  for (std::size_t i = 0; i < nodes_.size(); ++i)
    out.push_back({nodes_[i].time, graph_.pose(int(i)) * T_cabin_H_.inverse()});
  return out;
}

std::vector<StampedPose> Mapper::raw_trajectory() const {
  std::vector<StampedPose> out;
  for (const Node& n : nodes_) out.push_back({n.time, n.T_world_H_raw * T_cabin_H_.inverse()});
  return out;
}

Eigen::Isometry3d Mapper::current_pose() const {
  if (nodes_.empty()) return Eigen::Isometry3d::Identity();
  return graph_.pose(graph_.num_nodes() - 1) * T_cabin_H_.inverse();
}

MapRunResult map_sweeps(const MapRunInputs& inputs, const SweepSource& next, const MappingConfig& config,
                        const MappingProgress& progress) {
  Stopwatch total;
  Mapper mapper({.robot = inputs.robot, .T_cabin_sensor = inputs.T_cabin_sensor}, config);
  mapper.add_state_estimates(inputs.state_estimate);
  mapper.add_joint_states(inputs.joint_states);
  const std::size_t total_pairs = (inputs.num_sweeps + 1) / 2;
  double read_ms = 0.0;
  std::size_t k = 0;
  RecordedSweep sweep;
  for (;; ++k) {
    Stopwatch sw;
    if (!next(sweep)) break;
    read_ms += sw.elapsed_ms();
    mapper.add_sweep(sweep.sensor, sweep.cloud, sweep.t_start, sweep.t_end);
    if (progress && (k % 2 == 1 || k + 1 == inputs.num_sweeps)) progress((k + 1) / 2, total_pairs);
  }
  if (k == 0) throw InputError("mapping: " + inputs.name + " holds no scans");
  const double online_seconds = total.elapsed_ms() / 1000.0;
  mapper.finish();
  MapRunResult r;
  r.online_seconds = online_seconds;
  Stopwatch sw;
  r.map = mapper.map();
  r.timings = mapper.timings();
  r.timings.stages.insert(r.timings.stages.begin(), {"read_sweeps", read_ms});
  r.timings.add("map_snapshot", sw.elapsed_ms());
  r.trajectory = mapper.trajectory();
  r.raw_trajectory = mapper.raw_trajectory();
  r.stats = mapper.stats();
  r.seconds = total.elapsed_ms() / 1000.0;
  return r;
}

MapRunResult map_run(const io::RunDirectory& run, const MappingConfig& config, const MappingProgress& progress) {
  if (run.scans.empty()) throw InputError("mapping: " + run.root.string() + " holds no scans");
  const MapRunInputs inputs{.robot = run.robot, .T_cabin_sensor = run.T_cabin_sensor,
                            .state_estimate = run.state_estimate, .joint_states = run.joint_states,
                            .num_sweeps = run.scans.size(), .name = run.root.string()};
  std::size_t k = 0;
  const SweepSource files = [&](RecordedSweep& out) {
    if (k == run.scans.size()) return false;
    const io::ScanInfo& s = run.scans[k++];
    out = {.sensor = s.sensor, .cloud = run.read_scan(s), .t_start = s.t_start, .t_end = s.t_end};
    return true;
  };
  return map_sweeps(inputs, files, config, progress);
}

}  // namespace cairn
