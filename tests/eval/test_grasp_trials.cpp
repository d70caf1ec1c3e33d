// The grasp test in the physics (eval/grasp_trials.hpp): invariants of the pipeline on one site
// (every stone planned from the sensed map, executed, with the baseline on the same stones), and
// the Wilson interval. The success rates themselves are measured by `cairn grasp-trials` on many
// seeds (docs/grasp.md), not asserted here.
#include <gtest/gtest.h>

#include "cairn/core/error.hpp"
#include "cairn/eval/grasp_trials.hpp"

namespace cairn::eval {
namespace {

TEST(WilsonInterval, MatchesTheClosedForm) {
  const auto [lo, hi] = wilson_interval(88, 100);  // p = 0.88
  EXPECT_NEAR(lo, 0.8024, 1e-3);
  EXPECT_NEAR(hi, 0.9301, 1e-3);
  const auto [lo0, hi0] = wilson_interval(0, 10);
  EXPECT_DOUBLE_EQ(lo0, 0.0);
  EXPECT_NEAR(hi0, 0.2775, 1e-3);
  EXPECT_DOUBLE_EQ(wilson_interval(0, 0).second, 1.0);
}

TEST(GraspTrials, EveryStoneIsPlannedFromTheSensedMapAndExecutedWithTheBaseline) {
  GraspTrialsConfig c;
  c.scenarios = {"exp1"};
  c.seeds = {1};
  c.study = 1;  // one more force-closure grasp per stone, executed too (diagnostic)
#if defined(__SANITIZE_ADDRESS__)
  c.scan_time = 8.0;  // one path under the sanitizers, a short scan
  c.grasp.candidates.samples = 20;
  c.baseline = false;  // the centred grasp's path (centred_antipodal_grasp, run_grasp_trial): GraspBaseline
#endif
  const GraspTrialsResult r = run_grasp_trials(c);
  ASSERT_EQ(r.trials.size(), 7u);
  int segmented = 0;
  std::size_t studied = 0;
  for (const PlannedGraspTrial& t : r.trials) {
    if (!t.segmented) continue;
    ++segmented;
    EXPECT_GT(t.purity, 0.5);
    EXPECT_GT(t.planning_ms, 0.0);
    if (t.planned) {
      EXPECT_EQ(t.plan.target_stone, t.stone);
      EXPECT_TRUE(t.best.force_closure);
      EXPECT_GT(t.result.sim_time, 0.0);
      EXPECT_TRUE(t.result.success || !t.result.failure_reasons.empty());  // every failure has a reason
    }
    if (c.baseline) {
      EXPECT_GT(t.baseline.sim_time, 0.0);
    }
    ASSERT_EQ(t.study_grasps.size(), t.study_results.size());
    EXPECT_LE(t.study_grasps.size(), 1u);
    studied += t.study_grasps.size();
    for (std::size_t j = 0; j < t.study_grasps.size(); ++j) {
      EXPECT_TRUE(t.study_grasps[j].force_closure);
      EXPECT_GT(t.study_results[j].sim_time, 0.0);
      EXPECT_TRUE(t.study_results[j].success || !t.study_results[j].failure_reasons.empty());
    }
  }
  const nlohmann::json j = to_json(r);
  for (std::size_t k = 0; k < r.trials.size(); ++k)
    EXPECT_EQ(j["trials"][k].contains("study"), !r.trials[k].study_grasps.empty());
  EXPECT_GE(segmented, 5);
  EXPECT_GT(studied, 0u);
  EXPECT_EQ(r.planned.trials, segmented);
  EXPECT_EQ(r.planned_flat.trials + r.planned_roundish.trials, r.planned.trials);
  EXPECT_EQ(r.baseline.trials, c.baseline ? segmented : 0);
  EXPECT_LE(r.planned.wilson_low, double(r.planned.successes) / r.planned.trials);
  GraspTrialsConfig bad;
  bad.source = "lidar";
  EXPECT_THROW((void)run_grasp_trials(bad), ConfigError);
}

}  // namespace
}  // namespace cairn::eval
