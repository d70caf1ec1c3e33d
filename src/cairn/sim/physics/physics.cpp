#include "cairn/sim/physics/physics.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iomanip>
#include <map>
#include <numbers>
#include <sstream>

#include <spdlog/spdlog.h>
#include <tbb/parallel_for.h>

#include "cairn/core/error.hpp"
#include "cairn/robot/grasp_plan.hpp"
#include "cairn/sim/physics/scene.hpp"
#include "cairn/core/units.hpp"

namespace cairn::sim {
namespace {

using detail::Contact;
using detail::Scene;
using Eigen::Isometry3d;
using Eigen::Matrix3d;
using Eigen::Vector2d;
using Eigen::Vector3d;

constexpr double kGravity = 9.81;           // [m/s^2], as in the generated model
constexpr double kCloseMinTime = 0.1;       // [s] closing runs at least this long
constexpr double kJawStopHold = 0.05;       // [s] jaws must stay stopped this long
constexpr double kEmptyMargin = 0.01;       // [m] jaws this close to fully closed hold nothing
constexpr double kContactWindow = 0.05;     // [s] a jaw touches what it touched this recently
constexpr double kExtentAngleStep = 0.5;    // [deg] search step of the shortest extent
constexpr int kJawFootprintSamples = 9;     // per axis, terrain samples under the jaws' sweep
constexpr double kStallLowering = 0.5;      // [m] after a stall, lowered by the lift height and this

void require(bool ok, const std::string& message) {
  if (!ok) throw ConfigError("PhysicsConfig: " + message);
}

/// Minimum-jerk time scaling of a segment, s(0) = 0, s(1) = 1, zero velocity and acceleration
/// at both ends.
double min_jerk(double t) {
  const double u = std::clamp(t, 0.0, 1.0);
  return u * u * u * (10.0 - 15.0 * u + 6.0 * u * u);
}

double wrap_angle(double a) { return std::remainder(a, 2.0 * std::numbers::pi); }

/// Pose at fraction s of the way from a to b: straight line, or an arc about the vertical through
/// `pivot` (radius and height interpolated); orientations are slerped.
Isometry3d interpolate(const Isometry3d& a, const Isometry3d& b, double s,
                       const std::optional<Vector2d>& pivot) {
  Isometry3d T = Isometry3d::Identity();
  const Eigen::Quaterniond qa(a.linear()), qb(b.linear());
  T.linear() = qa.slerp(s, qb).toRotationMatrix();
  if (!pivot) {
    T.translation() = a.translation() + s * (b.translation() - a.translation());
    return T;
  }
  const Vector2d ra = a.translation().head<2>() - *pivot, rb = b.translation().head<2>() - *pivot;
  const double ta = std::atan2(ra.y(), ra.x());
  const double dt = wrap_angle(std::atan2(rb.y(), rb.x()) - ta);
  const double r = ra.norm() + s * (rb.norm() - ra.norm()), t = ta + s * dt;
  T.translation() << pivot->x() + r * std::cos(t), pivot->y() + r * std::sin(t),
      a.translation().z() + s * (b.translation().z() - a.translation().z());
  return T;
}

double path_length(const Isometry3d& a, const Isometry3d& b, const std::optional<Vector2d>& pivot) {
  if (!pivot) return (b.translation() - a.translation()).norm();
  const Vector2d ra = a.translation().head<2>() - *pivot, rb = b.translation().head<2>() - *pivot;
  const double dt = wrap_angle(std::atan2(rb.y(), rb.x()) - std::atan2(ra.y(), ra.x()));
  return std::abs(dt) * std::max(ra.norm(), rb.norm()) + std::abs(rb.norm() - ra.norm()) +
         std::abs(b.translation().z() - a.translation().z());
}

double rotation_angle(const Matrix3d& R) { return Eigen::AngleAxisd(R).angle(); }

/// Placing by weight: the load cell is read over the hold after the lift from this share of it on
/// (the stone first swings into the grip about the jaw axis).
constexpr double kWeighAfter = 0.5;

Isometry3d translated_world(const Isometry3d& T, const Vector3d& d) {
  Isometry3d out = T;
  out.translation() += d;
  return out;
}

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

/// Runs the scene until, over a window of `hold` seconds, no stone point moved further than
/// speed * hold (the stones' poses compared at the window's ends, so contact jitter does not
/// count as motion), or for at most max_time. Returns whether it came to rest.
bool run_until_rest(Scene& scene, double max_time, double speed, double hold) {
  const double end = scene.time() + max_time;
  const auto poses = [&] {
    std::vector<Isometry3d> p;
    for (int k = 0; k < scene.num_stones(); ++k) p.push_back(scene.stone_body_pose(k));
    return p;
  };
  std::vector<Isometry3d> before = poses();
  double window_end = scene.time() + hold;
  while (scene.time() < end) {
    scene.step();
    if (scene.time() < window_end) continue;
    const std::vector<Isometry3d> now = poses();
    double moved = 0.0;
    for (int k = 0; k < scene.num_stones(); ++k) {
      const Isometry3d d = before[static_cast<std::size_t>(k)].inverse() * now[static_cast<std::size_t>(k)];
      moved = std::max(moved, d.translation().norm() + rotation_angle(d.linear()) * scene.stone_radius(k));
    }
    if (moved < speed * hold) return true;
    before = now;
    window_end = scene.time() + hold;
  }
  return false;
}

/// World-frame box of points given in frame T.
Eigen::AlignedBox3d world_box(const Isometry3d& T, const std::vector<Vector3d>& points) {
  Eigen::AlignedBox3d box;
  for (const Vector3d& p : points) box.extend(T * p);
  return box;
}

std::vector<Vector3d> box_corners(const Eigen::AlignedBox3d& b) {
  std::vector<Vector3d> corners;
  for (int i = 0; i < 8; ++i) corners.push_back(b.corner(static_cast<Eigen::AlignedBox3d::CornerType>(i)));
  return corners;
}

/// Union-find over stones: stones `joined(a, b)` end in one group; groups listed by their
/// smallest member, members ascending.
template <class Joined>
std::vector<std::vector<int>> groups(int n, Joined&& joined) {
  std::vector<int> parent(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) parent[static_cast<std::size_t>(i)] = i;
  const auto root = [&](int i) {
    while (parent[static_cast<std::size_t>(i)] != i) i = parent[static_cast<std::size_t>(i)] = parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(i)])];
    return i;
  };
  for (int a = 0; a < n; ++a) {
    for (int b = a + 1; b < n; ++b) {
      if (joined(a, b)) parent[static_cast<std::size_t>(std::max(root(a), root(b)))] = std::min(root(a), root(b));
    }
  }
  std::vector<std::vector<int>> out;
  std::vector<int> slot(static_cast<std::size_t>(n), -1);
  for (int i = 0; i < n; ++i) {
    const int r = root(i);
    if (slot[static_cast<std::size_t>(r)] < 0) {
      slot[static_cast<std::size_t>(r)] = static_cast<int>(out.size());
      out.emplace_back();
    }
    out[static_cast<std::size_t>(slot[static_cast<std::size_t>(r)])].push_back(i);
  }
  return out;
}

bool boxes_near(const Eigen::AlignedBox3d& a, const Eigen::AlignedBox3d& b, double gap) {
  Eigen::AlignedBox3d grown = a;
  grown.min().array() -= gap;
  grown.max().array() += gap;
  return grown.intersects(b);
}

/// Trials: which stones are free bodies. Free: the target stone and every stone within
/// free_margin of the gripper (at its opening) or the carried stone anywhere along the planned
/// path, sampled every kPathSample, plus the stones touching a free stone (island_gap).
constexpr double kPathSample = 0.25;  // [m]

/// Boxes swept by the gripper (at its opening) and the carried stone along the planned path:
/// approach, lift, move (the swing arc), place, retreat; each grown upwards by approach_distance
/// (an aborted trial lifts the gripper that far from wherever it stopped). Without a target, a
/// box between the jaws stands for whatever they grasp.
std::vector<Eigen::AlignedBox3d> swept_boxes(const GraspPlan& plan, const GripperConfig& gripper,
                                             const Site& site, const Isometry3d& pre_grasp) {
  // The gripper at the plan's opening and, closing from it, with its tips at their deepest
  // (jaws parallel) and fully closed.
  std::vector<Vector3d> gripper_points;
  for (const double opening : {plan.opening, std::min(plan.opening, gripper.hinge_spacing), gripper.closed_gap}) {
    for (const ConvexPart& p : gripper_parts(gripper, opening)) {
      gripper_points.insert(gripper_points.end(), p.vertices.begin(), p.vertices.end());
    }
  }
  const Isometry3d lifted = translated_world(plan.T_world_gripper, plan.lift_height * Vector3d::UnitZ());
  const Isometry3d above_place = translated_world(plan.T_world_place, plan.lift_height * Vector3d::UnitZ());
  const Isometry3d retreat = plan.T_world_place * Eigen::Translation3d(-plan.approach_distance, 0, 0);
  const std::vector<Isometry3d> waypoints = {pre_grasp, plan.T_world_gripper, lifted, above_place, plan.T_world_place, retreat};
  // The carried stone's box in the gripper frame at grasp.
  std::vector<Vector3d> carried;
  if (plan.target_stone >= 0) {
    carried = box_corners(site.stones[static_cast<std::size_t>(plan.target_stone)].bounds);
    for (Vector3d& p : carried) p = plan.T_world_gripper.inverse() * p;
  } else {
    const double half = 0.5 * plan.opening;
    carried = box_corners(Eigen::AlignedBox3d(Vector3d(0.0, -half, -0.5 * gripper.jaw_height),
                                              Vector3d(gripper.jaw_length, half, 0.5 * gripper.jaw_height)));
  }
  std::vector<Eigen::AlignedBox3d> swept;
  for (std::size_t w = 0; w + 1 < waypoints.size(); ++w) {
    const std::optional<Vector2d> pivot = w == 2 ? plan.swing_pivot : std::nullopt;
    const int samples = 1 + static_cast<int>(std::ceil(path_length(waypoints[w], waypoints[w + 1], pivot) / kPathSample));
    for (int i = 0; i <= samples; ++i) {
      const Isometry3d T = interpolate(waypoints[w], waypoints[w + 1], static_cast<double>(i) / samples, pivot);
      swept.push_back(world_box(T, gripper_points));
      if (w >= 1 && w <= 3) swept.push_back(world_box(T, carried));
    }
  }
  for (auto& b : swept) b.max().z() += plan.approach_distance;
  return swept;
}

std::vector<bool> free_stones(const Site& site, const std::vector<Eigen::AlignedBox3d>& swept, int target,
                              const PhysicsConfig& c) {
  const int n = static_cast<int>(site.stones.size());
  std::vector<bool> free(static_cast<std::size_t>(n), false);
  for (int k = 0; k < n; ++k) {
    const auto& b = site.stones[static_cast<std::size_t>(k)].bounds;
    free[static_cast<std::size_t>(k)] =
        k == target ||
        std::any_of(swept.begin(), swept.end(), [&](const Eigen::AlignedBox3d& s) { return boxes_near(s, b, c.free_margin); });
  }
  // Stones touching a free stone move with it (piles).
  for (const auto& g : groups(n, [&](int a, int b) {
         return boxes_near(site.stones[static_cast<std::size_t>(a)].bounds, site.stones[static_cast<std::size_t>(b)].bounds, c.island_gap);
       })) {
    const bool any = std::any_of(g.begin(), g.end(), [&](int k) { return free[static_cast<std::size_t>(k)]; });
    for (int k : g) free[static_cast<std::size_t>(k)] = any;
  }
  return free;
}

// ---------------------------------------------------------------------------------------------

class Trial {
 public:
  Trial(const Site& site, const GraspPlan& plan, const GripperConfig& gripper,
        const PhysicsConfig& config)
      : plan_(plan), c_(config), closed_gap_(gripper.closed_gap), pre_grasp_(plan.T_world_gripper * Eigen::Translation3d(-plan.approach_distance, 0, 0)),
        scene_(site, spec(site, plan, gripper, config, pre_grasp_), gripper, config), place_(plan.T_world_place) {
    target_ = pre_grasp_;
    scene_.set_gripper_target(target_);
    scene_.set_jaw_command(-1.0);
    scene_.relax(config, std::vector<bool>(site.stones.size(), true));
  }

  GraspTrialResult run() {
    const auto wall_start = std::chrono::steady_clock::now();
    scene_.set_jaw_command(-1.0);
    bool ok = phase("settle_in", [&] { return wait(c_.initial_settle_time, [&] { return approach_clear(); }); });
    for (int k = 0; k < scene_.num_stones(); ++k) r_.initial_stone_poses.push_back(scene_.stone_pose(k));
    r_.initial_max_speed = scene_.max_stone_speed();
    r_.free_stones = 0;
    for (int k = 0; k < scene_.num_stones(); ++k) r_.free_stones += scene_.is_free(k) ? 1 : 0;
    ok = ok && phase("approach", [&] {
      return move(plan_.T_world_gripper, c_.approach_speed, false, [&] { return approach_clear(); });
    });
    // Without abort_on_failure the machine is blind to the simulator's verdicts after closing:
    // a failure while lifting, holding or moving is recorded, and the motion goes on as planned
    // (what a machine that only watches its own signals does). Contact on the approach or while
    // closing still stops the arm (its force is measured), and with no stone between the jaws
    // there is nothing to lift.
    const bool blind = !c_.abort_on_failure;
    const auto keep = [blind](bool verdict) { return verdict || blind; };
    ok = ok && phase("close", [&] { return close(); }) && keep(check_grasp()) && r_.grasped_stone >= 0;
    if (ok) {
      const Isometry3d lifted = translated_world(plan_.T_world_gripper, plan_.lift_height * Vector3d::UnitZ());
      lifted_ = true;
      stone_at_lift_ = scene_.stone_body_pose(r_.grasped_stone);
      T_gripper_stone0_ = scene_.gripper_pose().inverse() * stone_at_lift_;
      opening_at_lift_ = scene_.opening();
      // Carrying: the simulator's verdicts, and the arm's own force limit (it stalls where it is).
      const auto carry = [&](bool lifting) { return keep(transport_ok(lifting)) && !arm_stalled(); };
      ok = phase("lift", [&] { return move(lifted, c_.lift_speed, false, [&] { return carry(true); }); }) &&
           phase("hold", [&] {
             const double from = scene_.time();
             return wait(c_.hold_time, [&] { weigh(from); return carry(false); });
           }) &&
           grip_settled() && place_by_weight() &&
           phase("move", [&] {
             const Isometry3d above_place = translated_world(place_, plan_.lift_height * Vector3d::UnitZ());
             return move(above_place, c_.move_speed, true, [&] { return carry(false); });
           }) &&
           phase("hold", [&] { return wait(c_.hold_time, [&] { return carry(false); }); }) && keep(still_held());
    }
    if (ok || !c_.abort_on_failure) {
      if (r_.grasped_stone >= 0) {
        // After a stall the machine sets the stone down where the arm stopped: straight down.
        const Vector3d down = -(plan_.lift_height + kStallLowering) * Vector3d::UnitZ();
        const Isometry3d place = r_.arm_stalled ? translated_world(target_, down) : place_;
        phase("place", [&] {
          start_lowering();
          bool reached = move(place, c_.lift_speed, false, [&] { return !touched(); });
          if (!reached && c_.place_touch_fraction > 0) reached = creep(place);
          if (!reached && c_.place_stop_on_set_down) stop_arm();
          return reached;
        });
      }
      r_.T_world_release = target_;  // Eq. 3: the gripper where the jaws are commanded open (before any back-off)
      record_release();
      phase("release", [&] { return release(); });
      // To the planned retreat pose (swept_boxes), whatever the release backed off.
      phase("retreat", [&] {
        return move(r_.T_world_release * Eigen::Translation3d(-plan_.approach_distance, 0, 0), c_.approach_speed,
                    false, [] { return true; });
      });
    } else {
      r_.T_world_release = target_;
      phase("abort", [&] {
        scene_.set_jaw_command(-1.0);
        wait(c_.release_time, [] { return true; });
        return move(translated_world(target_, plan_.approach_distance * Vector3d::UnitZ()), c_.approach_speed,
                    false, [] { return true; });
      });
    }
    phase("settle", [&] {
      return r_.settled = wait_for_rest(c_.settle_time);
    });

    for (int k = 0; k < scene_.num_stones(); ++k) r_.stone_poses.push_back(scene_.stone_pose(k));
    if (r_.released_centroid.allFinite()) r_.rest_centroid = scene_.stone_body_pose(r_.grasped_stone).translation();
    if (ok && r_.grasped_stone >= 0) {
      const Isometry3d expected = place_ * plan_.T_world_gripper.inverse() * stone_at_lift_;
      r_.place_error = (scene_.stone_body_pose(r_.grasped_stone).translation() - expected.translation()).norm();
    }
    r_.success = r_.failure_reasons.empty();
    if (r_.success) {
      std::ostringstream m;
      m.precision(3);
      m << "grasped stone " << r_.grasped_stone << " (opening " << r_.grasp_opening << " m), slip "
        << r_.slip_distance << " m, placed within " << r_.place_error << " m";
      r_.message = m.str();
    }
    if (scene_.contact_overflows() > 0) add_note("MuJoCo contact buffer overflowed");
    r_.sim_time = scene_.time();
    r_.wall_time = seconds_since(wall_start);
    return std::move(r_);
  }

 private:
  static detail::SceneSpec spec(const Site& site, const GraspPlan& plan, const GripperConfig& gripper,
                                const PhysicsConfig& config, const Isometry3d& pre_grasp) {
    detail::SceneSpec s;
    s.start_poses.assign(site.stones.size(), Isometry3d::Identity());
    const std::vector<Eigen::AlignedBox3d> swept = swept_boxes(plan, gripper, site, pre_grasp);
    s.free = free_stones(site, swept, plan.target_stone, config);
    s.with_gripper = true;
    s.T_world_gripper = pre_grasp;
    s.opening = plan.opening;
    for (const Eigen::AlignedBox3d& b : swept) {  // the ground under the whole path
      s.extra_xy.push_back(b.min().head<2>());
      s.extra_xy.push_back(b.max().head<2>());
    }
    return s;
  }

  template <class F>
  bool phase(const char* name, F&& body) {
    PhaseTiming t{.name = name, .start = scene_.time(), .end = 0.0};
    phase_now_ = name;
    const auto wall_start = std::chrono::steady_clock::now();
    const bool ok = body();
    t.end = scene_.time();
    t.wall = seconds_since(wall_start);
    r_.phases.push_back(std::move(t));
    phase_name_ = name;
    return ok;
  }

  /// One physics step; every trace_interval the machine's signals are recorded.
  void step() {
    scene_.step();
    if (scene_.time() + 0.5 * c_.timestep < next_trace_) return;
    next_trace_ += c_.trace_interval;
    record_trace();
  }

  /// The machine's signals now (also at the moment a detector fires, between the samples).
  void record_trace() {
    if (!r_.trace.empty() && r_.trace.back().time >= scene_.time()) return;
    const int k = plan_.target_stone;
    const Eigen::Vector3d in_gripper =
        k >= 0 && k < scene_.num_stones()
            ? Eigen::Vector3d(scene_.gripper_pose().inverse() * scene_.stone_body_pose(k).translation())
            : Eigen::Vector3d::Zero();
    r_.trace.push_back({.time = scene_.time(), .jaw_angle = scene_.jaw_angle(), .opening = scene_.opening(),
                        .arm_load = scene_.arm_load(), .stone_in_gripper = in_gripper});
  }

  bool wait_for_rest(double max_time) {
    const double end = scene_.time() + max_time;
    double calm = 0.0;
    while (scene_.time() < end) {
      step();
      calm = scene_.max_stone_speed() < c_.settle_speed ? calm + c_.timestep : 0.0;
      if (calm >= c_.settle_hold) return true;
    }
    return false;
  }

  /// Steps for `duration`; stops early (returning false) when monitor() returns false.
  template <class F>
  bool wait(double duration, F&& monitor) {
    const double end = scene_.time() + duration;
    while (scene_.time() < end) {
      step();
      if (!monitor()) return false;
    }
    return true;
  }

  /// Moves the gripper target to `to` along a min-jerk segment; false when monitor() stopped it.
  template <class F>
  bool move(const Isometry3d& to, double speed, bool swing, F&& monitor) {
    const Isometry3d from = target_;
    const std::optional<Vector2d> pivot = swing ? plan_.swing_pivot : std::nullopt;
    const double duration =
        std::max({path_length(from, to, pivot) / speed,
                  rotation_angle(from.linear().transpose() * to.linear()) / c_.rotation_speed,
                  c_.min_segment_time});
    const double start = scene_.time();
    while (scene_.time() - start < duration) {
      target_ = interpolate(from, to, min_jerk((scene_.time() - start + c_.timestep) / duration), pivot);
      scene_.set_gripper_target(target_);
      step();
      if (!monitor()) return false;
    }
    return true;
  }

  /// The arm's force above its limit while carrying: the arm stops where it is (the target
  /// follows the gripper, so the weld pushes no further) and the machine knows it.
  bool arm_stalled() {
    if (r_.arm_stalled) return true;
    // Low-passed (the hydraulics feel sustained pressure; the weld rings step to step).
    arm_force_ += std::min(1.0, c_.timestep / c_.arm_stall_time) * (scene_.arm_force() - arm_force_);
    const double force = arm_force_.norm();
    if (!(force > c_.arm_max_force)) return false;
    r_.arm_stalled = true;
    stop_arm();
    std::ostringstream m;
    m.precision(3);
    m << "arm stalled (" << force / 1000.0 << " kN) in " << phase_now_ << at_time();
    fail(reason::kArmStalled, m.str());
    return true;
  }

  /// The arm stops where it is: the target follows the gripper, so the weld pushes no further.
  void stop_arm() {
    target_ = scene_.gripper_pose();
    scene_.set_gripper_target(target_);
  }

  void fail(const char* code, const std::string& message) {
    if (std::find(r_.failure_reasons.begin(), r_.failure_reasons.end(), code) != r_.failure_reasons.end()) return;
    r_.failure_reasons.emplace_back(code);
    add_note(message);
    record_trace();
  }

  void add_note(const std::string& message) { r_.message += (r_.message.empty() ? "" : "; ") + message; }

  std::string at_time() const {
    std::ostringstream s;
    s.precision(3);
    s << std::fixed << " at t=" << scene_.time() << " s";
    return s.str();
  }

  static std::string depth_text(const Contact& c) {
    std::ostringstream s;
    s.precision(3);
    s << std::fixed << " (depth " << c.depth << " m, force " << std::setprecision(0) << c.normal_force << " N)";
    return s.str();
  }

  bool hard(const Contact& c) const { return c.depth > c_.collision_depth || c.normal_force > c_.collision_force; }

  /// No gripper part touches anything (pre-grasp and approach).
  bool approach_clear() {
    for (const Contact& c : scene_.contacts()) {
      if (detail::is_gripper(c.a) && hard(c)) {
        fail(reason::kCollisionApproach, "approach: " + detail::entity_name(c.a) + " hit " +
                                             detail::entity_name(c.b) + at_time() + depth_text(c));
        return false;
      }
    }
    return true;
  }

  /// Closes the jaws with the full force until they stop; a jaw touching the terrain fails.
  bool close() {
    scene_.set_jaw_command(1.0);
    const double start = scene_.time();
    double stopped = 0.0;
    while (scene_.time() - start < c_.close_time) {
      step();
      for (const Contact& c : scene_.contacts()) {
        note_jaw_contact(c);
        if (detail::is_gripper(c.a) && c.b == detail::kTerrain && hard(c)) {
          fail(reason::kCollisionClose, "close: " + detail::entity_name(c.a) + " hit the terrain" + at_time() + depth_text(c));
          return false;
        }
      }
      stopped = scene_.jaw_speed() < c_.jaw_stop_speed ? stopped + c_.timestep : 0.0;
      if (scene_.time() - start > kCloseMinTime && stopped >= kJawStopHold) break;
    }
    r_.grasp_opening = scene_.opening();
    return true;
  }

  /// Remembers when a jaw last touched a stone (the monitors see every contact of every step).
  void note_jaw_contact(const Contact& c) {
    if (c.b < 0 || (c.a != detail::kJawLeft && c.a != detail::kJawRight)) return;
    last_touch_[{c.a, c.b}] = scene_.time();
  }

  /// Stones each jaw touched within the last kContactWindow: a jaw pressing an edge with tens
  /// of kN chatters, and its contact set flickers from one step to the next.
  std::pair<std::vector<int>, std::vector<int>> jaw_contacts() {
    for (const Contact& c : scene_.contacts()) note_jaw_contact(c);
    std::pair<std::vector<int>, std::vector<int>> s;
    for (const auto& [key, time] : last_touch_) {
      if (scene_.time() - time > kContactWindow) continue;
      (key.first == detail::kJawLeft ? s.first : s.second).push_back(key.second);
    }
    return s;
  }

  bool check_grasp() {
    const auto [left, right] = jaw_contacts();
    const auto names = [](const std::vector<int>& v) {
      std::string s;
      for (int k : v) s += (s.empty() ? "" : ", ") + detail::entity_name(k);
      return s.empty() ? std::string("nothing") : s;
    };
    if (left.empty() || right.empty() || r_.grasp_opening < closed_gap_ + kEmptyMargin) {
      fail(reason::kEmptyGrasp, "close: nothing between the jaws (jaw_left touches " + names(left) +
                                    ", jaw_right touches " + names(right) + ")");
      return false;
    }
    for (int k : left) {
      if (std::find(right.begin(), right.end(), k) != right.end()) {
        r_.grasped_stone = k;
        break;
      }
    }
    if (r_.grasped_stone < 0) {
      fail(reason::kMultipleStones, "close: the jaws hold different stones (jaw_left: " + names(left) +
                                        ", jaw_right: " + names(right) + ")");
      return false;
    }
    if (plan_.target_stone >= 0 && r_.grasped_stone != plan_.target_stone) {
      fail(reason::kWrongStone, "close: grasped " + detail::entity_name(r_.grasped_stone) + " instead of " +
                                    detail::entity_name(plan_.target_stone));
      return false;
    }
    return true;
  }

  /// Collisions, slip and drop while the stone is carried. `lifting`: the carried stone may
  /// still touch the terrain it is lifted from.
  bool transport_ok(bool lifting) {
    const int g = r_.grasped_stone;
    for (const Contact& c : scene_.contacts()) {
      note_jaw_contact(c);
      if (!hard(c)) continue;
      const bool gripper_hit = detail::is_gripper(c.a) && c.b != g;
      const bool stone_hit = (c.a == g || c.b == g) && !detail::is_gripper(c.a) && !(lifting && c.a == detail::kTerrain);
      if (gripper_hit || stone_hit) {
        const std::string who = gripper_hit ? detail::entity_name(c.a) : "carried " + detail::entity_name(g);
        const std::string what = detail::entity_name(c.a == g ? c.b : (gripper_hit ? c.b : c.a));
        fail(reason::kCollisionTransport, std::string(lifting ? "lift" : "move") + ": " + who + " hit " + what + at_time());
        return false;
      }
    }
    const Isometry3d T_gs = scene_.gripper_pose().inverse() * scene_.stone_body_pose(g);
    const double moved = (T_gs.translation() - T_gripper_stone0_.translation()).norm();
    r_.jaw_travel = std::max(r_.jaw_travel, opening_at_lift_ - scene_.opening());
    std::ostringstream m;
    m.precision(3);
    if (moved > c_.drop_distance) {
      m << "stone " << g << " dropped (moved " << moved << " m relative to the gripper)" << at_time();
      fail(reason::kDropped, m.str());
      return false;
    }
    if (r_.jaw_travel > c_.jaw_slip_threshold) {  // the paper's encoder: the jaws close further
      m << "stone " << g << " slipped (jaws closed " << r_.jaw_travel << " m further)" << at_time();
      fail(reason::kSlipped, m.str());
      return false;
    }
    if (!gripped_) {  // lifting / hanging still: the stone may swing into place about the jaw axis
      r_.swing_in = std::max(r_.swing_in, moved);
      return true;
    }
    const double slip = (T_gs.translation() - T_gripper_stone1_.translation()).norm();
    const double angle = rotation_angle(T_gripper_stone1_.linear().transpose() * T_gs.linear());
    r_.slip_distance = std::max(r_.slip_distance, slip);
    r_.slip_angle = std::max(r_.slip_angle, angle);
    if (slip > c_.slip_threshold || angle > c_.slip_angle_threshold) {
      m << "stone " << g << " slipped (" << slip << " m, " << angle * 180.0 / std::numbers::pi
        << " deg relative to the gripper)" << at_time();
      fail(reason::kSlipped, m.str());
      return false;
    }
    return true;
  }

  /// The stone hangs still in the grip: from here on, relative motion is slip.
  bool grip_settled() {
    T_gripper_stone1_ = scene_.gripper_pose().inverse() * scene_.stone_body_pose(r_.grasped_stone);
    gripped_ = true;
    return true;
  }

  bool still_held() {
    const auto [left, right] = jaw_contacts();
    const int g = r_.grasped_stone;
    const auto has = [g](const std::vector<int>& v) { return std::find(v.begin(), v.end(), g) != v.end(); };
    if (has(left) && has(right)) return true;
    fail(reason::kDropped, "stone " + std::to_string(g) + " is no longer between the jaws after moving");
    return false;
  }

  /// The load cell in the second half of the hold after the lift (`from`: its start), when the
  /// stone has swung into the grip and hangs still (summed; averaged by place_by_weight).
  void weigh(double from) {
    if (scene_.time() - from < kWeighAfter * c_.hold_time) return;
    weighed_load_ += scene_.arm_load();
    weighed_moment_ += scene_.arm_moment();
    weighed_samples_ += 1;
  }

  /// Placing by weight: the weighed centre of mass under the gripper (W (r_y, -r_x) is the arm's
  /// moment, Scene::arm_moment), carried to the place pose by the turn between the two poses
  /// (about the vertical: the unmeasured height of the centre does not move it sideways), and
  /// the place pose shifted so that it lands on plan.place_com_xy. Never stops the trial.
  bool place_by_weight() {
    if (!plan_.place_com_xy || weighed_samples_ == 0) return true;
    const double load = weighed_load_ / weighed_samples_;
    if (!(load > c_.weigh_min_load)) return true;  // nothing to weigh: the plan's place pose
    const Vector3d moment = weighed_moment_ / weighed_samples_;
    const Vector3d r(-moment.y() / load, moment.x() / load, 0.0);
    if (!r.allFinite()) return true;
    r_.weighed_com = scene_.gripper_pose().translation() + r;
    const Eigen::Matrix3d turn = place_.linear() * target_.linear().transpose();  // commanded to commanded
    const Vector2d landing = place_.translation().head<2>() + (turn * r).head<2>();
    Vector2d shift = *plan_.place_com_xy - landing;
    if (shift.norm() > c_.max_place_correction) shift *= c_.max_place_correction / shift.norm();
    place_.translation().head<2>() += shift;
    r_.place_correction = shift.norm();
    return true;
  }

  /// Placement diagnostics (truth) when the jaws are about to open on a lifted stone.
  void record_release() {
    if (!lifted_ || r_.grasped_stone < 0) return;
    const Isometry3d stone = scene_.stone_body_pose(r_.grasped_stone);
    r_.released_centroid = stone.translation();
    const Vector3d in_grip = (scene_.gripper_pose().inverse() * stone).translation();
    r_.grip_drift = (in_grip - T_gripper_stone0_.translation()).norm();
    if (in_grip_lowering_) r_.set_down_drift = (in_grip - *in_grip_lowering_).norm();
    r_.released_on_support = ground_carries();
    for (const Contact& c : scene_.contacts()) {
      if (!detail::is_gripper(c.a) || c.b == r_.grasped_stone || detail::is_gripper(c.b)) continue;
      const std::string touch = detail::entity_name(c.a) + ":" + detail::entity_name(c.b);
      if (std::find(r_.release_touches.begin(), r_.release_touches.end(), touch) == r_.release_touches.end())
        r_.release_touches.push_back(touch);
    }
  }

  /// The jaws open at the place pose for release_time; with release_backoff the arm backs off
  /// along the approach until the encoder reads them open (tips on the ground open only so).
  bool release() {
    const double opening = scene_.opening(), end = scene_.time() + c_.release_time;
    scene_.set_jaw_command(-1.0);
    double backed = 0.0;
    bool open = false;  // latched: the back-off ends once the jaws have opened
    while (scene_.time() < end) {
      open = open || scene_.opening() >= plan_.opening - c_.release_open_tolerance;
      if (c_.release_backoff && !open && backed < c_.release_backoff_max) {
        const double ds = std::min(c_.release_backoff_speed * c_.timestep, c_.release_backoff_max - backed);
        target_.translation() -= ds * target_.linear().col(0);
        backed += ds;
        scene_.set_gripper_target(target_);
      }
      step();
    }
    r_.release_backoff = backed;
    if (lifted_ && r_.grasped_stone >= 0) r_.release_opened = scene_.opening() - opening;
    return true;
  }

  /// Lowering to place: the load the arm carried (weighed in the hold after the lift) and its
  /// low-passed value from here on.
  void start_lowering() {
    in_grip_lowering_ = (scene_.gripper_pose().inverse() * scene_.stone_body_pose(r_.grasped_stone)).translation();
    carried_load_ = weighed_samples_ > 0 ? weighed_load_ / weighed_samples_ : 0.0;
    load_lp_ = carried_load_;
  }

  /// The machine's sign that the stone sits on the ground: the arm's load has fallen by
  /// place_support_fraction of the load it carried (load_fell).
  bool set_down() { return load_fell(c_.place_support_fraction); }

  /// The stone touches: the same load has fallen by place_touch_fraction (feathering; without it,
  /// the set-down itself).
  bool touched() {
    const double share = c_.place_touch_fraction > 0 ? c_.place_touch_fraction : c_.place_support_fraction;
    return load_fell(share);
  }

  /// One step of the arm's load low-passed over place_filter_time (call once per step; a first
  /// touch of a corner rings the stiff contacts for a few steps); true when it has fallen by
  /// `share` of the load carried. Each sample is clipped to [0, carried] first: the ring of a
  /// first touch swings the load far below zero (-115 kN on a 19 kN stone), which alone would
  /// drag the low-pass under the threshold while the stone still hangs.
  bool load_fell(double share) {
    if (!(carried_load_ > 0.0)) return ground_carries();  // not weighed (a stall in the lift): the contacts
    const double sample = std::clamp(scene_.arm_load(), 0.0, carried_load_);
    load_lp_ += std::min(1.0, c_.timestep / c_.place_filter_time) * (sample - load_lp_);
    return load_lp_ < (1.0 - share) * carried_load_;
  }

  /// Feathering after the touch: straight down at place_touch_speed, at most to the height of
  /// `to`, until the set-down fires (false) or that height is reached (true). Straight down keeps
  /// the touch's x, y and rotation: every lowering to place is vertical (from above the place
  /// pose, or down from a stall). A touch on the lowering's last step leaves nothing to creep.
  bool creep(const Isometry3d& to) {
    const double end_z = to.translation().z();
    while (target_.translation().z() > end_z) {
      target_.translation().z() = std::max(end_z, target_.translation().z() - c_.place_touch_speed * c_.timestep);
      scene_.set_gripper_target(target_);
      step();
      if (set_down()) return false;
    }
    return true;
  }

  /// Truth (diagnostics): the ground and other stones carry place_support_fraction of the held
  /// stone's weight now.
  bool ground_carries() const {
    const int g = r_.grasped_stone;
    double up = 0.0;
    for (const Contact& c : scene_.contacts()) {
      if (detail::is_gripper(c.a) || (c.a != g && c.b != g)) continue;
      up += c.normal_force * std::abs(c.normal.z());
    }
    return up > c_.place_support_fraction * scene_.stone_mass(g) * kGravity;
  }

  const GraspPlan& plan_;
  const PhysicsConfig& c_;
  double closed_gap_ = 0.0;
  Isometry3d pre_grasp_;
  Scene scene_;
  Isometry3d target_ = Isometry3d::Identity();
  Isometry3d stone_at_lift_ = Isometry3d::Identity(), T_gripper_stone0_ = Isometry3d::Identity();
  Isometry3d T_gripper_stone1_ = Isometry3d::Identity();
  std::optional<Vector3d> in_grip_lowering_;  // the stone in the gripper frame when the lowering to place began
  bool gripped_ = false;
  bool lifted_ = false;  // the lift began with a stone between the jaws
  Isometry3d place_;     // the place pose: the plan's, shifted by place_by_weight
  double weighed_load_ = 0.0, weighed_samples_ = 0.0;
  double load_lp_ = 0.0, carried_load_ = 0.0;  // lowering to place (set_down)
  Vector3d weighed_moment_ = Vector3d::Zero();
  double opening_at_lift_ = 0.0;
  std::string phase_name_;
  const char* phase_now_ = "";  // the phase running
  double next_trace_ = 0.0;
  Vector3d arm_force_ = Vector3d::Zero();  // low-passed while carrying (arm_stalled)
  std::map<std::pair<int, int>, double> last_touch_;  // (jaw, stone) -> last contact time
  GraspTrialResult r_;
};

}  // namespace

void validate(const PhysicsConfig& c) {
  const auto positive = [](double v) { return std::isfinite(v) && v > 0.0; };
  const auto non_negative = [](double v) { return std::isfinite(v) && v >= 0.0; };
  require(positive(c.timestep), "timestep must be > 0");
  require(c.hull_subdivisions <= 5, "hull_subdivisions must be <= 5");
  require(c.cone == "pyramidal" || c.cone == "elliptic", "cone must be pyramidal or elliptic");
  require(c.solver_iterations >= 1 && positive(c.solver_tolerance) && c.noslip_iterations >= 0,
          "solver_iterations >= 1, solver_tolerance > 0, noslip_iterations >= 0");
  require(positive(c.rock_density), "rock_density must be > 0");
  require(non_negative(c.friction) && non_negative(c.torsional_friction) && non_negative(c.rolling_friction) &&
              non_negative(c.ground_rolling_friction),
          "friction coefficients must be >= 0");
  require(positive(c.contact_timeconst) && positive(c.arm_timeconst), "time constants must be > 0");
  require(c.arm_max_force > 0.0 && positive(c.arm_stall_time),
          "arm_max_force must be > 0 (infinite: the arm never stalls), arm_stall_time > 0");
  require(c.contact_timeconst >= 2.0 * c.timestep && c.arm_timeconst >= 2.0 * c.timestep,
          "contact_timeconst and arm_timeconst must be at least 2 * timestep (MuJoCo stability)");
  require(std::isfinite(c.seat_clearance), "seat_clearance must be finite");
  require(positive(c.terrain_resolution) && non_negative(c.terrain_margin) && positive(c.terrain_base),
          "terrain_resolution and terrain_base must be > 0, terrain_margin >= 0");
  require(c.contact_impedance > 0.5 && c.contact_impedance < 1.0, "contact_impedance must lie in (0.5, 1)");
  require(c.jaw_pads >= 1 && c.jaw_pads <= 8, "jaw_pads must lie in [1, 8]");
  require(positive(c.palm_mass) && positive(c.jaw_mass) && positive(c.jaw_speed), "gripper masses and jaw_speed must be > 0");
  require(positive(c.approach_speed) && positive(c.lift_speed) && positive(c.move_speed) && positive(c.rotation_speed),
          "speeds must be > 0");
  require(positive(c.min_segment_time), "min_segment_time must be > 0");
  require(non_negative(c.initial_settle_time) && positive(c.close_time) && non_negative(c.hold_time) &&
              non_negative(c.release_time) && non_negative(c.settle_time),
          "phase times must be >= 0 (close_time > 0)");
  require(positive(c.settle_speed) && positive(c.settle_hold) && positive(c.jaw_stop_speed), "rest thresholds must be > 0");
  require(non_negative(c.relax_time) && positive(c.relax_timeconst), "relax_time >= 0, relax_timeconst > 0");
  require(positive(c.collision_force), "collision_force must be > 0");
  require(positive(c.jaw_slip_threshold), "jaw_slip_threshold must be > 0");
  require(non_negative(c.collision_depth) && positive(c.slip_threshold) && positive(c.slip_angle_threshold) &&
              positive(c.drop_distance),
          "collision_depth >= 0; slip_threshold, slip_angle_threshold, drop_distance > 0");
  // < 1: the clipped, low-passed load never falls below zero, so a full share would never end the lowering.
  require(c.place_support_fraction > 0.0 && c.place_support_fraction < 1.0,
          "place_support_fraction must lie in (0, 1)");
  require(positive(c.place_filter_time), "place_filter_time must be > 0");
  require(c.place_touch_fraction >= 0 && c.place_touch_fraction < c.place_support_fraction,
          "place_touch_fraction must be in [0, place_support_fraction)");
  require(positive(c.place_touch_speed), "place_touch_speed must be > 0");
  require(positive(c.release_backoff_speed) && non_negative(c.release_backoff_max) &&
              non_negative(c.release_open_tolerance),
          "release_backoff_speed must be > 0, release_backoff_max and release_open_tolerance >= 0");
  require(non_negative(c.weigh_min_load) && non_negative(c.max_place_correction),
          "weigh_min_load and max_place_correction must be >= 0");
  require(non_negative(c.free_margin) && non_negative(c.island_gap), "free_margin and island_gap must be >= 0");
  require(positive(c.trace_interval), "trace_interval must be > 0");
  require(positive(c.site_settle_time) && positive(c.rest_speed) && positive(c.rest_hold),
          "site_settle_time, rest_speed and rest_hold must be > 0");
  require(c.restart_limit >= 1 && non_negative(c.restart_shift) && non_negative(c.restart_turn_deg),
          "restart_limit must be >= 1, restart_shift and restart_turn_deg >= 0");
}

GraspTrialResult run_grasp_trial(const Site& site, const GraspPlan& plan, const GripperConfig& gripper,
                                 const PhysicsConfig& config) {
  validate(config);
  validate(gripper);
  validate(plan, gripper);
  if (plan.target_stone >= static_cast<int>(site.stones.size())) {
    throw InputError("grasp plan: target_stone " + std::to_string(plan.target_stone) + " but the site has " +
                     std::to_string(site.stones.size()) + " stones");
  }
  Trial trial(site, plan, gripper, config);
  return trial.run();
}

namespace {

/// Settles `site` from the given start poses (empty: all at placement) until every stone point
/// stayed slower than `speed` for `hold`, at most max_time.
SettleResult settle_until_rest(const Site& site, const PhysicsConfig& config, std::span<const Isometry3d> start_poses,
                               double max_time, double speed, double hold, std::vector<Vector2d> extra_xy = {}) {
  const auto wall_start = std::chrono::steady_clock::now();
  detail::SceneSpec spec;
  spec.extra_xy = std::move(extra_xy);
  spec.start_poses.assign(site.stones.size(), Isometry3d::Identity());
  for (std::size_t k = 0; k < start_poses.size(); ++k) {
    require_rigid_pose(start_poses[k], "settle: start pose of stone " + std::to_string(k));
    spec.start_poses[k] = start_poses[k];
  }
  Scene scene(site, spec, GripperConfig{}, config);
  std::vector<bool> at_placement;  // dropped stones fall freely
  for (const Isometry3d& T : spec.start_poses) at_placement.push_back(T.isApprox(Isometry3d::Identity()));
  scene.relax(config, at_placement);
  SettleResult r;
  r.settled = run_until_rest(scene, max_time, speed, hold);
  r.max_speed = scene.max_stone_speed();
  for (int k = 0; k < scene.num_stones(); ++k) r.stone_poses.push_back(scene.stone_pose(k));
  r.sim_time = scene.time();
  r.wall_time = seconds_since(wall_start);
  return r;
}

/// The site with only the listed stones (same terrain).
Site site_subset(const Site& site, const std::vector<int>& members) {
  Site sub;
  sub.terrain_config = site.terrain_config;
  sub.stone_config = site.stone_config;
  sub.terrain = site.terrain;
  for (int k : members) sub.stones.push_back(site.stones[static_cast<std::size_t>(k)]);
  return sub;
}

std::vector<std::vector<int>> islands(const Site& site, double gap) {
  return groups(static_cast<int>(site.stones.size()), [&](int a, int b) {
    return boxes_near(site.stones[static_cast<std::size_t>(a)].bounds, site.stones[static_cast<std::size_t>(b)].bounds, gap);
  });
}

/// Largest displacement of a stone point [m] under the poses (centroid shift + rotation x radius).
double largest_motion(const Site& site, std::span<const Isometry3d> poses) {
  double moved = 0.0;
  for (std::size_t k = 0; k < poses.size(); ++k) {
    const Stone& s = site.stones[k];
    double radius = 0.0;
    for (std::size_t i = 0; i < s.mesh.vertices.size(); ++i) radius = std::max(radius, (s.mesh.vertices.world(i) - s.centroid).norm());
    moved = std::max(moved, (poses[k] * s.centroid - s.centroid).norm() + rotation_angle(poses[k].linear()) * radius);
  }
  return moved;
}

/// Largest centroid shift [m] and rotation [rad] of a stone under the poses.
std::pair<double, double> largest_shift_and_turn(const Site& site, std::span<const Isometry3d> poses) {
  double shift = 0.0, turn = 0.0;
  for (std::size_t k = 0; k < poses.size(); ++k) {
    const Vector3d c = site.stones[k].centroid;
    shift = std::max(shift, (poses[k] * c - c).norm());
    turn = std::max(turn, rotation_angle(poses[k].linear()));
  }
  return {shift, turn};
}

struct IslandSettle {
  SettleResult settle;
  double restart_shift = 0.0, restart_turn = 0.0;  // of the last restart
};

/// One island: settles from the generated poses, then restarts the physics from where the stones
/// came to rest (as every later scene of the site will, without the warm start of the running
/// simulation) until a restart moves no stone point more than rest_speed x rest_hold, at most
/// restart_limit times; at rest when the last restart stayed within restart_shift and
/// restart_turn_deg. Stone poses compose over the restarts.
IslandSettle settle_island(Site island, const PhysicsConfig& config, const std::vector<Vector2d>& region) {
  IslandSettle out;
  SettleResult& total = out.settle;
  total = settle_until_rest(island, config, {}, config.site_settle_time, config.rest_speed, config.rest_hold, region);
  apply_stone_poses(island, total.stone_poses);
  island.at_rest = true;
  bool within = false;  // the last restart moved the stones within the tolerance
  for (int restart = 0; restart < config.restart_limit && total.settled; ++restart) {
    const SettleResult again = settle_until_rest(island, config, {}, config.site_settle_time, config.rest_speed,
                                                 config.rest_hold, region);
    const bool still = largest_motion(island, again.stone_poses) < config.rest_speed * config.rest_hold;
    std::tie(out.restart_shift, out.restart_turn) = largest_shift_and_turn(island, again.stone_poses);
    within = out.restart_shift <= config.restart_shift && out.restart_turn <= config.restart_turn_deg * kDeg;
    apply_stone_poses(island, again.stone_poses);
    for (std::size_t k = 0; k < total.stone_poses.size(); ++k) total.stone_poses[k] = again.stone_poses[k] * total.stone_poses[k];
    total.sim_time += again.sim_time;
    total.wall_time += again.wall_time;
    total.settled = again.settled;
    spdlog::debug("settle: island of {} stones, restart {}: shift {:.1f} mm, turn {:.2f} deg", island.stones.size(),
                  restart + 1, 1e3 * out.restart_shift, out.restart_turn / kDeg);
    if (still) break;
  }
  total.settled = total.settled && within;
  return out;
}

}  // namespace

SettleResult settle_stones(const Site& site, const PhysicsConfig& config, std::span<const Eigen::Isometry3d> start_poses) {
  validate(config);
  if (!start_poses.empty() && start_poses.size() != site.stones.size()) {
    throw InputError("settle_stones: " + std::to_string(start_poses.size()) + " start poses for " +
                     std::to_string(site.stones.size()) + " stones");
  }
  return settle_until_rest(site, config, start_poses, config.settle_time, config.settle_speed, config.settle_hold);
}

SiteSettleResult settle_site(Site& site, const PhysicsConfig& physics) {
  validate(physics);
  // No seats: the stones come to rest on the height field itself, as every later scene of the
  // site holds it (overlaps of the generated placement resolve in the gentle start).
  PhysicsConfig config = physics;
  config.seat_clearance = -1.0;
  const auto wall_start = std::chrono::steady_clock::now();
  site.at_rest = false;
  const Site generated = site;
  const int n = static_cast<int>(site.stones.size());
  SiteSettleResult r;
  r.stone_poses.assign(static_cast<std::size_t>(n), Isometry3d::Identity());
  std::vector<std::vector<int>> partition = islands(generated, config.island_gap);
  // Every island's height field covers the whole terrain: a stone may roll far, never off it.
  const Vector2d half(0.5 * generated.terrain.config.size_x, 0.5 * generated.terrain.config.size_y);
  const std::vector<Vector2d> region = {-half, half};
  std::vector<bool> todo(partition.size(), true);
  std::vector<bool> island_settled(partition.size(), false);
  std::vector<std::pair<double, double>> restart_motion(static_cast<std::size_t>(n));  // per stone: its island's
  while (true) {
    ++r.rounds;
    std::vector<IslandSettle> results(partition.size());
    tbb::parallel_for(std::size_t{0}, partition.size(), [&](std::size_t i) {
      if (!todo[i]) return;
      results[i] = settle_island(site_subset(generated, partition[i]), config, region);
    });
    for (std::size_t i = 0; i < partition.size(); ++i) {
      if (!todo[i]) continue;
      const SettleResult& island = results[i].settle;
      r.sim_time += island.sim_time;
      island_settled[i] = island.settled;
      for (std::size_t j = 0; j < partition[i].size(); ++j) {
        const auto k = static_cast<std::size_t>(partition[i][j]);
        r.stone_poses[k] = island.stone_poses[j];
        restart_motion[k] = {results[i].restart_shift, results[i].restart_turn};
      }
    }
    // Islands whose stones came to rest near each other join and settle again, together.
    Site moved = generated;
    apply_stone_poses(moved, r.stone_poses);
    // Each stone's range: from where it was generated to where it came to rest (a stone that
    // rolled through another island's place joins it).
    std::vector<Eigen::AlignedBox3d> ranges;
    for (int k = 0; k < n; ++k) {
      ranges.push_back(moved.stones[static_cast<std::size_t>(k)].bounds.merged(generated.stones[static_cast<std::size_t>(k)].bounds));
    }
    std::vector<int> island_of(static_cast<std::size_t>(n));
    for (std::size_t i = 0; i < partition.size(); ++i) {
      for (int k : partition[i]) island_of[static_cast<std::size_t>(k)] = static_cast<int>(i);
    }
    const auto joined = groups(n, [&](int a, int b) {
      return island_of[static_cast<std::size_t>(a)] == island_of[static_cast<std::size_t>(b)] ||
             boxes_near(ranges[static_cast<std::size_t>(a)], ranges[static_cast<std::size_t>(b)], config.island_gap);
    });
    if (joined.size() == partition.size()) break;
    std::vector<bool> next_todo, next_settled;
    for (const auto& g : joined) {
      const bool same = std::find(partition.begin(), partition.end(), g) != partition.end();
      next_todo.push_back(!same);
      next_settled.push_back(same && island_settled[static_cast<std::size_t>(
                                         std::find(partition.begin(), partition.end(), g) - partition.begin())]);
    }
    partition = joined;
    todo = next_todo;
    island_settled = next_settled;
  }
  r.islands = static_cast<int>(partition.size());
  r.settled = std::all_of(island_settled.begin(), island_settled.end(), [](bool b) { return b; });
  std::tie(r.max_displacement, r.max_rotation) = largest_shift_and_turn(generated, r.stone_poses);
  for (int k = 0; k < n; ++k) {
    r.restart_shift = std::max(r.restart_shift, restart_motion[static_cast<std::size_t>(k)].first);
    r.restart_turn = std::max(r.restart_turn, restart_motion[static_cast<std::size_t>(k)].second);
  }
  apply_stone_poses(site, r.stone_poses);
  site.at_rest = true;
  r.wall_time = seconds_since(wall_start);
  return r;
}

std::vector<double> collision_hull_volumes(const Site& site, const PhysicsConfig& config) {
  validate(config);
  detail::SceneSpec spec;
  spec.start_poses.assign(site.stones.size(), Isometry3d::Identity());
  const Scene scene(site, spec, GripperConfig{}, config);
  std::vector<double> volumes;
  for (int k = 0; k < scene.num_stones(); ++k) volumes.push_back(scene.hull_volume(k));
  return volumes;
}

void apply_stone_poses(Site& site, std::span<const Eigen::Isometry3d> poses) {
  if (poses.size() != site.stones.size()) {
    throw InputError("apply_stone_poses: " + std::to_string(poses.size()) + " poses for " +
                     std::to_string(site.stones.size()) + " stones");
  }
  for (std::size_t k = 0; k < poses.size(); ++k) {
    const Isometry3d& T = poses[k];
    if (!T.matrix().allFinite()) throw InputError("apply_stone_poses: pose " + std::to_string(k) + " is not finite");
    Stone& s = site.stones[k];
    PointCloud& v = s.mesh.vertices;
    Eigen::AlignedBox3d bounds;
    for (std::size_t i = 0; i < v.size(); ++i) {
      const Vector3d p = T * v.world(i);
      v.points[i] = (p - v.origin).cast<float>();
      bounds.extend(p);
    }
    s.centroid = T * s.centroid;
    s.bounds = bounds;
    s.yaw += std::atan2(T.linear()(1, 0), T.linear()(0, 0));
  }
}

std::pair<double, Vector2d> shortest_horizontal_extent(const Stone& stone) {
  const PointCloud& v = stone.mesh.vertices;
  if (v.size() == 0) throw InputError("shortest_horizontal_extent: stone has no vertices");
  double best = INFINITY;
  Vector2d best_dir = Vector2d::UnitX();
  for (double deg = 0.0; deg < 180.0; deg += kExtentAngleStep) {
    const double a = deg * std::numbers::pi / 180.0;
    const Vector2d d(std::cos(a), std::sin(a));
    double lo = INFINITY, hi = -INFINITY;
    for (std::size_t i = 0; i < v.size(); ++i) {
      const double u = d.dot(v.world(i).head<2>());
      lo = std::min(lo, u);
      hi = std::max(hi, u);
    }
    if (hi - lo < best) {
      best = hi - lo;
      best_dir = d;
    }
  }
  return {best, best_dir};
}

namespace {

/// Highest terrain under the jaws' sweep across the closing line (half length half_u about c,
/// the jaws' height wide), else the stone's lowest point.
double ground_under_jaws(const Stone& stone, const Vector2d& dir, double half_u, const GripperConfig& gripper,
                         const Terrain* terrain) {
  if (terrain == nullptr) return stone.bounds.min().z();
  const Vector2d c = stone.centroid.head<2>();
  const Vector2d side(-dir.y(), dir.x());
  const double half_v = 0.5 * gripper.jaw_height;
  double ground = -INFINITY;
  for (int i = 0; i < kJawFootprintSamples; ++i) {
    for (int j = 0; j < kJawFootprintSamples; ++j) {
      const double u = -half_u + 2.0 * half_u * i / (kJawFootprintSamples - 1);
      const double w = -half_v + 2.0 * half_v * j / (kJawFootprintSamples - 1);
      const Vector2d p = c + u * dir + w * side;
      ground = std::max(ground, terrain->height(p.x(), p.y()));
    }
  }
  return std::isfinite(ground) ? ground : terrain->height(c.x(), c.y());
}

/// Smallest jaw angle whose open jaws clear every vertex of the stone by `margin` (the inner
/// face at depth x below the palm lies hinge_spacing/2 + x tan(angle) off the closing plane's
/// centre line), for the palm at height palm_z; clamped to the gripper's range. Conservative:
/// vertices beyond the tips or outside the jaws' height count too.
double clearing_jaw_angle(const Stone& stone, const Vector2d& dir, double palm_z, double margin,
                          const GripperConfig& gripper) {
  const Vector2d c = stone.centroid.head<2>();
  double angle = min_jaw_angle(gripper);
  for (std::size_t i = 0; i < stone.mesh.vertices.size(); ++i) {
    const Vector3d v = stone.mesh.vertices.world(i);
    const double depth = palm_z - v.z(), off = std::abs(dir.dot(v.head<2>() - c)) + margin;
    if (depth > 0.0) angle = std::max(angle, std::atan2(off - 0.5 * gripper.hinge_spacing, depth));
  }
  return std::clamp(angle, min_jaw_angle(gripper), max_jaw_angle(gripper));
}

}  // namespace

GraspPlan centred_antipodal_grasp(const Stone& stone, const GripperConfig& gripper, const Terrain* terrain,
                                  const CentredGraspOptions& o) {
  const Vector2d dir = shortest_horizontal_extent(stone).second;
  const Vector2d c = stone.centroid.head<2>();
  double reach = 0.0;  // the stone's half width across the closing line
  for (std::size_t i = 0; i < stone.mesh.vertices.size(); ++i) {
    reach = std::max(reach, std::abs(dir.dot(stone.mesh.vertices.world(i).head<2>() - c)));
  }
  GraspPlan plan;
  plan.approach_distance = o.approach_distance;
  plan.lift_height = o.lift_height;
  // Frame: x down (approach), y along the shortest extent (closing), z = x × y.
  Matrix3d R;
  R.col(0) = -Vector3d::UnitZ();
  R.col(1) = Vector3d(dir.x(), dir.y(), 0.0);
  R.col(2) = R.col(0).cross(R.col(1));
  // Palm just above the stone, raised until the jaw tips clear the ground under them. Closing
  // from an open angle, the tips swing down to their deepest (jaw_length, jaws parallel): they
  // must clear the ground there. The jaws open just enough to clear the stone (capped); a
  // wider opening widens their footprint, so the ground is checked once more.
  const auto lowest_palm = [&](double half_u) {
    return ground_under_jaws(stone, dir, half_u, gripper, terrain) + o.tip_clearance + gripper.jaw_length;
  };
  const double half_u = reach + o.opening_margin + gripper.jaw_thickness;
  double palm_z = std::max(stone.bounds.max().z() + o.palm_clearance, lowest_palm(half_u));
  plan.opening = opening_at(gripper, clearing_jaw_angle(stone, dir, palm_z, o.opening_margin, gripper));
  palm_z = std::max(palm_z, lowest_palm(std::max(half_u, 0.5 * plan.opening + gripper.jaw_thickness)));
  plan.opening = opening_at(gripper, clearing_jaw_angle(stone, dir, palm_z, o.opening_margin, gripper));
  plan.T_world_gripper.linear() = R;
  plan.T_world_gripper.translation() = Vector3d(c.x(), c.y(), palm_z);
  // Place: shifted, rotated about the vertical, following the terrain.
  const Vector2d pc = c + o.place_offset;
  const double dz = terrain != nullptr ? terrain->height(pc.x(), pc.y()) - terrain->height(c.x(), c.y()) : 0.0;
  plan.T_world_place.linear() = Eigen::AngleAxisd(o.place_yaw, Vector3d::UnitZ()).toRotationMatrix() * R;
  plan.T_world_place.translation() = Vector3d(pc.x(), pc.y(), palm_z + dz + o.place_drop);
  return plan;
}

}  // namespace cairn::sim
