// Physics grasp trials in MuJoCo: centred grasps succeed, grasps on air and into the terrain fail
// with the right reasons, dropped stones come to rest, results are deterministic.
#include "cairn/sim/physics/physics.hpp"
#include "cairn/sim/simulation.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <vector>

#include "cairn/core/error.hpp"
#include "cairn/sim/physics/scene.hpp"
#include "support/sanitizers.hpp"

namespace cairn::sim {
namespace {

using Eigen::Isometry3d;
using Eigen::Vector2d;
using Eigen::Vector3d;

bool has_reason(const GraspTrialResult& r, const std::string& code) {
  return std::find(r.failure_reasons.begin(), r.failure_reasons.end(), code) != r.failure_reasons.end();
}

/// Closed, outward-oriented box mesh between lo and hi (world frame).
io::Mesh box_mesh(const Vector3d& lo, const Vector3d& hi) {
  io::Mesh mesh;
  for (int i = 0; i < 8; ++i) {
    const Vector3d corner((i & 1) ? hi.x() : lo.x(), (i & 2) ? hi.y() : lo.y(), (i & 4) ? hi.z() : lo.z());
    mesh.vertices.points.push_back(corner.cast<float>());
  }
  mesh.triangles = {{0, 2, 3}, {0, 3, 1}, {4, 5, 7}, {4, 7, 6}, {0, 1, 5}, {0, 5, 4},
                    {2, 6, 7}, {2, 7, 3}, {0, 4, 6}, {0, 6, 2}, {1, 3, 7}, {1, 7, 5}};
  return mesh;
}

Stone box_stone(const Vector3d& lo, const Vector3d& hi) {
  Stone s;
  s.mesh = box_mesh(lo, hi);
  s.volume = mesh_volume(s.mesh);
  s.centroid = mesh_centroid(s.mesh);
  s.bounds = Eigen::AlignedBox3d(lo, hi);
  return s;
}

/// Flat terrain at z = 0 with one box-like stone (1.5 x 1.4 x 0.45 m = 0.95 m^3, 2.5 t, the
/// paper's size range; as wide as the jaw pivots are apart, so the jaws close on it parallel)
/// resting on it.
constexpr double kBoxWidth = 1.4;
Site flat_box_site() {
  Site site;
  site.terrain.config = TerrainConfig{.slope_x = 0.0, .slope_y = 0.0, .bump_amplitude = 0.0, .roughness = 0.0};
  site.stones.push_back(box_stone({-0.75, -0.5 * kBoxWidth, 0.0}, {0.75, 0.5 * kBoxWidth, 0.45}));
  return site;
}

/// Coarser settings that keep each trial to about a second of wall time.
PhysicsConfig fast_config() {
  PhysicsConfig c;
  c.timestep = 0.004;
  c.contact_timeconst = 0.008;  // >= 2 * timestep
  c.terrain_resolution = 0.2;
  c.settle_time = 2.0;
  return c;
}

/// The centred grasp of flat_box_site()'s box, set down 1.5 m along x and 0.5 m along y, turned by `yaw`.
GraspPlan box_plan(const Site& site, const GripperConfig& gripper, double yaw) {
  CentredGraspOptions o;
  o.place_offset = {1.5, 0.5};
  o.place_yaw = yaw;
  GraspPlan plan = centred_antipodal_grasp(site.stones[0], gripper, &site.terrain, o);
  plan.target_stone = 0;
  return plan;
}

TEST(GraspTrial, CentredAntipodalGraspOnBoxSucceedsAndPlaces) {
  const Site site = flat_box_site();
  const GripperConfig gripper;
  const GraspPlan plan = box_plan(site, gripper, 0.4);
  // The shortest horizontal extent of the box is along y.
  EXPECT_NEAR(std::abs(plan.T_world_gripper.linear().col(1).y()), 1.0, 1e-9);
  const GraspTrialResult r = run_grasp_trial(site, plan, gripper, fast_config());
  EXPECT_TRUE(r.success) << r.message;
  EXPECT_TRUE(r.failure_reasons.empty());
  EXPECT_EQ(r.grasped_stone, 0);
  EXPECT_NEAR(r.grasp_opening, kBoxWidth, 0.03);
  EXPECT_LT(r.slip_distance, 0.05);
  EXPECT_TRUE(r.settled);
  ASSERT_EQ(r.stone_poses.size(), 1u);
  // The stone ends near the place pose: shifted by the offset, turned by the yaw.
  const Vector3d c = site.stones[0].centroid;
  const Vector3d moved = r.stone_poses[0] * c;
  EXPECT_NEAR(moved.x(), c.x() + 1.5, 0.1);
  EXPECT_NEAR(moved.y(), c.y() + 0.5, 0.1);
  EXPECT_NEAR(moved.z(), c.z(), 0.05);  // resting on the flat ground again
  EXPECT_NEAR(Eigen::AngleAxisd(r.stone_poses[0].linear()).angle(), 0.4, 0.1);
  EXPECT_GE(r.place_error, 0.0);
  EXPECT_LT(r.place_error, 0.1);
}

std::vector<TraceSample> trace_in(const GraspTrialResult& r, const std::string& phase);

// Placing by weight (GraspPlan::place_com_xy): a grasp 0.25 m off the box's centre along its
// length, set down (turned by the swing) where a centred grasp would have put the centre.
// Without weighing, the centre of mass lands 0.25 m off the target; weighed while it hangs still, the arm's moment gives the
// centre under the gripper and the place pose is shifted so that it lands on the target.
TEST(GraspTrial, PlacingByWeightPutsTheCentreOfMassOnTheTarget) {
  const Site site = flat_box_site();
  const GripperConfig gripper;
  GraspPlan plan = box_plan(site, gripper, 0.6);
  constexpr double kOff = 0.25;  // [m] along the box's length (world x), within the jaws' height
  plan.T_world_gripper.translation().x() += kOff;  // set down where the centred grasp's gripper was
  const Vector3d c = site.stones[0].centroid;
  const Vector2d target = c.head<2>() + Vector2d(1.5, 0.5);
  const auto landed = [&](const GraspTrialResult& r) {
    return Vector2d((r.stone_poses.at(0) * c).head<2>() - target).norm();
  };
  const GraspTrialResult blind = run_grasp_trial(site, plan, gripper, fast_config());
  ASSERT_TRUE(blind.success) << blind.message;
  EXPECT_FALSE(blind.weighed_com.allFinite());
  EXPECT_LT(blind.place_correction, 0.0);
  EXPECT_GT(landed(blind), 0.2);
  plan.place_com_xy = target;
  const GraspTrialResult weighed = run_grasp_trial(site, plan, gripper, fast_config());
  ASSERT_TRUE(weighed.success) << weighed.message;
  ASSERT_TRUE(weighed.weighed_com.allFinite());
  // The truth: where the box's centre hung in the hold (it swings in about the jaw axis first).
  const std::vector<TraceSample> hold = trace_in(weighed, "hold");
  ASSERT_FALSE(hold.empty());
  const Isometry3d lifted = Eigen::Translation3d(0, 0, plan.lift_height) * plan.T_world_gripper;
  const Vector2d held_com = (lifted * hold.front().stone_in_gripper).head<2>();
  std::printf("weighed centre %.4f %.4f m, true %.4f %.4f; landed %.3f m off the target (%.3f m without weighing)\n",
              weighed.weighed_com.x(), weighed.weighed_com.y(), held_com.x(), held_com.y(), landed(weighed),
              landed(blind));
  EXPECT_LT((weighed.weighed_com.head<2>() - held_com).norm(), 0.01);  // measured 2 mm
  EXPECT_GT(weighed.place_correction, 0.2);
  // Measured 3.0 cm: the box hangs tilted about the jaw axis (held off-centre); its low edge
  // touches first, and pressed down until the ground carries it (Trial::set_down) it turns flat
  // in the jaws, its centre moving sideways; the weighing itself is within millimetres.
  EXPECT_LT(landed(weighed), 0.05);
}

/// Samples of the trace within a phase of the trial.
std::vector<TraceSample> trace_in(const GraspTrialResult& r, const std::string& phase) {
  std::vector<TraceSample> out;
  for (const PhaseTiming& p : r.phases) {
    if (p.name != phase) continue;
    for (const TraceSample& t : r.trace) {
      if (t.time >= p.start && t.time <= p.end) out.push_back(t);
    }
  }
  return out;
}

// The lowest arm load of a phase's trace samples [N] (negative: the arm pushing down).
double min_load(const GraspTrialResult& r, const std::string& phase) {
  double m = 0.0;
  for (const TraceSample& t : trace_in(r, phase)) m = std::min(m, t.arm_load);
  return m;
}

// The box gripped 0.25 m off its centre (it hangs tilted about the jaw axis) and set down with
// the place pose 0.3 m below the ground contact, so only the arm's load can stop the lowering.
GraspPlan off_centre_box_pressed_down(const Site& site, const GripperConfig& gripper) {
  CentredGraspOptions o;
  o.place_offset = {1.5, 0.5};
  o.place_drop = -0.3;
  GraspPlan plan = centred_antipodal_grasp(site.stones[0], gripper, &site.terrain, o);
  plan.target_stone = 0;
  plan.T_world_gripper.translation().x() += 0.25;
  return plan;
}

// Setting down on the machine's signal (PhysicsConfig::place_support_fraction): a box held 0.25 m
// off its centre hangs tilted about the jaw axis, so one edge touches the ground first and rings
// the stiff contact (the arm's load swings to several times the weight, both signs, for a few
// steps). The place pose lies 0.3 m below the ground contact, so only the load can stop the
// lowering, and it must stop once the ground carries the box, not on that first touch.
TEST(GraspTrial, TheJawsOpenOnlyOnceTheGroundCarriesTheStone) {
  const Site site = flat_box_site();
  const GripperConfig gripper;
  const GraspPlan plan = off_centre_box_pressed_down(site, gripper);
  PhysicsConfig c = fast_config();
  const GraspTrialResult r = run_grasp_trial(site, plan, gripper, c);
  ASSERT_TRUE(r.success) << r.message;
  ASSERT_TRUE(r.released_centroid.allFinite() && r.rest_centroid.allFinite());
  // How far the box's centre fell once the jaws opened: it is still tilted in the jaws (its low
  // edge on the ground) and turns flat; the higher it hung, the further.
  const double fell = r.released_centroid.z() - r.rest_centroid.z();
  std::printf("released on support: %d; the box's centre fell %.3f m after the release\n", r.released_on_support, fell);
  // Truth: the contacts carried place_support_fraction (95 %) of the weight when the jaws opened,
  // the box lay flat (measured: it fell 0.000 m). Without clipping the ring's samples
  // (Trial::load_fell) the jaws opened on the first touch: not on support, and the box fell 0.175 m
  // (with them clipped at 80 %: the box still tilted ~10 deg in the jaws, 0.119 m).
  EXPECT_TRUE(r.released_on_support);
  EXPECT_LT(fell, 0.02);
}

// The box of the test above, held off its centre and commanded 0.3 m below the ground contact.
// Lowered at full speed the arm drives on for the filter's lag after the ground has taken the box
// and pushes it through the grip until both jaw tips stand on the ground.
// - The arm stops where the set-down fired (PhysicsConfig::place_stop_on_set_down, default) instead
//   of holding on to its last, deeper command while the jaws open.
// - Feathering (place_touch_fraction, place_touch_speed) keeps the jaws off the ground; off by
//   default: stones seated less firmly move more after the release (docs/simulator-physics.md).
// - Converging jaws swing their tips forwards as they open: tips on the ground cannot open unless
//   the arm backs off while they open (PhysicsConfig::release_backoff, default).
TEST(GraspTrial, TheSetDownStopsTheArmAndFeatheringKeepsTheJawsOffTheGround) {
  const Site site = flat_box_site();
  const GripperConfig gripper;
  const GraspPlan plan = off_centre_box_pressed_down(site, gripper);
  const auto run = [&](const char* name, bool stop, double touch_fraction, bool backoff, double backoff_max) {
    PhysicsConfig c = fast_config();
    c.place_stop_on_set_down = stop;
    c.place_touch_fraction = touch_fraction;
    c.release_backoff = backoff;
    c.release_backoff_max = backoff_max;
    GraspTrialResult r = run_grasp_trial(site, plan, gripper, c);
    std::printf("%s: the box moved %.3f m in the grip while set down; jaws on the ground: %zu; release command z "
                "%.3f m; arm load while opening down to %.0f kN; the jaws opened %.3f m (backing off %.3f m); the box "
                "fell %.3f m after the release\n",
                name, r.set_down_drift, r.release_touches.size(), r.T_world_release.translation().z(),
                min_load(r, "release") / 1000.0, r.release_opened, r.release_backoff,
                r.released_centroid.z() - r.rest_centroid.z());
    EXPECT_TRUE(r.success) << name << ": " << r.message;
    return r;
  };
  const PhysicsConfig defaults = fast_config();
  const double backoff_max = defaults.release_backoff_max;
  const GraspTrialResult stopped = run("stops where set down (default)", true, 0.0, true, backoff_max);
  const GraspTrialResult pressing = run("presses on (before)", false, 0.0, true, backoff_max);
  const GraspTrialResult feathered = run("feathered", true, 0.2, true, backoff_max);
  const GraspTrialResult still = run("stops, the arm still while the jaws open (before)", true, 0.0, false, backoff_max);
  const GraspTrialResult capped = run("stops, backs off at most 1 cm", true, 0.0, true, 0.01);
  // Measured: the stopped arm's command at the opening 0.999 m, the pressing arm's 0.972 m.
  EXPECT_GT(stopped.T_world_release.translation().z(), pressing.T_world_release.translation().z() + 0.01);
  // Measured: without feathering the box moved 0.159 m in the grip while set down and both jaw
  // tips ended on the ground. Feathered: 0.105 m, no jaw on the ground, -7 kN with the arm still
  // while the jaws open, -6 kN backing off.
  EXPECT_GE(stopped.set_down_drift, 0.0);
  EXPECT_LT(feathered.set_down_drift, stopped.set_down_drift - 0.02);
  EXPECT_TRUE(feathered.release_touches.empty()) << feathered.release_touches.front();
  EXPECT_GT(min_load(feathered, "release"), -20e3);
  EXPECT_LT(feathered.released_centroid.z() - feathered.rest_centroid.z(), 0.02);  // it lay flat
  // The tips on the ground: with the arm still the jaws could not open (measured: 2 mm in the
  // release phase; the arm's load -7.9 MN in its first sample); backing off 3.2 cm they open
  // 0.327 m, to the plan's opening.
  ASSERT_FALSE(stopped.release_touches.empty());
  EXPECT_GT(stopped.release_backoff, 0.0);
  // It stopped because the jaws opened, not at a limit (the phase allows speed x release_time).
  EXPECT_LT(stopped.release_backoff, std::min(backoff_max, defaults.release_backoff_speed * defaults.release_time) - 0.01);
  EXPECT_EQ(still.release_backoff, 0.0);
  EXPECT_NEAR(capped.release_backoff, 0.01, 1e-9);
  const std::vector<TraceSample> opening = trace_in(stopped, "release");
  ASSERT_FALSE(opening.empty());
  EXPECT_GE(opening.back().opening, plan.opening - defaults.release_open_tolerance);
  EXPECT_GT(stopped.release_opened, still.release_opened + 0.1);
  EXPECT_LT(stopped.released_centroid.z() - stopped.rest_centroid.z(), 0.02);
}

TEST(GraspTrial, TraceCarriesTheStoneWeightAndASteadyJaw) {
  // What the machine measures (Sec. 6.3): while the stone hangs in the grip the arm carries its
  // weight (2.5 t), and the jaw opening stays at the stone's width. The load is read as the
  // median of the hold (a load cell's filtered value): single samples spike when the tips'
  // edge contacts chatter.
  const Site site = flat_box_site();
  const GripperConfig gripper;
  GraspPlan plan = centred_antipodal_grasp(site.stones[0], gripper, &site.terrain);
  plan.target_stone = 0;
  const PhysicsConfig c = fast_config();
  const GraspTrialResult r = run_grasp_trial(site, plan, gripper, c);
  ASSERT_TRUE(r.success) << r.message;
  ASSERT_GT(r.trace.size(), 100u);
  for (std::size_t i = 1; i < r.trace.size(); ++i) EXPECT_GT(r.trace[i].time, r.trace[i - 1].time);
  const double weight = c.rock_density * site.stones[0].volume * 9.81;
  const std::vector<TraceSample> hold = trace_in(r, "hold");
  ASSERT_GE(hold.size(), 10u);
  std::vector<double> load;
  for (const TraceSample& t : hold) {
    load.push_back(t.arm_load);
    EXPECT_NEAR(t.opening, kBoxWidth, 0.03) << "t = " << t.time;
    EXPECT_NEAR(t.opening, opening_at(gripper, t.jaw_angle), 1e-9);
  }
  std::nth_element(load.begin(), load.begin() + static_cast<std::ptrdiff_t>(load.size() / 2), load.end());
  EXPECT_NEAR(load[load.size() / 2], weight, 0.1 * weight);
  // Before the grasp, held still, the arm carries nothing but the gripper (while it moves, the
  // trace also holds the gripper's own inertia: ~1.7 t at the min-jerk accelerations).
  for (const TraceSample& t : trace_in(r, "settle_in")) EXPECT_NEAR(t.arm_load, 0.0, 0.02 * weight);
}

/// Largest motion of the target stone relative to the gripper during the first `phase`
/// (diagnostic trace).
double creep_in(const GraspTrialResult& r, const std::string& phase) {
  const auto p = std::find_if(r.phases.begin(), r.phases.end(), [&](const PhaseTiming& q) { return q.name == phase; });
  if (p == r.phases.end()) return -1.0;  // no such phase
  const TraceSample* first = nullptr;
  double d = 0.0;
  for (const TraceSample& s : r.trace) {
    if (s.time < p->start || s.time > p->end) continue;
    if (!first) first = &s;
    d = std::max(d, (s.stone_in_gripper - first->stone_in_gripper).norm());
  }
  return first ? d : -1.0;  // no trace sample in it
}

TEST(GraspTrial, CentredGraspsHoldTheGeneratedStonesWithoutCreep) {
  // Static friction holds: the centred grasp squeezes each stone of a settled exp1 site (0.5-1
  // m^3, procedural) with 60 kN per jaw tip at mu 0.6, and a stone that is held hangs still in
  // the grip. With MuJoCo's pyramidal cone and no no-slip pass the soft frictional contacts
  // creep instead (stones slid 1-2 cm/s along the jaw faces while squeezed and lifted), and most
  // of these grasps failed as "slipped" (issue #17): the defaults are the elliptic cone with the
  // no-slip pass.
  SimulationConfig cfg = scenario_config("exp1", "");  // procedural stones: no data needed
  cfg.settle_in_physics = true;
  const SimulatedWorld w = make_world(cfg, 1);
  ASSERT_TRUE(w.site.at_rest);
  ASSERT_EQ(cfg.physics.cone, "elliptic");
  ASSERT_GT(cfg.physics.noslip_iterations, 0);
  PhysicsConfig soft = cfg.physics;
  soft.cone = "pyramidal";
  soft.noslip_iterations = 0;
  // The contrast is the creep alone: a creeping stone wedged while lifted can also stall the arm
  // (stone 5: 61 kN), which would hide its slip.
  soft.arm_max_force = std::numeric_limits<double>::infinity();
#ifdef __SANITIZE_ADDRESS__
  const std::size_t stones = 2;  // the path once under ASan; the figures in Release
#else
  const std::size_t stones = w.site.stones.size();
#endif
  // Counted: grasps that slip (the creep's symptom); grasps the centred plan drives into a
  // touching neighbour (stones 3 and 6 of this site) fail either way.
  int slipped = 0, slipped_soft = 0, held = 0;
  for (std::size_t k = 0; k < stones; ++k) {
    GraspPlan plan = centred_antipodal_grasp(w.site.stones[k], cfg.gripper, &w.site.terrain);
    plan.target_stone = int(k);
    // Placing by weight on the way: the centre of mass set down where the plan would put it.
    plan.place_com_xy = (plan.T_world_place * plan.T_world_gripper.inverse() * w.site.stones[k].centroid).head<2>();
    const GraspTrialResult r = run_grasp_trial(w.site, plan, cfg.gripper, cfg.physics);
    held += r.success ? 1 : 0;
    if (r.success) {  // the weighing finds where the stone hangs (truth: the trace), within 1 cm
      ASSERT_TRUE(r.weighed_com.allFinite()) << "stone " << k;
      const std::vector<TraceSample> hold = trace_in(r, "hold");
      ASSERT_FALSE(hold.empty());
      const Isometry3d lifted = Eigen::Translation3d(0, 0, plan.lift_height) * plan.T_world_gripper;
      EXPECT_LT(((lifted * hold.front().stone_in_gripper) - r.weighed_com).head<2>().norm(), 0.01) << "stone " << k;
    }
    slipped += has_reason(r, reason::kSlipped) ? 1 : 0;
    EXPECT_FALSE(r.arm_stalled) << "stone " << k << ": " << r.message;  // a normal carry never stalls
    if (r.success) {
      const double creep = creep_in(r, "hold");
      EXPECT_GE(creep, 0.0) << "stone " << k << ": no hold phase";
      EXPECT_LT(creep, 0.005) << "stone " << k;
    }
    slipped_soft += has_reason(run_grasp_trial(w.site, plan, cfg.gripper, soft), reason::kSlipped) ? 1 : 0;
  }
  EXPECT_GE(held, 1);
  EXPECT_LE(slipped, 1);
#ifndef __SANITIZE_ADDRESS__
  EXPECT_GE(slipped_soft, slipped + 2) << "the pyramidal cone's creep";
#endif
}

TEST(GraspTrial, LowFrictionSlipShowsInTheJawTrace) {
  // A wedge-shaped stone (1.6 m long, 1.45 m wide at the bottom, 1.4 m at the top, 0.45 m high,
  // 1.03 m^3): at friction 0.1 it slides down out of the jaws while lifting, and because it
  // narrows upwards the wire encoder's trace shows the jaws closing further; the result says
  // "slipped". (At the default friction this slab is not held either: the jaw tips pinch it
  // near its bottom edge and it drops, docs/simulator-physics.md; the parallel-faced box of the
  // tests above is held.)
  Site site = flat_box_site();
  Stone wedge;
  for (int i = 0; i < 8; ++i) {
    const float half_width = (i & 4) ? 0.7f : 0.725f;
    wedge.mesh.vertices.points.emplace_back((i & 1) ? 0.8f : -0.8f, (i & 2) ? half_width : -half_width,
                                            (i & 4) ? 0.45f : 0.0f);
  }
  wedge.mesh.triangles = box_mesh(Vector3d::Zero(), Vector3d::Ones()).triangles;
  wedge.volume = mesh_volume(wedge.mesh);
  wedge.centroid = mesh_centroid(wedge.mesh);
  for (std::size_t i = 0; i < wedge.mesh.vertices.size(); ++i) wedge.bounds.extend(wedge.mesh.vertices.world(i));
  site.stones[0] = wedge;
  const GripperConfig gripper;
  GraspPlan plan = centred_antipodal_grasp(site.stones[0], gripper, &site.terrain);
  plan.target_stone = 0;
  PhysicsConfig c = fast_config();
  c.friction = 0.1;
  const GraspTrialResult r = run_grasp_trial(site, plan, gripper, c);
  EXPECT_FALSE(r.success);
  EXPECT_TRUE(has_reason(r, reason::kSlipped)) << r.message;
  const std::vector<TraceSample> lift = trace_in(r, "lift");
  ASSERT_GE(lift.size(), 2u);
  EXPECT_GT(r.jaw_travel, c.jaw_slip_threshold);
  // The trace (every 20 ms, and at the moment the detector fired) shows the jaws closing; its
  // first lift sample comes up to 20 ms into the lift, when the slip has begun.
  EXPECT_GT(lift.front().opening - lift.back().opening, 0.75 * c.jaw_slip_threshold);
}

TEST(GraspTrial, StonesFarFromThePathAreStatic) {
  // Two boxes 5 m apart: grasping one leaves the other static (not simulated, not moved).
  Site site = flat_box_site();
  site.stones.push_back(box_stone({4.6, -0.25, 0.0}, {5.4, 0.25, 0.5}));
  const GripperConfig gripper;
  CentredGraspOptions o;
  o.place_offset = {0.0, 1.5};
  GraspPlan plan = centred_antipodal_grasp(site.stones[0], gripper, &site.terrain, o);
  plan.target_stone = 0;
  const GraspTrialResult r = run_grasp_trial(site, plan, gripper, fast_config());
  EXPECT_TRUE(r.success) << r.message;
  EXPECT_EQ(r.free_stones, 1);
  EXPECT_TRUE(r.stone_poses[1].isApprox(Isometry3d::Identity(), 1e-12));
  // Placed next to it instead, the second box is free (it could be bumped).
  o.place_offset = {4.3, 0.0};  // the carried box reaches into the second one
  plan = centred_antipodal_grasp(site.stones[0], gripper, &site.terrain, o);
  plan.target_stone = 0;
  EXPECT_EQ(run_grasp_trial(site, plan, gripper, fast_config()).free_stones, 2);
}

// A carried stone driven into a wall: the arm's force limit stalls it where it hits (the machine
// knows: arm_stalled) and it is set down there; without the limit the arm's weld drives on and
// shoves the 16 t wall aside.
TEST(GraspTrial, TheArmStallsWhenTheCarriedStoneHitsSomething) {
  Site site = flat_box_site();
  site.stones.push_back(box_stone({2.0, -2.0, 0.0}, {2.6, 2.0, 2.5}));  // in the way, 6 m^3
  const GripperConfig gripper;
  CentredGraspOptions o;
  o.place_offset = {5.0, 0.0};  // beyond the wall
  GraspPlan plan = centred_antipodal_grasp(site.stones[0], gripper, &site.terrain, o);
  plan.target_stone = 0;
  plan.swing_pivot.reset();  // straight through
  plan.lift_height = 0.5;    // the carried box's underside below the wall's top
  PhysicsConfig c = fast_config();
  c.abort_on_failure = false;  // the experiment's machine: blind to the simulator's verdicts
  const GraspTrialResult r = run_grasp_trial(site, plan, gripper, c);
  EXPECT_TRUE(r.arm_stalled) << r.message;
  EXPECT_TRUE(has_reason(r, reason::kCollisionTransport)) << r.message;
  ASSERT_EQ(r.stone_poses.size(), 2u);
  const auto moved = [&](const GraspTrialResult& t, int k) {
    const Vector3d c0 = site.stones[std::size_t(k)].centroid;
    return (t.stone_poses[std::size_t(k)] * c0 - c0).norm();
  };
  EXPECT_LT(moved(r, 1), 0.1) << "the wall";
  EXPECT_LT((r.stone_poses[0] * site.stones[0].centroid).x(), 2.0) << "the carried box stays on its side";
  EXPECT_LT(r.T_world_release.translation().x(), 2.0);
  if (test::kSanitized) return;  // the comparison without the limit: Release only (the path is the same)
  c.arm_max_force = std::numeric_limits<double>::infinity();  // the weld alone
  const GraspTrialResult weld = run_grasp_trial(site, plan, gripper, c);
  EXPECT_FALSE(weld.arm_stalled);
  std::printf("wall moved %.3f m with the arm's limit, %.3f m without; carried box %.3f vs %.3f m\n", moved(r, 1),
              moved(weld, 1), moved(r, 0), moved(weld, 0));
  EXPECT_GT(moved(weld, 1), 0.5) << weld.message;
}

TEST(GraspTrial, SwingAboutAPivotSucceeds) {
  const Site site = flat_box_site();
  const GripperConfig gripper;
  CentredGraspOptions o;
  o.place_offset = {-2.0, 2.0};  // a quarter turn about (-2, 0)
  o.place_yaw = std::numbers::pi / 2;
  GraspPlan plan = centred_antipodal_grasp(site.stones[0], gripper, &site.terrain, o);
  plan.swing_pivot = Eigen::Vector2d(-2.0, 0.0);
  const GraspTrialResult r = run_grasp_trial(site, plan, gripper, fast_config());
  EXPECT_TRUE(r.success) << r.message;
  EXPECT_NEAR((r.stone_poses[0] * site.stones[0].centroid - Vector3d(-2.0, 2.0, 0.225)).head<2>().norm(), 0.0, 0.1);
}

TEST(GraspTrial, GraspOnAirFailsAsEmpty) {
  const Site site = flat_box_site();
  const GripperConfig gripper;
  GraspPlan plan = centred_antipodal_grasp(site.stones[0], gripper, &site.terrain);
  plan.T_world_gripper.translation().x() += 3.0;  // nothing there
  plan.T_world_place.translation().x() += 3.0;
  const GraspTrialResult r = run_grasp_trial(site, plan, gripper, fast_config());
  EXPECT_FALSE(r.success);
  ASSERT_EQ(r.failure_reasons.size(), 1u) << r.message;
  EXPECT_EQ(r.failure_reasons[0], reason::kEmptyGrasp);
  EXPECT_NE(r.message.find("nothing between the jaws"), std::string::npos) << r.message;
  EXPECT_EQ(r.grasped_stone, -1);
  EXPECT_LT(r.grasp_opening, 0.05);  // the jaws closed fully
  EXPECT_LT(r.stone_poses[0].translation().norm(), 0.01);  // the stone was not touched
}

TEST(GraspTrial, JawHittingTheTerrainOnApproachIsACollision) {
  const Site site = flat_box_site();
  const GripperConfig gripper;
  GraspPlan plan = centred_antipodal_grasp(site.stones[0], gripper, &site.terrain);
  // Palm 0.1 m above the box top: the jaw tips end 0.2 m below the ground.
  plan.T_world_gripper.translation().z() = 0.6;
  const GraspTrialResult r = run_grasp_trial(site, plan, gripper, fast_config());
  EXPECT_FALSE(r.success);
  EXPECT_TRUE(has_reason(r, reason::kCollisionApproach)) << r.message;
  EXPECT_NE(r.message.find("jaw_"), std::string::npos) << r.message;
  EXPECT_NE(r.message.find("hit terrain"), std::string::npos) << r.message;
  EXPECT_EQ(r.grasped_stone, -1);
}

TEST(GraspTrial, PalmHittingTheStoneOnApproachIsACollision) {
  Site site = flat_box_site();
  site.stones[0] = box_stone({-0.3, -0.25, 0.0}, {0.3, 0.25, 1.4});  // tall: the jaws stay clear
  const GripperConfig gripper;
  GraspPlan plan = centred_antipodal_grasp(site.stones[0], gripper, &site.terrain);
  plan.T_world_gripper.translation().z() = 1.35;  // palm 5 cm into the box top
  const GraspTrialResult r = run_grasp_trial(site, plan, gripper, fast_config());
  EXPECT_TRUE(has_reason(r, reason::kCollisionApproach)) << r.message;
  EXPECT_NE(r.message.find("palm hit stone 0"), std::string::npos) << r.message;
}

TEST(GraspTrial, PhysicsJawsAreTheGripperParts) {
  // One definition: MuJoCo's palm and jaw pads, at the scene's start, tile exactly the parts of
  // robot/gripper.hpp at the plan's opening (every pad corner inside its part, volumes equal).
  const Site site = flat_box_site();
  const GripperConfig gripper;
  detail::SceneSpec spec;
  spec.start_poses.assign(1, Isometry3d::Identity());
  spec.with_gripper = true;
  spec.T_world_gripper.linear() = Eigen::AngleAxisd(2.0, Vector3d(0.3, -1.0, 0.2).normalized()).toRotationMatrix();
  spec.T_world_gripper.translation() = Vector3d(0.5, -1.0, 3.0);
  spec.opening = 1.3;
  const detail::Scene scene(site, spec, gripper, fast_config());
  const std::vector<ConvexPart> parts = gripper_parts(gripper, spec.opening);
  std::array<double, 3> volume{};
  for (const detail::Scene::GeomBox& b : scene.gripper_boxes()) {
    const std::size_t part = b.entity == detail::kPalm ? 0 : (b.entity == detail::kJawLeft ? 1 : 2);
    volume[part] += 8.0 * b.half.prod();
    for (int i = 0; i < 8; ++i) {
      const Vector3d sign((i & 1) ? 1.0 : -1.0, (i & 2) ? 1.0 : -1.0, (i & 4) ? 1.0 : -1.0);
      const Vector3d corner_G = spec.T_world_gripper.inverse() * (b.pose * sign.cwiseProduct(b.half));
      EXPECT_TRUE(parts[part].contains(corner_G, 1e-6)) << parts[part].name << " corner " << corner_G.transpose();
    }
  }
  for (std::size_t p = 0; p < 3; ++p) EXPECT_NEAR(volume[p], 8.0 * parts[p].half_extents.prod(), 1e-9) << parts[p].name;
  EXPECT_NEAR(scene.opening(), spec.opening, 1e-9);
}

TEST(GraspTrial, IsDeterministic) {
  const Site site = flat_box_site();
  const GripperConfig gripper;
  const GraspPlan plan = centred_antipodal_grasp(site.stones[0], gripper, &site.terrain);
  const GraspTrialResult a = run_grasp_trial(site, plan, gripper, fast_config());
  const GraspTrialResult b = run_grasp_trial(site, plan, gripper, fast_config());
  EXPECT_EQ(a.success, b.success);
  EXPECT_EQ(a.failure_reasons, b.failure_reasons);
  EXPECT_EQ(a.slip_distance, b.slip_distance);
  EXPECT_EQ(a.sim_time, b.sim_time);
  ASSERT_EQ(a.stone_poses.size(), b.stone_poses.size());
  EXPECT_TRUE(a.stone_poses[0].matrix() == b.stone_poses[0].matrix());
}

TEST(GraspTrial, RejectsInvalidInput) {
  const Site site = flat_box_site();
  const GripperConfig gripper;
  GraspPlan plan = centred_antipodal_grasp(site.stones[0], gripper, &site.terrain);
  GraspPlan wide = plan;
  wide.opening = max_opening(gripper) + 0.1;
  EXPECT_THROW(run_grasp_trial(site, wide, gripper, fast_config()), InputError);
  GraspPlan skew = plan;
  skew.T_world_gripper.linear()(0, 0) += 0.1;
  EXPECT_THROW(run_grasp_trial(site, skew, gripper, fast_config()), InputError);
  GraspPlan wrong = plan;
  wrong.target_stone = 5;
  EXPECT_THROW(run_grasp_trial(site, wrong, gripper, fast_config()), InputError);
  PhysicsConfig bad = fast_config();
  bad.timestep = 0.0;
  EXPECT_THROW(run_grasp_trial(site, plan, gripper, bad), ConfigError);
  // The set-down: a full share would never end the lowering (the clipped load never falls below 0).
  for (const double share : {0.0, 1.0, std::numeric_limits<double>::quiet_NaN()}) {
    bad = fast_config();
    bad.place_support_fraction = share;
    EXPECT_THROW(run_grasp_trial(site, plan, gripper, bad), ConfigError) << share;
  }
  bad = fast_config();
  bad.place_filter_time = 0.0;
  EXPECT_THROW(run_grasp_trial(site, plan, gripper, bad), ConfigError);
  const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
  for (const double share : {-0.1, 0.95, 0.99, nan}) {  // the touch must come before the set-down (0.95)
    bad = fast_config();
    bad.place_touch_fraction = share;
    EXPECT_THROW(run_grasp_trial(site, plan, gripper, bad), ConfigError) << share;
  }
  for (const double speed : {0.0, -0.05, nan, inf}) {
    bad = fast_config();
    bad.place_touch_speed = speed;
    EXPECT_THROW(run_grasp_trial(site, plan, gripper, bad), ConfigError) << speed;
  }
  for (const double speed : {0.0, -0.1, nan, inf}) {  // the release's back-off
    bad = fast_config();
    bad.release_backoff_speed = speed;
    EXPECT_THROW(run_grasp_trial(site, plan, gripper, bad), ConfigError) << speed;
  }
  for (const double length : {-0.1, nan, inf}) {
    bad = fast_config();
    bad.release_backoff_max = length;
    EXPECT_THROW(run_grasp_trial(site, plan, gripper, bad), ConfigError) << length;
    bad = fast_config();
    bad.release_open_tolerance = length;
    EXPECT_THROW(run_grasp_trial(site, plan, gripper, bad), ConfigError) << length;
  }
}

TEST(Settle, DroppedStoneComesToRestOnTheTerrain) {
  // Gravel terrain with a gentle slope and a flat rock (0.4 m^3, ~1 t) dropped from 0.5 m.
  std::mt19937_64 rng(42);
  Site site;
  site.terrain = Terrain::random(TerrainConfig{.slope_x = 0.03, .slope_y = 0.0, .bump_amplitude = 0.05}, rng);
  Stone s;
  s.mesh = make_stone_mesh(0.4, true, rng);
  double gap0 = INFINITY;  // lift the rock so its lowest point touches the ground
  for (std::size_t i = 0; i < s.mesh.vertices.size(); ++i) {
    const Vector3d p = s.mesh.vertices.world(i);
    gap0 = std::min(gap0, p.z() - site.terrain.height(p.x(), p.y()));
  }
  for (auto& p : s.mesh.vertices.points) p.z() -= static_cast<float>(gap0);
  s.volume = mesh_volume(s.mesh);
  s.centroid = mesh_centroid(s.mesh);
  for (std::size_t i = 0; i < s.mesh.vertices.size(); ++i) s.bounds.extend(s.mesh.vertices.world(i));
  site.stones.push_back(s);

  PhysicsConfig c = fast_config();
  c.settle_time = 5.0;
  Isometry3d start = Isometry3d::Identity();
  start.translation() = Vector3d(0.0, 0.0, 0.5);  // dropped from 0.5 m
  const SettleResult r = settle_stones(site, c, std::span(&start, 1));
  EXPECT_TRUE(r.settled);
  EXPECT_LT(r.max_speed, c.settle_speed);
  EXPECT_LT(r.sim_time, c.settle_time + c.relax_time);
  // Resting on the terrain surface: the lowest point of the moved mesh is within a few cm of
  // the ground (the height field is sampled every 0.2 m here), and it fell, not floated.
  apply_stone_poses(site, r.stone_poses);
  double gap = INFINITY;
  for (std::size_t i = 0; i < site.stones[0].mesh.vertices.size(); ++i) {
    const Vector3d p = site.stones[0].mesh.vertices.world(i);
    gap = std::min(gap, p.z() - site.terrain.height(p.x(), p.y()));
  }
  EXPECT_NEAR(gap, 0.0, 0.04);
  EXPECT_LT(r.stone_poses[0].translation().norm(), 0.5);  // landed near where it was dropped
}

TEST(Settle, ApplyStonePosesMovesMeshCentroidAndBounds) {
  Site site = flat_box_site();
  Isometry3d T = Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(0.5, Vector3d::UnitZ()).toRotationMatrix();
  T.translation() = Vector3d(1.0, 2.0, 0.0);
  const Vector3d c0 = site.stones[0].centroid;
  apply_stone_poses(site, std::span(&T, 1));
  EXPECT_TRUE(site.stones[0].centroid.isApprox(T * c0));
  EXPECT_NEAR(site.stones[0].yaw, 0.5, 1e-12);
  EXPECT_NEAR(mesh_centroid(site.stones[0].mesh).x(), (T * c0).x(), 1e-5);
  EXPECT_TRUE(site.stones[0].bounds.contains(T * c0));
  EXPECT_THROW(apply_stone_poses(site, {}), InputError);
}

}  // namespace
}  // namespace cairn::sim

namespace cairn::sim {
namespace {

/// Per stone: tilt [rad] and displacement [m] when MuJoCo lets the site settle.
std::vector<std::pair<double, double>> settle_motion(const Site& site) {
  const SettleResult r = settle_stones(site, PhysicsConfig{});
  std::vector<std::pair<double, double>> motion;
  for (std::size_t k = 0; k < site.stones.size(); ++k) {
    const Eigen::Isometry3d& T = r.stone_poses[k];
    motion.emplace_back(Eigen::AngleAxisd(T.linear()).angle(), (T * site.stones[k].centroid - site.stones[k].centroid).norm());
  }
  return motion;
}

std::size_t count_still(const std::vector<std::pair<double, double>>& motion) {
  return static_cast<std::size_t>(std::count_if(motion.begin(), motion.end(), [](const auto& m) {
    return m.first < 0.1 && m.second < 0.06;
  }));
}

TEST(Settle, ScenarioStonesRestStably) {
  // The scenarios' generator tips every stone until its centroid lies over its support; MuJoCo
  // then barely moves most of them. Without that step most stones tip by tenths of a radian.
  std::size_t still_on = 0, still_off = 0, total = 0;
  // The path once under the sanitizers (one seed); the figure over both seeds in Release.
  const std::vector<std::uint64_t> seeds = test::kSanitized ? std::vector<std::uint64_t>{1} : std::vector<std::uint64_t>{1, 2};
  for (std::uint64_t seed : seeds) {
    SimulationConfig cfg = scenario_config("exp1", default_real_mesh_dir());
    still_on += count_still(settle_motion(generate_site(cfg.site, seed)));
    cfg.site.stones.settle = false;
    still_off += count_still(settle_motion(generate_site(cfg.site, seed)));
    total += static_cast<std::size_t>(cfg.site.stones.count);
  }
  std::printf("stones that stay put in MuJoCo (< 0.1 rad, < 6 cm): settled %zu / %zu, unsettled %zu / %zu\n",
              still_on, total, still_off, total);
  // Measured: 12 / 14 vs 3 / 14 (seeds 1, 2; 9 vs 1 when written); the rest roll on the slope or
  // off an edge that the quasi-static check took for support (MuJoCo collides with the stones'
  // convex hulls).
  EXPECT_GE(still_on, total / 2);
  if (!test::kSanitized) {
    EXPECT_GE(still_on, still_off + 4);
  }
}

}  // namespace
}  // namespace cairn::sim
