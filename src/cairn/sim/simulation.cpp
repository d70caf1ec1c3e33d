#include "cairn/sim/simulation.hpp"

#include <spdlog/spdlog.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>

#include "cairn/core/config.hpp"
#include "cairn/core/error.hpp"
#include "cairn/core/image.hpp"
#include "cairn/core/io/colmap.hpp"
#include "cairn/core/io/io.hpp"
#include "cairn/core/io/run_dir.hpp"
#include "cairn/core/io/trajectory.hpp"
#include "cairn/core/log.hpp"
#include "cairn/core/units.hpp"
#include "cairn/sim/world.hpp"

#ifndef CAIRN_DEFAULT_REAL_MESH_DIR
#define CAIRN_DEFAULT_REAL_MESH_DIR ""
#endif

namespace cairn::sim {

namespace fs = std::filesystem;

namespace {

// Scenario geometry [m].
constexpr double kSiteSize = 30.0;          // terrain extent (the LiDARs see up to ~15 m)
constexpr double kBaseX = -6.0;             // machine swing axis, facing +x
constexpr double kKeepOutRadius = 3.0;      // chassis + legs + margin
constexpr double kDroneExtent = 10.0;

std::vector<std::string> real_mesh_files(const fs::path& dir) {
  std::vector<std::string> files;
  if (dir.empty() || !fs::is_directory(dir)) return files;
  for (const auto& e : fs::directory_iterator(dir)) {
    if (e.path().extension() == ".ply") files.push_back(e.path().string());
  }
  std::sort(files.begin(), files.end());  // directory order is not deterministic
  return files;
}

void write_json(const fs::path& file, const nlohmann::json& j) {
  std::ofstream out(file);
  if (!out) throw InputError(file.string() + ": cannot write");
  out << j.dump(2) << "\n";
  if (!out) throw InputError(file.string() + ": write failed");
}

nlohmann::json vec_json(const Eigen::Vector3d& v) { return nlohmann::json::array({v.x(), v.y(), v.z()}); }

constexpr std::size_t kPreviewStride = 3;  // every n-th LiDAR return goes into the preview
constexpr double kPreviewPixelsPerMetre = 30.0;
constexpr double kPreviewMargin = 4.0;       // [m] around the stones and the machine

Rgb truth_color(std::int32_t label) {
  static constexpr Rgb kStones[] = {{230, 25, 75},  {60, 180, 75},  {0, 130, 200}, {245, 130, 48}, {145, 30, 180},
                                    {70, 240, 240}, {240, 50, 230}, {210, 245, 60}, {0, 128, 128}, {170, 110, 40}};
  if (label == kLabelTerrain) return {165, 155, 140};
  if (label == kLabelRobot) return {40, 40, 40};
  if (label < 0) return {200, 200, 200};
  return kStones[static_cast<std::size_t>(label) % std::size(kStones)];
}

std::string sweep_file(const std::string& sensor, int index) {
  char name[32];
  std::snprintf(name, sizeof(name), "%06d.ply", index);
  return "scans/" + sensor + "/" + name;
}

}  // namespace

Similarity read_drone_truth(const fs::path& run) {
  const fs::path file = run / "truth" / "drone.json";
  std::ifstream in(file);
  if (!in) throw InputError("cannot read " + file.string());
  try {
    const nlohmann::json j = nlohmann::json::parse(in);
    if (!j.contains("T_map_drone")) throw InputError("it has no T_map_drone");
    return Similarity::from_matrix(matrix_from_json(j.at("T_map_drone")));
  } catch (const std::exception& e) {  // JSON syntax, the matrix's shape, not a similarity
    throw InputError(file.string() + " is not a drone truth file: " + e.what());
  }
}

std::vector<std::string> scenario_names() { return {"exp1", "exp2", "pile"}; }

fs::path default_real_mesh_dir() {
  // $CAIRN_STONE_MESH_DIR wins over the meshes shipped in the repository (data/stones).
  if (const char* dir = std::getenv("CAIRN_STONE_MESH_DIR")) {
    if (fs::is_directory(dir)) return dir;
    spdlog::warn("CAIRN_STONE_MESH_DIR='{}' is not a directory: using the shipped stone meshes", dir);
  }
  const fs::path dir(CAIRN_DEFAULT_REAL_MESH_DIR);
  return (!dir.empty() && fs::is_directory(dir)) ? dir : fs::path{};
}

SimulationConfig scenario_config(const std::string& name, const fs::path& real_mesh_dir) {
  SimulationConfig c;
  c.site.terrain.size_x = kSiteSize;
  c.site.terrain.size_y = kSiteSize;
  c.site.terrain.slope_x = 0.05;
  c.site.terrain.slope_y = 0.02;
  c.site.stones.keep_out_x = kBaseX;
  c.site.stones.keep_out_radius = kKeepOutRadius;
  c.site.stones.settle = true;
  c.settle_in_physics = true;  // the world at rest before anything is sensed (issue #15 item 1)
  c.excavator.base_x = kBaseX;
  c.drone.extent_x = c.drone.extent_y = kDroneExtent;
  std::vector<std::string> real = real_mesh_files(real_mesh_dir);
  double real_fraction = 0.0;
  if (name == "exp1") {
    c.site.stones.count = 7;
    c.site.stones.placement_radius = 4.0;  // ~50 m^2 (Sec. 6.1)
    real_fraction = 2.0 / 7.0;
  } else if (name == "exp2") {
    c.site.stones.count = 7;
    c.site.stones.center_x = -1.5;
    c.site.stones.placement_radius = 2.0;
    c.site.stones.placement_aspect = 3.5;  // a band 4 m deep, 14 m wide
    c.site.stones.min_spacing = 0.5;
    c.site.stones.flat_fraction = 0.45;
    c.excavator.swing_amplitude_deg = 120.0;
    c.drone.center_x = -1.5;
    c.drone.extent_x = 6.0;
    c.drone.extent_y = 16.0;
    real_fraction = 3.0 / 7.0;
  } else if (name == "pile") {
    c.site.stones.count = 6;
    c.site.stones.arrangement = "pile";
    c.drone.extent_x = c.drone.extent_y = 8.0;
    real_fraction = 2.0 / 6.0;
  } else {
    std::string known;
    for (const auto& n : scenario_names()) known.append(known.empty() ? "" : ", ").append(n);
    throw ConfigError("unknown scenario '" + name + "' (known: " + known + ")");
  }
  if (!real.empty()) {
    c.site.stones.real_meshes = real;
    c.site.stones.real_fraction = real_fraction;
  } else if (real_fraction > 0) {
    spdlog::warn("scenario {}: real stone meshes not found ({}); all stones are procedural", name,
                 real_mesh_dir.empty() ? std::string("no directory given") : real_mesh_dir.string());
  }
  return c;
}

Site make_site(const SimulationConfig& config, std::uint64_t seed, SiteSettleResult* settle) {
  if (!config.settle_in_physics) return generate_site(config.site, seed);
  // Settled sites are generated resting on the ground, not sunk into it: a sunk stone needs a
  // seat carved under it, which every later physics scene would carve again at its new pose,
  // shifting it by 1-4 cm each time (docs/simulator-physics.md).
  SiteConfig resting = config.site;
  resting.stones.embed_depth = 0.0;
  Site site = generate_site(resting, seed);
  const SiteSettleResult r = settle_site(site, config.physics);
  if (!r.settled) spdlog::warn("site seed {}: not every stone came to rest in the physics", seed);
  if (settle != nullptr) *settle = r;
  return site;
}

SimulatedWorld make_world(const SimulationConfig& config, std::uint64_t seed) {
  return make_world(config, make_site(config, seed));
}

SimulatedWorld make_world(const SimulationConfig& config, Site site) {
  Excavator excavator(config.excavator, config.gripper, site.terrain);
  RayScene scene = make_world_scene(site, config.terrain_mesh_spacing);
  return SimulatedWorld{std::move(site), std::move(excavator), std::move(scene)};
}

namespace {

/// The jaws closed on a stone held at T_G_world: its width across them (G's y) over the part
/// between the palm and the jaw tips, within the gripper's range.
double closed_opening(const Stone& stone, const Eigen::Isometry3d& T_G_world, const GripperConfig& gripper) {
  double lo = INFINITY, hi = -INFINITY;
  const PointCloud& v = stone.mesh.vertices;
  for (std::size_t i = 0; i < v.size(); ++i) {
    const Eigen::Vector3d p = T_G_world * v.world(i);
    if (p.x() < 0.0 || p.x() > gripper.jaw_length) continue;
    lo = std::min(lo, p.y());
    hi = std::max(hi, p.y());
  }
  return std::clamp(hi > lo ? hi - lo : 0.0, gripper.closed_gap, max_opening(gripper));
}

}  // namespace

void hold_stone(SimulatedWorld& world, std::size_t k, const Eigen::Isometry3d& T_world_G_grasp, double t,
                const SimulationConfig& config) {
  if (world.held) throw InputError("hold_stone: the gripper already holds stone " + std::to_string(world.held->stone));
  if (k >= world.site.stones.size()) throw InputError("hold_stone: no stone " + std::to_string(k));
  if (!T_world_G_grasp.matrix().allFinite()) throw InputError("hold_stone: the grasp pose is not finite");
  const HeldStone held{.stone = k, .T_G_world = T_world_G_grasp.inverse()};
  ArmPose carry = config.excavator.carry;
  carry.gripper_opening = closed_opening(world.site.stones[k], held.T_G_world, config.gripper);
  world.excavator.move_arm(t, carry);
  io::Mesh mesh = world.site.stones[k].mesh;
  transform_cloud(mesh.vertices, held.T_G_world);
  auto scene = std::make_unique<RayScene>();
  scene->add_mesh(mesh, static_cast<std::int32_t>(k));
  scene->commit();
  world.scene = make_world_scene(world.site, config.terrain_mesh_spacing, static_cast<std::int64_t>(k));
  world.held = held;
  world.held_scene = std::move(scene);
}

Eigen::Isometry3d held_stone_pose(const SimulatedWorld& world, double t) {
  if (!world.held) throw InputError("held_stone_pose: the gripper holds no stone");
  const int g = world.excavator.model().link_index(kGripperLink);
  return world.excavator.link_poses(t)[std::size_t(g)] * world.held->T_G_world;
}

std::size_t release_stone(SimulatedWorld& world, double t, const SimulationConfig& config) {
  if (!world.held) throw InputError("release_stone: the gripper holds no stone");
  world.excavator.move_arm(t, world.excavator.parked());
  const std::size_t k = world.held->stone;
  world.held.reset();
  world.held_scene.reset();
  world.scene = make_world_scene(world.site, config.terrain_mesh_spacing);
  return k;
}

GraspTrialResult execute_grasp(SimulatedWorld& world, const GraspPlan& plan, const SimulationConfig& config) {
  GraspTrialResult r = run_grasp_trial(world.site, plan, config.gripper, config.physics);
  apply_stone_poses(world.site, r.stone_poses);
  world.scene = make_world_scene(world.site, config.terrain_mesh_spacing);
  return r;
}

CarryResult carry_and_release(SimulatedWorld& world, std::size_t k, const Eigen::Isometry3d& T_motion,
                              double drop_height, const SimulationConfig& config) {
  if (k >= world.site.stones.size()) throw InputError("carry_and_release: no stone " + std::to_string(k));
  if (!T_motion.matrix().allFinite()) throw InputError("carry_and_release: the motion is not finite");
  const PointCloud& v = world.site.stones[k].mesh.vertices;
  double lift = -INFINITY;  // how far the carried stone must rise so its lowest point clears the terrain
  for (std::size_t i = 0; i < v.size(); ++i) {
    const Eigen::Vector3d p = T_motion * v.world(i);
    lift = std::max(lift, world.site.terrain.height(p.x(), p.y()) + drop_height - p.z());
  }
  CarryResult r;
  r.lift = lift;
  r.carried = Eigen::Translation3d(0.0, 0.0, lift) * T_motion;
  std::vector<Eigen::Isometry3d> poses(world.site.stones.size(), Eigen::Isometry3d::Identity());
  poses[k] = r.carried;
  apply_stone_poses(world.site, poses);
  const SiteSettleResult settled = settle_site(world.site, config.physics);  // moves the site's stones
  world.scene = make_world_scene(world.site, config.terrain_mesh_spacing);
  r.total = settled.stone_poses[k] * r.carried;
  r.settling = settled.stone_poses;
  r.settled = settled.settled;
  return r;
}

std::vector<SweepSchedule> sweep_schedule(const LidarConfig& lidar, double duration, std::uint64_t seed) {
  validate(lidar);
  if (!(duration > 0) || !std::isfinite(duration)) throw ConfigError("sweep_schedule: duration must be positive");
  const double period = 1.0 / lidar.rate;
  std::vector<SweepSchedule> all;
  for (const std::string sensor : {"H", "V"}) {
    SplitMix64 rng(mix_seed(seed, name_hash("sweep_phase"), name_hash(sensor)));
    const double phase = period * rng.uniform01();
    for (int k = 0;; ++k) {
      const double t = phase + k * period;
      if (t + period > duration) break;
      all.push_back({sensor, k, t});
    }
  }
  std::stable_sort(all.begin(), all.end(), [](const auto& a, const auto& b) { return a.t_start < b.t_start; });
  return all;
}

Sweep simulate_scheduled_sweep(const SimulatedWorld& world, const LidarConfig& lidar, const SweepSchedule& s,
                               std::uint64_t seed) {
  const Excavator& ex = world.excavator;
  const Eigen::Isometry3d T_cabin_sensor = s.sensor == "H" ? ex.T_cabin_H() : ex.T_cabin_V();
  LidarMotion motion;
  motion.T_world_sensor = [&ex, T_cabin_sensor](double t) { return ex.T_world_cabin(t) * T_cabin_sensor; };
  motion.robot = &ex.model();
  motion.link_poses = [&ex](double t) { return ex.link_poses(t); };
  if (world.held) {
    motion.held = world.held_scene.get();
    motion.held_link = ex.model().link_index(kGripperLink);
  }
  return simulate_sweep(world.scene, motion, lidar, s.sensor, s.index, s.t_start, seed);
}

namespace {

/// Throws when `out` cannot take a new run: not a directory, not empty without `overwrite`, or
/// not a run directory (only ever delete what a previous simulation wrote).
void check_run_directory(const fs::path& out, bool overwrite) {
  if (fs::exists(out) && !fs::is_directory(out)) throw InputError(out.string() + ": exists and is not a directory");
  if (fs::exists(out) && !fs::is_empty(out) && !overwrite) {
    throw InputError(out.string() + ": directory is not empty (use --overwrite to replace it)");
  }
  if (fs::exists(out) && overwrite && !fs::exists(out / "run.json"))
    throw InputError(out.string() + ": not a run directory; refusing to overwrite it");
}

void prepare_run_directory(const fs::path& out, bool overwrite) {
  check_run_directory(out, overwrite);
  if (fs::exists(out) && overwrite) fs::remove_all(out);
}

/// The site at t = 0: stone meshes, site.json, the terrain, the dense labelled snapshot.
void write_site_truth(const fs::path& out, const SimulatedWorld& world, const SimulationConfig& config, std::uint64_t seed) {
  nlohmann::json stones = nlohmann::json::array();
  for (std::size_t k = 0; k < world.site.stones.size(); ++k) {
    const Stone& s = world.site.stones[k];
    char name[64];
    std::snprintf(name, sizeof(name), "stones/stone_%02zu.ply", k);
    io::write_ply_mesh(out / "truth" / name, s.mesh);
    stones.push_back({{"id", k}, {"volume", s.volume}, {"flat", s.flat}, {"source", s.source},
                      {"centroid", vec_json(s.centroid)}, {"bbox_min", vec_json(s.bounds.min())},
                      {"bbox_max", vec_json(s.bounds.max())}, {"mesh", name},
                      {"T_world_stone", matrix_to_json(Eigen::Matrix4d::Identity())}});
  }
  io::write_ply_mesh(out / "truth" / "terrain.ply", terrain_mesh(world.site.terrain, config.terrain_mesh_spacing));
  write_json(out / "truth" / "site.json",
             {{"stones", stones},
              {"T_world_base", matrix_to_json(world.excavator.T_world_base(0.0).matrix())},
              {"labels", {{"terrain", kLabelTerrain}, {"robot", kLabelRobot}, {"stone", "index k >= 0"}}},
              {"note", "stone meshes are in the world (= map) frame at t = 0; T_world_stone moves them from there "
                       "(segments.json: after the machine moved stones)"}});
  if (config.with_snapshot) {
    const SampledSite snap = sample_site(world.site, config.snapshot, seed);
    io::write_ply(out / "truth" / "map_snapshot.ply", snap.cloud);
  }
}

/// The drone survey of the site at t = 0 (Sec. 4.1): the cloud, the COLMAP model, VINS, truth.
void write_drone_survey(const fs::path& out, const SimulatedWorld& world, const SimulationConfig& config,
                        std::uint64_t seed, SimulationSummary& summary) {
  const DroneSurvey survey = simulate_drone(world.site, world.scene, config.drone, seed);
  PointCloud cloud = survey.cloud;
  cloud.labels.clear();  // the truth goes to truth/, not into the input
  io::write_ply(out / "drone" / "cloud.ply", cloud);
  io::write_npy_int32(out / "truth" / "drone_labels.npy", survey.truth);
  io::write_colmap_text(out / "drone" / "sparse", to_colmap_model(survey));
  io::write_tum_trajectory(out / "drone" / "vins_trajectory.tum", vins_trajectory(survey));
  nlohmann::json images = nlohmann::json::array();
  for (const auto& im : survey.images) {
    images.push_back({{"name", im.name}, {"timestamp", im.timestamp}, {"T_world_cam", matrix_to_json(im.T_world_cam.matrix())}});
  }
  write_json(out / "truth" / "drone.json",
             {{"T_map_drone", matrix_to_json(survey.T_world_sfm.matrix())},
              {"scale_map_per_sfm_unit", survey.T_world_sfm.scale},
              {"T_sfm_world", matrix_to_json(survey.T_sfm_world.matrix())},
              {"T_vins_world", matrix_to_json(survey.T_vins_world.matrix())},
              {"images", images}});
  summary.drone_points = survey.cloud.size();
  summary.drone_images = survey.images.size();
}

/// The state estimate over [0, duration] (the arm as commanded over the run), the robot model,
/// the extrinsics.
void write_machine(const fs::path& out, const Excavator& ex, const SimulationConfig& config, std::uint64_t seed,
                   double duration) {
  const StateEstimate state = simulate_state_estimation(
      [&ex](double t) { return ex.T_world_cabin(t); }, [&ex](double t) { return ex.joints_at(t); }, ex.model(), 0.0,
      duration, config.state, seed);
  io::write_stamped_poses(out / "state" / "cabin_poses.tum", state.estimate);
  io::write_joint_states(out / "state" / "joint_states.csv", state.joints);
  io::write_stamped_poses(out / "truth" / "cabin_poses.tum", state.truth);
  io::write_joint_states(out / "truth" / "joint_states.csv", state.joints_truth);
  write_json(out / "robot.json", to_json(ex.model()));
  const Eigen::Isometry3d T_H_V = ex.T_cabin_H().inverse() * ex.T_cabin_V();
  write_json(out / "extrinsics.json",
             {{"T_cabin_sensor", {{"H", matrix_to_json(ex.T_cabin_H().matrix())}, {"V", matrix_to_json(ex.T_cabin_V().matrix())}}},
              {"T_H_V", matrix_to_json(T_H_V.matrix())},
              {"note", "T_a_b maps points of frame b into frame a; sensors spin about their z axis"}});
}

/// LiDAR returns in the world (true poses) for the preview picture.
struct PreviewPoints {
  PointCloud cloud;
  std::vector<Rgb> colors;
};

/// Preview: LiDAR returns (left, coloured by truth) and the drone cloud (right, mapped into the
/// world by the true similarity), over the same extent.
void write_preview(const fs::path& out, const SimulatedWorld& world, const PreviewPoints& preview, bool with_drone) {
  Eigen::AlignedBox3d region;
  for (const auto& stone : world.site.stones) region.extend(stone.bounds);
  region.extend(world.excavator.T_world_base(0.0).translation());
  Aabb box;
  box.min = (region.min() - Eigen::Vector3d::Constant(kPreviewMargin)).cast<float>();
  box.max = (region.max() + Eigen::Vector3d::Constant(kPreviewMargin)).cast<float>();
  box.min.z() = static_cast<float>(region.min().z() - 1.0);
  box.max.z() = static_cast<float>(region.max().z() + 1.0);
  Image left = render_top_view(preview.cloud, preview.colors, kPreviewPixelsPerMetre, box);
  if (with_drone) {
    PointCloud drone = io::read_cloud(out / "drone" / "cloud.ply").cloud;
    transform_cloud(drone, read_drone_truth(out));
    std::vector<Rgb> colors = drone.has_colors() ? drone.colors : std::vector<Rgb>(drone.size(), Rgb{120, 120, 120});
    left = side_by_side(left, render_top_view(drone, colors, kPreviewPixelsPerMetre, box));
  }
  write_png(out / "preview.png", left);
}

/// Writes sweeps as they come (scan and truth files, the index, a share for the preview).
class SweepWriter {
 public:
  SweepWriter(const fs::path& out, const Excavator& ex, const SimulationConfig& config, SimulationSummary& summary)
      : out_(out), ex_(ex), config_(config), summary_(summary) {}

  void write(const Sweep& sweep) {
    PointCloud cloud;
    cloud.points = sweep.points;
    cloud.times = sweep.times;
    ScalarField ring{.name = "ring", .values = {}};
    ring.values.reserve(sweep.rings.size());
    for (auto r : sweep.rings) ring.values.push_back(static_cast<float>(r));
    cloud.fields.push_back(std::move(ring));
    const std::string file = sweep_file(sweep.sensor, sweep.index);
    io::write_ply(out_ / file, cloud);
    if (config_.with_scan_truth) {
      fs::path truth = out_ / "truth" / file;
      truth.replace_extension(".npy");
      io::write_npy_int32(truth, sweep.truth);
    }
    index_.push_back({sweep.sensor, sweep.index, sweep.t_start, sweep.t_end, sweep.points.size(), file});
    const Eigen::Isometry3d T_cabin_sensor = sweep.sensor == "H" ? ex_.T_cabin_H() : ex_.T_cabin_V();
    for (std::size_t p = 0; p < sweep.points.size(); p += kPreviewStride) {
      const Eigen::Isometry3d T = ex_.T_world_cabin(sweep.times[p]) * T_cabin_sensor;
      preview_.cloud.points.push_back((T * sweep.points[p].cast<double>()).cast<float>());
      preview_.colors.push_back(truth_color(sweep.truth[p]));
    }
    summary_.points += sweep.points.size();
    summary_.rays += sweep.num_rays;
  }
  /// scans/index.csv, in order of start time (sweeps across a move are written after it).
  void write_index() {
    std::stable_sort(index_.begin(), index_.end(), [](const io::ScanInfo& a, const io::ScanInfo& b) {
      return a.t_start < b.t_start;
    });
    io::write_scan_index(out_ / "scans" / "index.csv", index_);
  }
  [[nodiscard]] const PreviewPoints& preview() const { return preview_; }

 private:
  fs::path out_;
  const Excavator& ex_;
  const SimulationConfig& config_;
  SimulationSummary& summary_;
  std::vector<io::ScanInfo> index_;
  PreviewPoints preview_;
};

/// One revolution across a change of the world at time e: the returns fired before e from
/// `before`, those from e on from `after` (the same revolution simulated in the changed world).
Sweep joined_at(const Sweep& before, const Sweep& after, double e) {
  Sweep s = before;
  s.points.clear(), s.times.clear(), s.rings.clear(), s.truth.clear();
  for (const Sweep* part : {&before, &after})
    for (std::size_t i = 0; i < part->points.size(); ++i) {
      if ((part == &before) != (part->times[i] < e)) continue;
      s.points.push_back(part->points[i]);
      s.times.push_back(part->times[i]);
      s.rings.push_back(part->rings[i]);
      s.truth.push_back(part->truth[i]);
    }
  return s;
}

nlohmann::json move_json(const StoneMove& m) {
  return {{"time", m.time}, {"stone", m.stone}, {"shift", {m.shift.x(), m.shift.y()}}, {"turn_deg", m.turn_deg}};
}

}  // namespace

void validate_moves(const std::vector<StoneMove>& moves, std::size_t stones, double duration,
                    const SimulationConfig& config) {
  if (!moves.empty() && (!(config.held_time > 0) || !std::isfinite(config.held_time)))
    throw ConfigError("held_time: must be positive (got " + std::to_string(config.held_time) + ")");
  // Between two changes of the world lies at least one revolution (a sweep across a change is
  // joined from the world before and after it: one change per sweep).
  const double period = 1.0 / config.lidar.rate;
  if (!moves.empty() && !(config.held_time > period))
    throw ConfigError("held_time: must exceed one LiDAR revolution (" + std::to_string(period) + " s)");
  double free_from = -INFINITY;  // the gripper is free again from here (plus one revolution)
  for (std::size_t i = 0; i < moves.size(); ++i) {
    const StoneMove& m = moves[i];
    const std::string name = "move " + std::to_string(i + 1);
    if (!std::isfinite(m.time) || !m.shift.allFinite() || !std::isfinite(m.turn_deg))
      throw InputError(name + ": non-finite time, shift or turn");
    if (m.stone >= stones)
      throw InputError(name + ": no stone " + std::to_string(m.stone) + " (the site has " + std::to_string(stones) + ")");
    if (m.time < 0.0) throw InputError(name + ": starts before the run (" + std::to_string(m.time) + " s)");
    if (!(m.time > free_from + period))
      throw InputError(name + ": starts at " + std::to_string(m.time) +
                       " s, less than one LiDAR revolution after the previous move ends (" + std::to_string(free_from) +
                       " s)");
    free_from = m.time + config.held_time;
    if (free_from > duration)
      throw InputError(name + ": ends at " + std::to_string(free_from) + " s, after the run (" +
                       std::to_string(duration) + " s)");
  }
}

MoveScript::MoveScript(std::vector<StoneMove> moves, std::size_t stones) : moves_(std::move(moves)) {
  segments_.push_back({.t_start = 0.0, .held = -1, .T_gripper_stone = Eigen::Isometry3d::Identity(),
                       .T_world_stone = std::vector<Eigen::Isometry3d>(stones, Eigen::Isometry3d::Identity())});
}

double MoveScript::next_event(const SimulationConfig& config) const {
  if (next_ >= 2 * moves_.size()) return INFINITY;
  const StoneMove& m = moves_[next_ / 2];
  return next_ % 2 == 0 ? m.time : m.time + config.held_time;
}

void MoveScript::advance(SimulatedWorld& world, double t, const SimulationConfig& config) {
  for (double e = next_event(config); e <= t; e = next_event(config)) {
    const StoneMove& m = moves_[next_ / 2];
    TruthSegment seg = segments_.back();
    seg.t_start = e;
    if (next_ % 2 == 0) {  // the gripper takes the stone (the centred top-down grasp) and lifts it
      const GraspPlan plan = centred_antipodal_grasp(world.site.stones[m.stone], config.gripper, &world.site.terrain, {});
      hold_stone(world, m.stone, plan.T_world_gripper, e, config);
      seg.held = static_cast<int>(m.stone);
      seg.T_gripper_stone = world.held->T_G_world * seg.T_world_stone[m.stone];
    } else {  // ... and puts it down shifted and turned about the vertical through its centroid
      const Eigen::Vector3d c = world.site.stones[m.stone].centroid;
      const Eigen::Isometry3d T_motion = Eigen::Translation3d(c + Eigen::Vector3d(m.shift.x(), m.shift.y(), 0.0)) *
                                         Eigen::AngleAxisd(m.turn_deg * kDeg, Eigen::Vector3d::UnitZ()) *
                                         Eigen::Translation3d(-c);
      (void)release_stone(world, e, config);
      const CarryResult r = carry_and_release(world, m.stone, T_motion, config.drop_height, config);
      for (std::size_t j = 0; j < seg.T_world_stone.size(); ++j)
        seg.T_world_stone[j] = (j == m.stone ? r.total : r.settling[j]) * seg.T_world_stone[j];
      seg.held = -1;
      seg.T_gripper_stone = Eigen::Isometry3d::Identity();
    }
    segments_.push_back(std::move(seg));
    ++next_;
  }
}

nlohmann::json MoveScript::to_json(double duration) const {
  nlohmann::json segments = nlohmann::json::array();
  for (std::size_t i = 0; i < segments_.size(); ++i) {
    const TruthSegment& s = segments_[i];
    nlohmann::json poses = nlohmann::json::array();
    for (std::size_t k = 0; k < s.T_world_stone.size(); ++k) {
      poses.push_back(static_cast<int>(k) == s.held ? nlohmann::json(nullptr) : matrix_to_json(s.T_world_stone[k].matrix()));
    }
    nlohmann::json held = nullptr;
    if (s.held >= 0) held = {{"stone", s.held}, {"T_gripper_stone", matrix_to_json(s.T_gripper_stone.matrix())}};
    segments.push_back({{"t_start", s.t_start},
                        {"t_end", i + 1 < segments_.size() ? segments_[i + 1].t_start : duration},
                        {"held", held}, {"T_world_stone", poses}});
  }
  nlohmann::json moves = nlohmann::json::array();
  for (const StoneMove& m : moves_) moves.push_back(move_json(m));
  return {{"segments", segments},
          {"moves", moves},
          {"note", "T_world_stone moves truth/stones/stone_kk.ply (the site at t = 0) to where the stone lies in "
                   "the segment; the held stone (null there) moves with the gripper frame G (robot.json's link "
                   "'gripper', posed by truth/joint_states.csv and truth/cabin_poses.tum): T_gripper_stone maps "
                   "its t = 0 mesh into G"}};
}

SimulationSummary simulate_run(const std::string& scenario, const SimulationConfig& config, std::uint64_t seed,
                               double duration, const fs::path& out, bool overwrite, const Progress& progress,
                               const std::vector<StoneMove>& moves) {
  if (!(duration > 0) || !std::isfinite(duration)) throw ConfigError("simulate: duration must be positive");
  validate(config.lidar);  // fail before any file is written
  // Bad input refused before the site is generated and settled (seconds): the generator places
  // exactly stones.count stones or throws.
  validate_moves(moves, std::size_t(std::max(config.site.stones.count, 0)), duration, config);
  check_run_directory(out, overwrite);
  Stopwatch total, sw;
  SimulationSummary summary{.scenario = scenario, .seed = seed, .duration = duration};
  SimulatedWorld world = make_world(config, seed);
  prepare_run_directory(out, overwrite);  // after every check: a bad input never removes an old run
  for (const auto* dir : {"scans/H", "scans/V", "state", "drone/sparse", "truth/scans/H", "truth/scans/V", "truth/stones"}) {
    fs::create_directories(out / dir);
  }
  summary.seconds_site = sw.lap_ms() / 1000.0;
  // What the sensors see at t = 0: the site's truth and the drone survey (before any move).
  write_site_truth(out, world, config, seed);
  double write_ms = sw.lap_ms();
  if (config.with_drone) {
    if (progress) progress("drone", 0, 1);
    write_drone_survey(out, world, config, seed, summary);
    summary.seconds_drone = sw.lap_ms() / 1000.0;
    if (progress) progress("drone", 1, 1);
  }

  // Sweeps, written as they come; the machine moves stones between them.
  MoveScript script(moves, world.site.stones.size());
  SweepWriter writer(out, world.excavator, config, summary);
  const auto schedule = sweep_schedule(config.lidar, duration, seed);
  double lidar_ms = 0;
  const auto simulate = [&](const SweepSchedule& s) {
    Stopwatch one;
    Sweep sweep = simulate_scheduled_sweep(world, config.lidar, s, seed);
    lidar_ms += one.lap_ms();
    return sweep;
  };
  // The sweeps in flight when the next move happens see the world before it until then and after
  // it from then on (each firing draws its own random numbers, so the two halves join seamlessly).
  std::vector<std::pair<SweepSchedule, Sweep>> spanning;
  const auto move_happens = [&](double e) {
    script.advance(world, e, config);
    for (const auto& [s, before] : spanning) writer.write(joined_at(before, simulate(s), e));
    spanning.clear();
  };
  for (std::size_t i = 0; i < schedule.size(); ++i) {
    for (double e = script.next_event(config); e <= schedule[i].t_start; e = script.next_event(config)) move_happens(e);
    Sweep sweep = simulate(schedule[i]);
    if (sweep.t_end >= script.next_event(config)) spanning.emplace_back(schedule[i], std::move(sweep));
    else writer.write(sweep);
    if (progress) progress("lidar", i + 1, schedule.size());
  }
  for (double e = script.next_event(config); std::isfinite(e); e = script.next_event(config)) move_happens(e);
  summary.sweeps = schedule.size();
  summary.seconds_lidar = lidar_ms / 1000.0;
  write_ms += sw.lap_ms() - lidar_ms;
  writer.write_index();
  write_machine(out, world.excavator, config, seed, duration);  // the arm as commanded over the whole run
  write_json(out / "truth" / "segments.json", script.to_json(duration));
  write_preview(out, world, writer.preview(), config.with_drone);

  nlohmann::json moves_json = nlohmann::json::array();
  for (const StoneMove& m : moves) moves_json.push_back(move_json(m));
  nlohmann::json meta{{"format_version", io::kRunFormatVersion},
                      {"created_by", "cairn simulate"},
                      {"scenario", scenario},
                      {"seed", seed},
                      {"duration", duration},
                      {"moves", moves_json},
                      {"frames", {{"world", "map frame M: gravity-aligned, z up, metres"},
                                  {"cabin", "x forward, z up, origin on the swing axis"},
                                  {"H", "horizontal VLP-16, spin axis = cabin z"},
                                  {"V", "vertical VLP-16, spin axis = cabin y"}}},
                      {"sensors", {{"H", {{"model", "VLP-16"}, {"rate_hz", config.lidar.rate}}},
                                   {"V", {{"model", "VLP-16"}, {"rate_hz", config.lidar.rate}}}}},
                      {"counts", {{"sweeps", summary.sweeps}, {"points", summary.points}, {"rays", summary.rays},
                                  {"drone_points", summary.drone_points}, {"drone_images", summary.drone_images}}},
                      {"config", config::to_json(config)}};
  write_json(out / "run.json", meta);
  summary.seconds_write = (write_ms + sw.lap_ms()) / 1000.0;
  summary.seconds_total = total.elapsed_ms() / 1000.0;
  return summary;
}

}  // namespace cairn::sim
