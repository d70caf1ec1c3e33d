// The paper's experiments end to end (eval/experiment.hpp, issue #18): the failed-grasp detector
// on hand-made traces, and a short experiment 1 on the simulated machine — the drone cloud
// registered while scanning, the database filled, every stone planned, grasped in the physics,
// carried and placed; each attempt's detection (the machine's signals only) against the physics'
// truth, with an injected low-friction grasp detected and followed by a second attempt.
// Figures over many seeds: docs/experiments.md.
#include "cairn/eval/experiment.hpp"

#include <gtest/gtest.h>

#include <algorithm>

#include <unistd.h>

#include <cstdio>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numbers>
#include <set>

#include "cairn/core/error.hpp"
#include "cairn/objects/object_db.hpp"
#include "cairn/report/report.hpp"
#include "support/browser.hpp"
#include "support/test_data.hpp"

namespace cairn::eval {
namespace {

/// A trial trace: closing until t = 1, lifting to 2, holding to 2.5, moving to 5, holding to
/// 5.5, lowering from 5.5; `load(t)` and `opening(t)` give the signals.
template <class L, class O>
sim::GraspTrialResult trial(L load, O opening, bool lifted = true) {
  sim::GraspTrialResult r;
  r.phases = {{"approach", 0.0, 0.5}, {"close", 0.5, 1.0}};
  if (lifted)
    r.phases.insert(r.phases.end(), {{"lift", 1.0, 2.0}, {"hold", 2.0, 2.5}, {"move", 2.5, 5.0}, {"hold", 5.0, 5.5},
                                     {"place", 5.5, 6.0}, {"release", 6.0, 7.0}});
  else
    r.phases.push_back({"release", 1.0, 2.0});
  for (double t = 0.0; t <= 7.0; t += 0.02) r.trace.push_back({.time = t, .opening = opening(t), .arm_load = load(t)});
  return r;
}

TEST(GraspDetection, AHeldStoneIsNoFailure) {
  const auto d = detect_grasp_failure(
      trial([](double t) { return t > 1.2 && t < 6.0 ? 20000.0 : 0.0; }, [](double) { return 0.8; }), {});
  EXPECT_FALSE(d.failed);
  EXPECT_TRUE(d.held_at_release);
  EXPECT_NEAR(d.lifted_load, 20000.0, 1e-6);
  EXPECT_NEAR(d.jaw_travel, 0.0, 1e-12);
}

TEST(GraspDetection, LoadDropJawTravelAndEmptyLiftsAreFailures) {
  const SlipDetectionConfig c;
  // Dropped while moving: the load falls to nothing before lowering.
  const auto dropped = detect_grasp_failure(
      trial([](double t) { return t > 1.2 && t < 3.5 ? 20000.0 : 0.0; }, [](double) { return 0.8; }), c);
  EXPECT_TRUE(dropped.failed);
  EXPECT_FALSE(dropped.held_at_release);
  EXPECT_EQ(dropped.signs, std::vector<std::string>{"load_dropped"});
  // Slipping: the jaws close 5 cm further while the load stays.
  const auto slipped = detect_grasp_failure(
      trial([](double t) { return t > 1.2 && t < 6.0 ? 20000.0 : 0.0; }, [](double t) { return t < 2.0 ? 0.8 : 0.75; }),
      c);
  EXPECT_EQ(slipped.signs, std::vector<std::string>{"jaws_closed_further"});
  EXPECT_NEAR(slipped.jaw_travel, 0.05, 1e-9);
  EXPECT_TRUE(slipped.held_at_release);
  // Nothing lifted: the load after the lift stays below min_load.
  const auto empty = detect_grasp_failure(trial([](double) { return 50.0; }, [](double) { return 0.3; }), c);
  EXPECT_EQ(empty.signs, std::vector<std::string>{"nothing_lifted"});
  // Stopped before the lift (contact on the approach): no hold phase at all.
  const auto stopped = detect_grasp_failure(trial([](double) { return 0.0; }, [](double) { return 1.0; }, false), c);
  EXPECT_EQ(stopped.signs, std::vector<std::string>{"not_lifted"});
}

// The machine's at-target check carries the planned centre of mass with the object's stored
// motion, rotation included: a stone turned in the jaws about its grip is not where a translation
// of its centre would put it.
TEST(TargetCheck, TheEstimatedCentreIsCarriedByTheStoredMotionAndALostObjectIsNeverAtItsTarget) {
  const SlipDetectionConfig c;  // target_tolerance 0.10 m
  const Vec3d centre(2.0, 1.0, 0.5), grip(2.3, 1.0, 1.0);
  // Grasped at the grip, turned 90 degrees about the vertical there, carried 3 m along x.
  const Eigen::Isometry3d moved = Eigen::Translation3d(3.0, -1.0, 0.0) * Eigen::Translation3d(grip) *
                                  Eigen::AngleAxisd(0.5 * std::numbers::pi, Vec3d::UnitZ()) *
                                  Eigen::Translation3d(-grip);
  const Eigen::Vector2d landed = (moved * centre).head<2>();
  EXPECT_TRUE(seen_at_target(ObjectStatus::placed, moved, centre, landed, c));
  EXPECT_TRUE(seen_at_target(ObjectStatus::placed, moved, centre, landed + Eigen::Vector2d(0.0, 0.09), c));
  EXPECT_FALSE(seen_at_target(ObjectStatus::placed, moved, centre, landed + Eigen::Vector2d(0.0, 0.11), c));
  // Where the translation alone would put the centre: 0.42 m off after the turn.
  const Eigen::Vector2d translated = centre.head<2>() + Eigen::Vector2d(3.0, -1.0);
  EXPECT_NEAR((translated - landed).norm(), std::hypot(0.3, 0.3), 1e-12);
  EXPECT_FALSE(seen_at_target(ObjectStatus::placed, moved, centre, translated, c));
  // Lost: the re-alignment did not find it, whatever the stored motion says.
  EXPECT_FALSE(seen_at_target(ObjectStatus::lost, moved, centre, landed, c));
}

// Sec. 6.1's places on exp1's layout (swing axis at x = -6 facing +x, R_map = 10 m): the row
// 8 m out holds the places whose centre lies in the map (y = 0, +-1.7, +-3.4, +-5.1 — not the
// +-6.8 and +-8.5 the row offered before, 10.5 and 11.7 m from the axis, which the rescans never
// saw: stones placed there were lost), then the rows 1.7 m nearer, down to row_min_distance,
// then the rows farther out.
TEST(Targets, EveryPlaceLiesInTheMapRowByRowFromTheMiddleOutwards) {
  ExperimentConfig c;
  const Eigen::Vector2d axis(-6.0, 0.0);
  const double R = c.tracking.mapping.local_map.R_map;
  const std::vector<Eigen::Vector2d> places = target_places(axis, 0.0, c.row_distance, 7, c);
  ASSERT_GE(places.size(), 7u);
  const std::vector<double> first_row = {0.0, -1.7, 1.7, -3.4, 3.4, -5.1, 5.1};
  for (std::size_t i = 0; i < first_row.size(); ++i) {
    EXPECT_NEAR(places[i].x(), 2.0, 1e-9) << i;
    EXPECT_NEAR(places[i].y(), first_row[i], 1e-9) << i;
  }
  // The rows in the order offered, each place once.
  const auto rows_of = [&](const std::vector<Eigen::Vector2d>& ps) {
    std::vector<long> rows;
    for (std::size_t i = 0; i < ps.size(); ++i) {
      EXPECT_LE((ps[i] - axis).norm(), R + 1e-9) << i;
      const long row = std::lround(10.0 * (ps[i].x() - axis.x()));
      if (rows.empty() || rows.back() != row) rows.push_back(row);
      for (std::size_t j = 0; j < i; ++j) EXPECT_GE((ps[i] - ps[j]).norm(), c.row_spacing - 1e-9);
    }
    return rows;
  };
  // 2.9 m < row_min_distance: no fourth row nearer; none farther: at 9.7 m a stone reaching half
  // a spacing (0.85 m) would not fit in the map even at the row's middle (9.7 + 0.85 + 0.2 > 10).
  EXPECT_EQ(rows_of(places), (std::vector<long>{80, 63, 46}));
  // exp2's even rounds (4.5 m, the nearest row already): spares outwards, where the odd rounds'
  // stones wait (before: the 4.5 m row alone, which the odd rounds' 4.6 m spares overlap); 9.6 m
  // is too far out for the same reason.
  const auto even_round = target_places(axis, 0.0, c.row_distance_even, 7, c);
  EXPECT_EQ(rows_of(even_round), (std::vector<long>{45, 62, 79}));
  // The farthest row holds places that a stone of 1.2 m reach fits (y = 0 and +-1.7 at 7.9 m).
  for (const double y : {0.0, -1.7, 1.7}) {
    const Eigen::Vector2d p = axis + Eigen::Vector2d(7.9, y);
    EXPECT_EQ(std::count_if(even_round.begin(), even_round.end(), [&](const auto& q) { return (q - p).norm() < 1e-9; }), 1) << y;
    EXPECT_TRUE(place_in_map(p, 1.2, axis, c)) << y;
  }
  // A stone's footprint must fit too: 0.6 m reach and 0.2 m clearance fit at y = 3.4 (8.7 m
  // from the axis), not at y = 5.1 (9.5 m).
  EXPECT_TRUE(place_in_map({2.0, 3.4}, 0.6, axis, c));
  EXPECT_FALSE(place_in_map({2.0, 5.1}, 0.6, axis, c));
  // An even count centres the row; a turned heading turns it about the axis.
  const auto even = target_places(axis, 0.0, c.row_distance, 6, c);
  ASSERT_GE(even.size(), 4u);
  EXPECT_NEAR(even[0].y(), 0.85, 1e-9);
  EXPECT_NEAR(even[1].y(), -0.85, 1e-9);
  EXPECT_NEAR(even[2].y() + even[3].y(), 0.0, 1e-9);
  EXPECT_NEAR(std::abs(even[2].y()), 2.55, 1e-9);
  const auto turned = target_places(axis, std::numbers::pi / 2, c.row_distance, 7, c);
  ASSERT_EQ(turned.size(), places.size());
  for (std::size_t i = 0; i < places.size(); ++i) {
    EXPECT_NEAR(turned[i].x() - axis.x(), -(places[i].y() - axis.y()), 1e-9);
    EXPECT_NEAR(turned[i].y() - axis.y(), places[i].x() - axis.x(), 1e-9);
  }
  // A row farther out than the map offers nothing of its own: the nearer rows still do.
  EXPECT_FALSE(target_places(axis, 0.0, 11.0, 7, c).empty());
  c.row_min_distance = 12.0;
  EXPECT_TRUE(target_places(axis, 0.0, 11.0, 7, c).empty());
  for (const double bad : {0.0, -1.0, std::nan(""), std::numeric_limits<double>::infinity()}) {
    ExperimentConfig b;
    b.row_min_distance = bad;
    EXPECT_THROW((void)run_experiment(b), ConfigError) << bad;
    EXPECT_THROW((void)target_places(axis, 0.0, 8.0, 7, b), ConfigError) << bad;
    b = ExperimentConfig{};
    b.row_spacing = bad;
    EXPECT_THROW((void)target_places(axis, 0.0, 8.0, 7, b), ConfigError) << bad;
    b = ExperimentConfig{};
    b.tracking.mapping.local_map.R_map = bad;
    EXPECT_THROW((void)target_places(axis, 0.0, 8.0, 7, b), ConfigError) << bad;
  }
}

// A place is free for a stone when the other objects' points lie beyond its reach about its
// centroid plus the clearance: a long stone (3 m x 0.4 m) reaches 1.51 m however it is turned
// about the vertical, where half its bounding box's diagonal grows from 1.51 m to 1.70 m when it
// is turned 45 deg; the gap is to the nearest point, not to a bounding box that an L-shaped
// neighbour's empty corner inflates.
TEST(Targets, AStoneReachesItsFarthestPointAndTheGapIsToTheNearestPoint) {
  PointCloud bar;
  bar.origin = {10.0, 20.0, 1.0};
  for (int i = 0; i <= 30; ++i)
    for (const float w : {-0.2f, 0.2f}) bar.points.emplace_back(float(-1.5 + 0.1 * i), w, 0.3f * float(i % 2));
  const Eigen::Vector3d centre = bar.origin;
  EXPECT_NEAR(xy_reach(bar, centre), std::hypot(1.5, 0.2), 1e-6);
  EXPECT_NEAR(xy_reach(bar, centre + Eigen::Vector3d(0.5, 0.0, 0.0)), std::hypot(2.0, 0.2), 1e-6);
  EXPECT_EQ(xy_reach(PointCloud{}, centre), 0.0);
  PointCloud ell;  // an L: one arm along x, one along y, its bounding box's corner at (11, 11) empty
  for (int i = 0; i <= 10; ++i) {
    ell.points.emplace_back(float(0.1 * i), 0.0f, 0.0f);
    ell.points.emplace_back(0.0f, float(0.1 * i), 0.0f);
  }
  ell.origin = {10.0, 10.0, 0.0};
  EXPECT_NEAR(xy_gap(ell, {11.0, 11.0}), 1.0, 1e-6);
  EXPECT_NEAR(xy_gap(ell, {10.5, 9.0}), 1.0, 1e-6);
  EXPECT_NEAR(xy_gap(ell, {10.0, 10.0}), 0.0, 1e-9);
  EXPECT_TRUE(std::isinf(xy_gap(PointCloud{}, {0.0, 0.0})));
  // A place 1.0 m from the L's nearest point: free for a stone of 0.7 m reach (+ 0.2 m clearance),
  // not for one of 0.85 m (the gap must exceed reach + clearance); the stone itself and lost
  // objects never block.
  const ExperimentConfig c;
  ObjectRecord neighbour{.id = 2, .cloud = ell};
  const Eigen::Vector2d place(10.5, 9.0);
  EXPECT_TRUE(place_is_free(place, 0.7, 1, {neighbour}, c));
  EXPECT_FALSE(place_is_free(place, 0.85, 1, {neighbour}, c));
  EXPECT_TRUE(place_is_free(place, 0.85, 2, {neighbour}, c));
  neighbour.status = ObjectStatus::lost;
  EXPECT_TRUE(place_is_free(place, 0.85, 1, {neighbour}, c));
  EXPECT_TRUE(place_is_free(place, 5.0, 1, {}, c));
}

std::filesystem::path fresh_db(const std::string& name) {
  const auto f = std::filesystem::temp_directory_path() / (name + "_" + std::to_string(::getpid()) + ".db");
  test::remove_db(f);
  return f;
}

ExperimentConfig short_exp1(int stones, const std::string& db) {
  ExperimentConfig c;
  c.experiment = "exp1";
  c.tracking.scenario = "exp1";
  c.tracking.seed = 1;
  c.tracking.simulation = sim::scenario_config("exp1", sim::default_real_mesh_dir());
  c.tracking.simulation.site.stones.count = stones;
  c.tracking.database = fresh_db(db);
#if defined(__SANITIZE_ADDRESS__)
  c.tracking.simulation.site.stones.count = 1;  // the same path, short (figures asserted in Release)
  c.tracking.initial_scan = 6.0;
  c.tracking.rescan = 4.0;
  c.registration_period = c.registration_timeout = 10.0;  // one attempt; 10 s of scanning: the stone is seen
  c.max_attempts = 1;
#endif
  return c;
}

TEST(Experiment, Exp1RegistersPlansGraspsAndDetectsEveryFailure) {
  ExperimentConfig c = short_exp1(3, "cairn_test_experiment");
  c.inject_friction = 0.02;  // the first grasp cannot hold its stone: detected, then tried again
  c.inject_move = 1;
  c.trials_dir = test::temp_dir("experiment_trials");
  const ExperimentResult r = run_experiment(c);
  for (const std::string& n : r.notes) std::printf("note: %s\n", n.c_str());
  const nlohmann::json j = to_json(r);
  for (const char* key : {"experiment", "seed", "registration", "grasps", "rounds", "timings_ms"})
    EXPECT_TRUE(j.contains(key)) << key;
  // Every physics trial written beside the summary, with its placement's truth; a stone held
  // to its target was weighed (placing by weight, the default).
  for (const GraspRecord& g : r.grasps) {
    if (g.failure_reasons == std::vector<std::string>{"no_grasp"}) continue;
    const auto file = c.trials_dir / trial_file_name(g);
    std::ifstream in(file);
    ASSERT_TRUE(in.good()) << file;
    const nlohmann::json trial = nlohmann::json::parse(in);
    if (g.success) {
      EXPECT_FALSE(trial.at("placement").at("weighed_com").is_null()) << file;
      EXPECT_GE(g.place_correction_m, 0.0) << file;
    }
  }
  std::printf("timings [ms]: %s\n", j.at("timings_ms").dump().c_str());
  ASSERT_EQ(r.rounds.size(), 1u);
  ASSERT_FALSE(r.grasps.empty());
  {
    const ObjectDatabase db(c.tracking.database, ObjectDatabase::Mode::read_only);
    EXPECT_EQ(db.integrity_check(), "ok");
  }
  test::remove_db(c.tracking.database);
  // The report of this run (issue #18 item 4): every instant captured, and it opens.
  ASSERT_EQ(r.scene.snapshots.size(), 2u + (c.tracking.simulation.site.stones.count > 2 ? 1u : 0u));  // before, move 2, round 1
  EXPECT_FALSE(r.scene.trajectory.empty());
  const auto dir = std::filesystem::temp_directory_path() / ("cairn_test_experiment_report_" + std::to_string(::getpid()));
  const report::ReportFiles files = report::write_report(dir, r);
  test::expect_report_opens(files.html, dir / "screenshot.png");
  std::filesystem::remove_all(dir);
  const GraspRecord& first = r.grasps.front();  // the injected one
  EXPECT_FALSE(first.success);
  EXPECT_TRUE(first.detected);
#if !defined(__SANITIZE_ADDRESS__)
  ASSERT_GE(r.grasps.size(), 2u);  // the machine noticed and planned again
  EXPECT_EQ(r.grasps[1].attempt, 2);
  EXPECT_EQ(r.grasps[1].stone, first.stone);
  EXPECT_EQ(r.stones, 3);
  EXPECT_EQ(r.stones_tracked, 3);
  // Registration (Sec. 6.2): accepted at the first triggers, close to the truth in the map's frame.
  EXPECT_TRUE(r.registration.success);
  EXPECT_LE(r.registration.first_success_s, 10.0);
  EXPECT_LT(r.registration.rotation_error_deg, 0.5);
  EXPECT_LT(r.registration.translation_error_m, 0.05);
  // Every failed attempt: the machine's verdict (jaw trace, arm load, rescan) saw it.
  for (const GraspRecord& g : r.grasps) {
    const bool failed = !g.success || !(g.target_error_m >= 0 && g.target_error_m <= c.detection.target_tolerance);
    std::printf("stone %d attempt %d: truth %s (%zu reasons), detected %d, target error %.2f m, planning %.0f ms\n",
                g.stone, g.attempt, failed ? "failed" : "ok", g.failure_reasons.size(), g.detected, g.target_error_m,
                g.planning_ms);
    if (failed) {
      EXPECT_TRUE(g.detected) << "stone " << g.stone << " attempt " << g.attempt;
    }
  }
  EXPECT_EQ(r.failures, r.failures_detected);  // every failure seen by the machine
  // False alarms (the rescan's check of the target, 10 cm, is coarser than the placement) are
  // measured, not yet ruled out: 1 in this run; the "no false alarm" is missed
  // (docs/experiments.md).
  std::printf("%d failed attempts, %d detected, %d false alarms\n", r.failures, r.failures_detected, r.false_alarms);
#endif
}

// Clearing a pile (issue #21 item 4): every stone of a small pile picked in the machine's order
// (none another object rests on), the map re-segmented after every move, the pile's shifts
// counted from the truth. How many stones reach the row is measured over seeds in
// docs/experiments.md (missed: the grasps of issue #17), not asserted here.
TEST(Experiment, PileIsClearedOneStoneAtATimeReSegmentingAfterEveryMove) {
  ExperimentConfig c;
  c.experiment = c.tracking.scenario = "pile";
  c.tracking.seed = 1;
  c.tracking.simulation = sim::scenario_config("pile", sim::default_real_mesh_dir());
  c.tracking.simulation.site.stones.count = 3;
  c.tracking.database = fresh_db("cairn_test_pile");
  c.max_attempts = 1;
#if defined(__SANITIZE_ADDRESS__)
  c.tracking.simulation.site.stones.count = 2;  // the same path, short
  c.tracking.initial_scan = 6.0;
  c.tracking.rescan = 4.0;
  c.registration_timeout = c.registration_period;  // one attempt: 6 s of scanning before the database is filled
#endif
  const ExperimentResult r = run_experiment(c);
  test::remove_db(c.tracking.database);
  for (const std::string& n : r.notes) std::printf("note: %s\n", n.c_str());
  const int stones = c.tracking.simulation.site.stones.count;
  EXPECT_EQ(r.stones, stones);
  EXPECT_GE(r.stones_tracked, stones - 1);  // at most one pair still merged at the end
  ASSERT_EQ(r.rounds.size(), 1u);
  // Every tracked stone picked once (one attempt each) unless the machine reports why not (no
  // free place in the row for it, or lost), the map re-segmented before each next pick and once
  // more to see that nothing is left.
  const auto skipped = int(std::count_if(r.notes.begin(), r.notes.end(), [](const std::string& n) {
    return n.find("no free place") != std::string::npos || n.find("is lost") != std::string::npos;
  }));
  EXPECT_LE(skipped, 1);
  EXPECT_EQ(r.moves + skipped, r.stones_tracked);
  EXPECT_EQ(int(r.grasps.size()), r.moves);
  EXPECT_EQ(r.resegmentations, r.moves + skipped);
  std::set<int> picked;
  int shifts = 0;
  for (const GraspRecord& g : r.grasps) {
    EXPECT_TRUE(picked.insert(g.stone).second) << "stone " << g.stone << " picked twice";
    EXPECT_GE(g.others_moved_m, 0.0);
    EXPECT_EQ(g.others_loaded, 0) << "a stone other objects rest on went while a free one was left";
    shifts += g.others_moved_m > c.pile_shift;
    std::printf("stone %d: %s, target error %.2f m, the pile moved %.3f m\n", g.stone,
                g.success ? "held" : "failed", g.target_error_m, g.others_moved_m);
  }
  EXPECT_EQ(r.pile_shifts, shifts);
  const nlohmann::json j = to_json(r);
  std::printf("timings [ms]: %s\n", j.at("timings_ms").dump().c_str());
  EXPECT_EQ(j.at("summary").at("pile_shifts").get<int>(), r.pile_shifts);
  EXPECT_EQ(j.at("summary").at("resegmentations").get<int>(), r.resegmentations);
  EXPECT_TRUE(j.at("grasps").at(0).contains("others_moved_m"));
  std::printf("pile of %d: %d moves, %d placed, %d pile shifts\n", stones, r.moves, r.placed, r.pile_shifts);
}

TEST(Experiment, APileHasOneRound) {
  ExperimentConfig c;
  c.experiment = "pile";
  c.rounds = 2;
  EXPECT_THROW((void)run_experiment(c), ConfigError);
  c.rounds = 1;
  c.pile_shift = 0.0;
  EXPECT_THROW((void)run_experiment(c), ConfigError);
}

}  // namespace
}  // namespace cairn::eval
