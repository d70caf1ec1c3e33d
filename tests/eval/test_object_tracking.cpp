// The object database over moves (eval/object_tracking.hpp, issue #16): a settled exp2 site scanned,
// its objects stored, stones carried, put down and rescanned without a map reset; the database
// scored against the truth in the map's frame. Figures over all rounds and seeds: docs/objects.md.
#include "cairn/eval/object_tracking.hpp"

#include <gtest/gtest.h>

#include <unistd.h>

#include <cstdio>
#include <filesystem>

#include "cairn/eval/tracker.hpp"
#include "cairn/objects/object_db.hpp"
#include "support/test_data.hpp"

namespace cairn::eval {
namespace {

TEST(ObjectTracking, MovedStonesAreFoundAgainAndTheGraspTakesOnlyTheStone) {
  ObjectTrackingConfig c;
  c.scenario = "exp2";
  c.seed = 2;  // exp2 seed 1 does not come to rest with the elliptic cone (docs/simulator-physics.md)
  c.rounds = 1;
  c.simulation = sim::scenario_config("exp2", sim::default_real_mesh_dir());
  c.database = std::filesystem::temp_directory_path() / ("cairn_test_tracking_" + std::to_string(::getpid()) + ".db");
  test::remove_db(c.database);
#if defined(__SANITIZE_ADDRESS__)
  // The same path, short: one move, scans of a few seconds (the figures are asserted in Release).
  c.max_moves_per_round = 1;
  c.initial_scan = 6.0;
  c.rescan = 4.0;
  const bool figures = false;
#else
  c.max_moves_per_round = 3;
  const bool figures = true;
#endif
  const ObjectTrackingResult r = run_object_tracking(c);
  ASSERT_FALSE(r.moves.empty());
  {  // What the run stored: every move's grasp, release and realign in the history, in order.
    const ObjectDatabase db(c.database, ObjectDatabase::Mode::read_only);
    EXPECT_EQ(db.integrity_check(), "ok");
    for (const MoveRecord& m : r.moves) {
      const std::vector<PoseUpdate> h = db.history(m.object);
      ASSERT_GE(h.size(), 4u);
      EXPECT_EQ(h[0].cause, PoseCause::created);
      EXPECT_EQ(h[1].cause, PoseCause::grasp);
      EXPECT_EQ(h[2].cause, PoseCause::release);
      EXPECT_TRUE(h[3].cause == PoseCause::realign || h[3].cause == PoseCause::lost);
      EXPECT_EQ(h[3].cause == PoseCause::lost, !m.found);
    }
  }
  test::remove_db(c.database);
  if (!figures) return;
  EXPECT_GE(r.stones_tracked, 5);  // of 7 (measured 6: one stone is not segmented on its own)
  int found = 0;
  for (const MoveRecord& m : r.moves) {
    std::printf("stone %d: moved %.2f m, settled %.2f m %.1f deg; Eq. 3 %.1f cm %.1f deg -> realigned %.1f cm %.2f deg "
                "(%s); ghosts %.2f %%; carried stone in the map %ld; ground lost sphere %zu / voxels %zu, neighbours %zu / %zu\n",
                m.stone, m.moved_m, m.settle_m, m.settle_deg, 100 * m.predicted_error_m, m.predicted_error_deg,
                100 * m.error_m, m.error_deg, m.reason.c_str(), 100 * m.ghost_share, m.carried_in_map, m.sphere.ground,
                m.object_voxels.ground, m.sphere.neighbours, m.object_voxels.neighbours);
    // The grasp's edit: the object's voxels take the stone's points and at most a fifth of the ground
    // the paper's sphere takes (measured 8-49x less), and no neighbour's when the object is one stone
    // (a segment of two touching stones takes both).
    EXPECT_GT(m.object_voxels.object, 0u);
    EXPECT_GE(m.object_voxels.object, m.sphere.object * 9 / 10);
    EXPECT_LE(5 * m.object_voxels.ground, m.sphere.ground);
    EXPECT_LE(m.object_voxels.neighbours, m.sphere.neighbours);
    if (m.purity > 0.95) {
      EXPECT_EQ(m.object_voxels.neighbours, 0u);
    }
    EXPECT_LT(m.ghost_share, 0.01);
    EXPECT_GE(m.carried_in_map, 0);  // scanned while carrying,
    EXPECT_LE(m.carried_in_map, 10);  // and the carried stone stayed out of the map
    // Never a silent wrong pose: a stone that settled away from where Eq. 3 put it is reported.
    if (m.predicted_error_m > 0.1) {
      EXPECT_FALSE(m.reason.empty());
    }
    if (m.found && m.purity > 0.95) {  // (an object that is two touching stones is not one pose)
      ++found;
      EXPECT_LT(m.error_m, 0.05);  // the 2 cm / 1 deg target is missed (docs/objects.md)
      EXPECT_LT(m.error_deg, 3.0);
      EXPECT_LT(m.error_m, m.predicted_error_m);
    }
  }
  EXPECT_GE(found, 1);
}

TEST(ObjectTracking, TheCarriedStoneStaysOutOfTheMap) {
  // Issue #15 item 2, Sec. 4.5: while the machine carries a stone the sweeps see it in the
  // gripper; attached to the self-filter (the box around the object's database cloud in the
  // gripper frame) it never enters the map, while the arm's own shapes alone let it in as points
  // floating in the air. The first tracked stone of the settled exp2 site of seed 2, lifted by a
  // top-down gripper and scanned for 2 s of the swinging cabin.
#if defined(__SANITIZE_ADDRESS__)
  GTEST_SKIP() << "figures in Release; the path runs under ASan in MovedStonesAreFoundAgain...";
#endif
  long floating[2] = {0, 0};
  for (const bool filter : {true, false}) {
    ObjectTrackingConfig c;
    c.scenario = "exp2";
    c.seed = 2;
    c.simulation = sim::scenario_config("exp2", sim::default_real_mesh_dir());
    c.initial_scan = 16.0;  // one swing
    c.filter_carried = filter;
    Tracker t(c, {}, c.initial_scan + 4.0);
    t.initial_scan();
    t.populate();
    ASSERT_FALSE(t.tracked().empty());
    const Tracker::Tracked& tr = t.tracked().front();
    const Eigen::Isometry3d T_MG = top_down_hold(*t.db().object(tr.object));
    const double t0 = t.machine().now();
    floating[filter ? 0 : 1] = t.scan_while_carrying(tr, t.machine().E_state(t0) * T_MG, T_MG,
                                                     t0, t0 + c.carry_scan);
  }
  std::printf("floating map points added while carrying: %ld with the object attached, %ld without\n", floating[0],
              floating[1]);
  EXPECT_GE(floating[0], 0);     // scanned while carrying
  EXPECT_LE(floating[0], 10);    // measured 1
  EXPECT_GE(floating[1], 500);   // measured 1,706: the test can tell
}

}  // namespace
}  // namespace cairn::eval
