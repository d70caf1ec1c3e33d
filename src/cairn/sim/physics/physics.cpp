#include "cairn/sim/physics/physics.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iomanip>
#include <numbers>
#include <sstream>

#include "cairn/core/error.hpp"
#include "cairn/sim/physics/scene.hpp"

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
constexpr double kEmptyOpening = 0.02;      // [m] jaws this close together hold nothing
constexpr double kRigidTolerance = 1e-6;    // |R^T R - I| of a valid rotation
constexpr double kExtentAngleStep = 0.5;    // [deg] search step of the shortest extent
constexpr int kJawFootprintSamples = 9;     // per axis, terrain samples under the jaws' sweep

void require(bool ok, const std::string& message) {
  if (!ok) throw ConfigError("PhysicsConfig: " + message);
}

void require_pose(const Isometry3d& T, const std::string& name) {
  if (!T.matrix().allFinite()) throw InputError("grasp plan: " + name + " is not finite");
  const Matrix3d R = T.linear();
  if ((R.transpose() * R - Matrix3d::Identity()).norm() > kRigidTolerance || R.determinant() < 0) {
    throw InputError("grasp plan: " + name + " is not a rigid transform (rotation not orthonormal)");
  }
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

Isometry3d translated_world(const Isometry3d& T, const Vector3d& d) {
  Isometry3d out = T;
  out.translation() += d;
  return out;
}

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

/// Runs the scene until every stone stayed slower than settle_speed for settle_hold, or for at
/// most max_time. Returns whether it settled.
bool run_settle(Scene& scene, const PhysicsConfig& c, double max_time) {
  const double end = scene.time() + max_time;
  double calm = 0.0;
  while (scene.time() < end) {
    scene.step();
    calm = scene.max_stone_speed() < c.settle_speed ? calm + c.timestep : 0.0;
    if (calm >= c.settle_hold) return true;
  }
  return false;
}

// ---------------------------------------------------------------------------------------------

class Trial {
 public:
  Trial(const Site& site, const GraspPlan& plan, const GripperConfig& gripper,
        const PhysicsConfig& config)
      : plan_(plan), c_(config), pre_grasp_(plan.T_world_gripper * Eigen::Translation3d(-plan.approach_distance, 0, 0)),
        scene_(site, spec(site, plan, pre_grasp_), gripper, config) {
    target_ = pre_grasp_;
    scene_.set_gripper_target(target_);
    scene_.set_jaw_command(-1.0);
    scene_.relax(config, std::vector<bool>(site.stones.size(), true));
  }

  GraspTrialResult run() {
    const auto wall_start = std::chrono::steady_clock::now();
    scene_.set_jaw_command(-1.0);
    bool ok = phase("settle_in", [&] { return wait(c_.initial_settle_time, [&] { return approach_clear(); }); });
    ok = ok && phase("approach", [&] {
      return move(plan_.T_world_gripper, c_.approach_speed, false, [&] { return approach_clear(); });
    });
    ok = ok && phase("close", [&] { return close(); }) && check_grasp();
    if (ok) {
      const Isometry3d lifted = translated_world(plan_.T_world_gripper, plan_.lift_height * Vector3d::UnitZ());
      const Isometry3d above_place = translated_world(plan_.T_world_place, plan_.lift_height * Vector3d::UnitZ());
      stone_at_lift_ = scene_.stone_body_pose(r_.grasped_stone);
      T_gripper_stone0_ = scene_.gripper_pose().inverse() * stone_at_lift_;
      opening_at_lift_ = scene_.opening();
      ok = phase("lift", [&] { return move(lifted, c_.lift_speed, false, [&] { return transport_ok(true); }); }) &&
           phase("hold", [&] { return wait(c_.hold_time, [&] { return transport_ok(false); }); }) &&
           grip_settled() &&
           phase("move", [&] { return move(above_place, c_.move_speed, true, [&] { return transport_ok(false); }); }) &&
           phase("hold", [&] { return wait(c_.hold_time, [&] { return transport_ok(false); }); }) && still_held();
    }
    if (ok || !c_.abort_on_failure) {
      if (r_.grasped_stone >= 0) {
        phase("place", [&] { return move(plan_.T_world_place, c_.lift_speed, false, [&] { return !supported(); }); });
      }
      phase("release", [&] {
        scene_.set_jaw_command(-1.0);
        return wait(c_.release_time, [] { return true; });
      });
      phase("retreat", [&] {
        return move(target_ * Eigen::Translation3d(-plan_.approach_distance, 0, 0), c_.approach_speed, false,
                    [] { return true; });
      });
    } else {
      phase("abort", [&] {
        scene_.set_jaw_command(-1.0);
        wait(c_.release_time, [] { return true; });
        return move(translated_world(target_, plan_.approach_distance * Vector3d::UnitZ()), c_.approach_speed,
                    false, [] { return true; });
      });
    }
    phase("settle", [&] { return r_.settled = run_settle(scene_, c_, c_.settle_time); });

    for (int k = 0; k < scene_.num_stones(); ++k) r_.stone_poses.push_back(scene_.stone_pose(k));
    if (ok && r_.grasped_stone >= 0) {
      const Isometry3d expected = plan_.T_world_place * plan_.T_world_gripper.inverse() * stone_at_lift_;
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
  static detail::SceneSpec spec(const Site& site, const GraspPlan& plan, const Isometry3d& pre_grasp) {
    detail::SceneSpec s;
    s.start_poses.assign(site.stones.size(), Isometry3d::Identity());
    s.with_gripper = true;
    s.T_world_gripper = pre_grasp;
    s.opening = plan.opening;
    for (const Isometry3d* T : {&pre_grasp, &plan.T_world_gripper, &plan.T_world_place}) {
      s.extra_xy.push_back(T->translation().head<2>());
    }
    return s;
  }

  template <class F>
  bool phase(const char* name, F&& body) {
    PhaseTiming t{.name = name, .start = scene_.time(), .end = 0.0};
    const bool ok = body();
    t.end = scene_.time();
    r_.phases.push_back(std::move(t));
    phase_name_ = name;
    return ok;
  }

  /// Steps for `duration`; stops early (returning false) when monitor() returns false.
  template <class F>
  bool wait(double duration, F&& monitor) {
    const double end = scene_.time() + duration;
    while (scene_.time() < end) {
      scene_.step();
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
      scene_.step();
      if (!monitor()) return false;
    }
    return true;
  }

  void fail(const char* code, const std::string& message) {
    if (std::find(r_.failure_reasons.begin(), r_.failure_reasons.end(), code) != r_.failure_reasons.end()) return;
    r_.failure_reasons.emplace_back(code);
    add_note(message);
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
      scene_.step();
      for (const Contact& c : scene_.contacts()) {
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

  /// Stones each jaw touches after closing.
  std::pair<std::vector<int>, std::vector<int>> jaw_contacts() const {
    std::pair<std::vector<int>, std::vector<int>> s;
    for (const Contact& c : scene_.contacts()) {
      if (c.b < 0) continue;
      if (c.a == detail::kJawLeft) s.first.push_back(c.b);
      if (c.a == detail::kJawRight) s.second.push_back(c.b);
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
    if (left.empty() || right.empty() || r_.grasp_opening < kEmptyOpening) {
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

  /// The ground (terrain or other stones) carries enough of the carried stone's weight.
  bool supported() const {
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
  Isometry3d pre_grasp_;
  Scene scene_;
  Isometry3d target_ = Isometry3d::Identity();
  Isometry3d stone_at_lift_ = Isometry3d::Identity(), T_gripper_stone0_ = Isometry3d::Identity();
  Isometry3d T_gripper_stone1_ = Isometry3d::Identity();
  bool gripped_ = false;
  double opening_at_lift_ = 0.0;
  std::string phase_name_;
  GraspTrialResult r_;
};

}  // namespace

void validate(const PhysicsConfig& c) {
  const auto positive = [](double v) { return std::isfinite(v) && v > 0.0; };
  const auto non_negative = [](double v) { return std::isfinite(v) && v >= 0.0; };
  require(positive(c.timestep), "timestep must be > 0");
  require(positive(c.rock_density), "rock_density must be > 0");
  require(non_negative(c.friction) && non_negative(c.torsional_friction) && non_negative(c.rolling_friction),
          "friction coefficients must be >= 0");
  require(positive(c.contact_timeconst) && positive(c.arm_timeconst), "time constants must be > 0");
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
  require(positive(c.settle_speed) && non_negative(c.settle_hold) && positive(c.jaw_stop_speed), "rest thresholds must be > 0");
  require(non_negative(c.relax_time) && positive(c.relax_timeconst), "relax_time >= 0, relax_timeconst > 0");
  require(positive(c.collision_force), "collision_force must be > 0");
  require(positive(c.jaw_slip_threshold), "jaw_slip_threshold must be > 0");
  require(non_negative(c.collision_depth) && positive(c.slip_threshold) && positive(c.slip_angle_threshold) &&
              positive(c.drop_distance),
          "collision_depth >= 0; slip_threshold, slip_angle_threshold, drop_distance > 0");
  require(c.place_support_fraction > 0.0 && c.place_support_fraction <= 1.0, "place_support_fraction must lie in (0, 1]");
}

GraspTrialResult run_grasp_trial(const Site& site, const GraspPlan& plan, const GripperConfig& gripper,
                                 const PhysicsConfig& config) {
  validate(config);
  if (!(gripper.closing_force > 0.0) || !(gripper.max_opening > 0.0)) {
    throw ConfigError("GripperConfig: closing_force and max_opening must be > 0");
  }
  require_pose(plan.T_world_gripper, "T_world_gripper");
  require_pose(plan.T_world_place, "T_world_place");
  if (!(plan.opening > 0.0 && plan.opening <= gripper.max_opening + 1e-9)) {
    throw InputError("grasp plan: opening must lie in (0, max_opening = " + std::to_string(gripper.max_opening) + "]");
  }
  if (!(std::isfinite(plan.approach_distance) && plan.approach_distance >= 0.0 && std::isfinite(plan.lift_height) &&
        plan.lift_height >= 0.0)) {
    throw InputError("grasp plan: approach_distance and lift_height must be finite and >= 0");
  }
  if (plan.swing_pivot && !plan.swing_pivot->allFinite()) throw InputError("grasp plan: swing_pivot is not finite");
  if (plan.target_stone >= static_cast<int>(site.stones.size())) {
    throw InputError("grasp plan: target_stone " + std::to_string(plan.target_stone) + " but the site has " +
                     std::to_string(site.stones.size()) + " stones");
  }
  Trial trial(site, plan, gripper, config);
  return trial.run();
}

SettleResult settle_stones(const Site& site, const PhysicsConfig& config, std::span<const Eigen::Isometry3d> start_poses) {
  validate(config);
  if (!start_poses.empty() && start_poses.size() != site.stones.size()) {
    throw InputError("settle_stones: " + std::to_string(start_poses.size()) + " start poses for " +
                     std::to_string(site.stones.size()) + " stones");
  }
  const auto wall_start = std::chrono::steady_clock::now();
  detail::SceneSpec spec;
  spec.start_poses.assign(site.stones.size(), Isometry3d::Identity());
  for (std::size_t k = 0; k < start_poses.size(); ++k) {
    require_pose(start_poses[k], "start pose of stone " + std::to_string(k));
    spec.start_poses[k] = start_poses[k];
  }
  Scene scene(site, spec, GripperConfig{}, config);
  std::vector<bool> at_placement;  // dropped stones fall freely
  for (const Isometry3d& T : spec.start_poses) at_placement.push_back(T.isApprox(Isometry3d::Identity()));
  scene.relax(config, at_placement);
  SettleResult r;
  r.settled = run_settle(scene, config, config.settle_time);
  r.max_speed = scene.max_stone_speed();
  for (int k = 0; k < scene.num_stones(); ++k) r.stone_poses.push_back(scene.stone_pose(k));
  r.sim_time = scene.time();
  r.wall_time = seconds_since(wall_start);
  return r;
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

GraspPlan centred_antipodal_grasp(const Stone& stone, const GripperConfig& gripper, const Terrain* terrain,
                                  const CentredGraspOptions& o) {
  const auto [width, dir] = shortest_horizontal_extent(stone);
  (void)width;
  const Vector2d c = stone.centroid.head<2>();
  // Opening: the jaws must clear the stone on both sides of the centroid.
  double reach = 0.0;
  for (std::size_t i = 0; i < stone.mesh.vertices.size(); ++i) {
    reach = std::max(reach, std::abs(dir.dot(stone.mesh.vertices.world(i).head<2>() - c)));
  }
  GraspPlan plan;
  plan.opening = std::min(gripper.max_opening, 2.0 * (reach + o.opening_margin));
  plan.approach_distance = o.approach_distance;
  plan.lift_height = o.lift_height;
  // Frame: x down (approach), y along the shortest extent (closing), z = x × y.
  Matrix3d R;
  R.col(0) = -Vector3d::UnitZ();
  R.col(1) = Vector3d(dir.x(), dir.y(), 0.0);
  R.col(2) = R.col(0).cross(R.col(1));
  // Lowest safe jaw-tip height: highest terrain under the jaws' sweep (open → centre), else the
  // stone's lowest point.
  double ground = stone.bounds.min().z();
  if (terrain != nullptr) {
    ground = -INFINITY;
    const Vector2d side(-dir.y(), dir.x());
    const double half_u = 0.5 * plan.opening + gripper.jaw_thickness, half_v = 0.5 * gripper.jaw_height;
    for (int i = 0; i < kJawFootprintSamples; ++i) {
      for (int j = 0; j < kJawFootprintSamples; ++j) {
        const double u = -half_u + 2.0 * half_u * i / (kJawFootprintSamples - 1);
        const double w = -half_v + 2.0 * half_v * j / (kJawFootprintSamples - 1);
        const Vector2d p = c + u * dir + w * side;
        ground = std::max(ground, terrain->height(p.x(), p.y()));
      }
    }
    if (!std::isfinite(ground)) ground = terrain->height(c.x(), c.y());
  }
  const double palm_z = std::max(stone.bounds.max().z() + o.palm_clearance, ground + o.tip_clearance + gripper.jaw_length);
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
