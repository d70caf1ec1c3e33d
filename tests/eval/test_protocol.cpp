// The registration protocol's scoring (cairn/eval/protocol.hpp) on hand-made trials; the whole
// protocol on a simulated site runs in the CLI test (Cli.ProtocolRegistersWhileMapping).
#include <gtest/gtest.h>

#include "cairn/core/error.hpp"
#include "cairn/eval/protocol.hpp"

namespace cairn::eval {
namespace {

ProtocolTrial trial(double time, bool accepted, bool single, double rot_deg, double trans_m, double ms) {
  ProtocolTrial t;
  t.time = time;
  t.map_points = 1000;
  t.score.accepted = accepted;
  t.score.every_stone_single = single;
  t.score.success = accepted && single;
  t.score.error = {.rotation_deg = rot_deg, .translation_m = trans_m};
  t.error_vs_map = {.rotation_deg = rot_deg / 2, .translation_m = trans_m / 2};
  t.ms = ms;
  return t;
}

TEST(Protocol, SummaryCountsSuccessesFalsePositivesAndErrorsFromATime) {
  const std::vector<ProtocolTrial> trials = {
      trial(5.0, false, false, 0.0, 0.0, 100.0),  // refused
      trial(10.0, true, true, 0.10, 0.010, 200.0),
      trial(15.0, true, true, 0.30, 0.030, 300.0),
      trial(20.0, true, false, 0.20, 0.020, 400.0),  // accepted, a stone split: no success
      trial(25.0, true, true, 5.00, 0.500, 500.0),   // accepted far off: a success by the test, a false positive
  };
  const nlohmann::json all = summarise_trials(trials, 0.0);
  EXPECT_EQ(all["trials"].get<int>(), 5);
  EXPECT_EQ(all["success"].get<int>(), 3);
  EXPECT_EQ(all["accepted"].get<int>(), 4);
  EXPECT_EQ(all["false_positives"].get<int>(), 1);
  EXPECT_DOUBLE_EQ(all["success_rate"].get<double>(), 0.6);
  EXPECT_DOUBLE_EQ(all["rotation_error_deg"]["median"].get<double>(), 0.30);  // of the successes 0.1, 0.3, 5
  EXPECT_DOUBLE_EQ(all["rotation_error_deg"]["max"].get<double>(), 5.0);
  EXPECT_DOUBLE_EQ(all["translation_error_vs_map_m"]["median"].get<double>(), 0.015);
  EXPECT_DOUBLE_EQ(all["registration_ms_median"].get<double>(), 300.0);
  const nlohmann::json late = summarise_trials(trials, 15.0);
  EXPECT_EQ(late["trials"].get<int>(), 3);
  EXPECT_EQ(late["success"].get<int>(), 2);
  EXPECT_DOUBLE_EQ(late["rotation_error_deg"]["median"].get<double>(), 2.65);  // 0.3 and 5
  EXPECT_DOUBLE_EQ(late["registration_ms_median"].get<double>(), 400.0);
  const nlohmann::json none = summarise_trials(trials, 30.0);
  EXPECT_EQ(none["trials"].get<int>(), 0);
  EXPECT_DOUBLE_EQ(none["success_rate"].get<double>(), 0.0);
}

TEST(Protocol, SummaryOfSeedsAndTheAcceptanceStudy) {
  ProtocolResult r;
  r.config.seeds = 3;
  r.stones = 7;
  r.per_seed = 1;
  r.trials = {trial(5.0, true, true, 0.1, 0.01, 100.0), trial(5.0, false, false, 0, 0, 100.0),
              trial(5.0, true, true, 0.1, 0.01, 100.0)};
  r.trials[0].refined = {{.rmse = 0.01, .overlap = 0.6, .right = true, .accepted = true},
                         {.rmse = 0.05, .overlap = 0.2, .right = false, .accepted = false}};
  r.wrong_site = {{.rmse = 0.04, .overlap = 0.3, .right = false, .accepted = true}};
  r.first_success = {5.0, std::nullopt, 15.0};
  const nlohmann::json s = protocol_summary(r, "grid.png", "acceptance.png");
  EXPECT_EQ(s["seeds_without_success"].get<int>(), 1);
  EXPECT_TRUE(s["time_to_first_success_s"][1].is_null());
  EXPECT_DOUBLE_EQ(s["time_to_first_success_median_s"].get<double>(), 10.0);
  const nlohmann::json& a = s["acceptance_study"];
  EXPECT_EQ(a["right"]["refined"].get<int>(), 1);
  EXPECT_EQ(a["wrong"]["refined"].get<int>(), 2);
  EXPECT_EQ(a["wrong"]["accepted"].get<int>(), 1);
  EXPECT_EQ(a["wrong_site_accepted"].get<int>(), 1);
  EXPECT_DOUBLE_EQ(a["wrong"]["rmse_m"]["max"].get<double>(), 0.05);
  EXPECT_EQ(a["picture"].get<std::string>(), "acceptance.png");
  EXPECT_TRUE(acceptance_study(ProtocolResult{})["right"]["rmse_m"].is_null());  // nothing refined
}

TEST(Protocol, RejectsBadSettings) {
  EXPECT_NO_THROW(validate(ProtocolConfig{}));
  EXPECT_THROW(validate(ProtocolConfig{.seeds = 0}), InputError);
  EXPECT_THROW(validate(ProtocolConfig{.duration = 5.0, .every = 6.0}), InputError);
  EXPECT_THROW(validate(ProtocolConfig{.every = 0.0}), InputError);
  EXPECT_THROW(validate(ProtocolConfig{.duration = std::numeric_limits<double>::quiet_NaN()}), InputError);
}

}  // namespace
}  // namespace cairn::eval
