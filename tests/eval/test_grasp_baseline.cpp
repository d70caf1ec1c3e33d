// The centred-grasp baseline (eval/grasp_baseline.hpp): every stone of a settled site gets one
// trial, the parallel run gives what a single trial on the same site gives, the summary counts the
// trials, and a site that cannot be made (a real mesh that cannot be read) is reported, not fatal.
#include "cairn/eval/grasp_baseline.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>
#include <system_error>

#include <unistd.h>

#include "cairn/core/error.hpp"
#include "cairn/sim/simulation.hpp"

namespace cairn::eval {
namespace {

TEST(GraspBaseline, EveryStoneOneTrialAsASingleTrialGivesIt) {
  GraspBaselineConfig c;
  c.scenarios = {"exp1"};
  c.seeds = {1};
  int calls = 0;
  const GraspBaselineResult r = run_grasp_baseline(c, [&](int done, int total) {
    ++calls;
    EXPECT_EQ(total, 7);
    EXPECT_LE(done, total);
  });
  ASSERT_EQ(r.trials.size(), 7u);
  EXPECT_EQ(calls, 7);
  EXPECT_TRUE(r.skipped_sites.empty());
  int successes = 0;
  for (std::size_t k = 0; k < r.trials.size(); ++k) {
    EXPECT_EQ(r.trials[k].stone, static_cast<int>(k));
    EXPECT_GT(r.trials[k].volume, 0.3);
    EXPECT_TRUE(r.trials[k].result.success == r.trials[k].result.failure_reasons.empty());
    successes += r.trials[k].result.success ? 1 : 0;
  }
  EXPECT_EQ(r.summary.trials, 7);
  EXPECT_EQ(r.summary.successes, successes);
  // Stone 0 again, alone: the same site (settled), the same plan, the same outcome.
  sim::SimulationConfig cfg = sim::scenario_config("exp1", sim::default_real_mesh_dir());
  cfg.settle_in_physics = true;
  const sim::Site site = sim::make_site(cfg, 1);
  sim::CentredGraspOptions o;
  o.place_offset = Eigen::Vector2d::Zero();
  o.place_yaw = c.place_yaw;
  GraspPlan plan = sim::centred_antipodal_grasp(site.stones[0], c.gripper, &site.terrain, o);
  plan.target_stone = 0;
  const sim::GraspTrialResult alone = sim::run_grasp_trial(site, plan, c.gripper, c.physics);
  EXPECT_EQ(alone.success, r.trials[0].result.success);
  EXPECT_EQ(alone.failure_reasons, r.trials[0].result.failure_reasons);
  EXPECT_EQ(alone.sim_time, r.trials[0].result.sim_time);
}

/// A folder of its own for one test, removed when the test ends (passed or not).
struct TempDir {
  std::filesystem::path path;
  explicit TempDir(const std::string& name)
      : path(std::filesystem::temp_directory_path() / (name + "_" + std::to_string(::getpid()))) {
    std::filesystem::create_directories(path);
  }
  ~TempDir() {
    std::error_code ignored;
    std::filesystem::remove_all(path, ignored);
  }
};

TEST(GraspBaseline, SitesThatCannotBeMadeAreReported) {
  // A real stone mesh that cannot be read: every site that draws from it is skipped, named.
  const TempDir dir("cairn_baseline_bad_meshes");
  std::ofstream(dir.path / "broken.ply") << "ply\nformat ascii 1.0\nelement vertex 3\nend_header\n0 0\n";
  GraspBaselineConfig c;
  c.scenarios = {"exp2"};
  c.seeds = {8};
  c.mesh_dir = dir.path.string();
  const GraspBaselineResult r = run_grasp_baseline(c);
  EXPECT_TRUE(r.trials.empty());
  ASSERT_EQ(r.skipped_sites.size(), 1u);
  EXPECT_NE(r.skipped_sites[0].find("exp2 seed 8: "), std::string::npos) << r.skipped_sites[0];
  EXPECT_NE(r.skipped_sites[0].find("broken.ply"), std::string::npos) << r.skipped_sites[0];
  c.scenarios = {"nope"};
  EXPECT_THROW((void)run_grasp_baseline(c), ConfigError);
}

}  // namespace
}  // namespace cairn::eval
