// The feature configs are visitable: documented keys, YAML round trip, Table 3 defaults.
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include "cairn/core/config.hpp"
#include "cairn/features/iss.hpp"
#include "cairn/features/matching.hpp"
#include "cairn/features/shot.hpp"
#include "cairn/registration/consistency_grouping.hpp"

using namespace cairn;

TEST(FeatureConfig, DefaultsAreTable3) {
  EXPECT_DOUBLE_EQ(IssConfig{}.salient_radius, 0.06);  // R_iss
  EXPECT_DOUBLE_EQ(ShotConfig{}.radius, 0.10);         // R_shot
  EXPECT_EQ(GroupingConfig{}.max_candidates, 10);      // b
  EXPECT_DOUBLE_EQ(MatchConfig{}.max_squared_distance, 0.25);
}

TEST(FeatureConfig, YamlRoundTripAndUnknownKeys) {
  const std::string iss = config::to_yaml(IssConfig{});
  for (const char* key : {"salient_radius", "non_max_radius", "gamma_21", "gamma_32", "min_neighbors"})
    EXPECT_NE(iss.find(key), std::string::npos) << key;
  const std::string grouping = config::to_yaml(GroupingConfig{});
  for (const char* key : {"consensus_size", "min_votes", "max_candidates", "refine"})
    EXPECT_NE(grouping.find(key), std::string::npos) << key;
  EXPECT_NE(config::to_yaml(ShotConfig{}).find("radius"), std::string::npos);
  EXPECT_NE(config::to_yaml(MatchConfig{}).find("search"), std::string::npos);

  GroupingConfig g;
  config::apply_yaml(g, YAML::Load("{consensus_size: 0.02, max_candidates: 3, refine: false}"));
  EXPECT_DOUBLE_EQ(g.consensus_size, 0.02);
  EXPECT_EQ(g.max_candidates, 3);
  EXPECT_FALSE(g.refine);
  MatchConfig m;
  config::apply_yaml(m, YAML::Load("{mutual: true, search: kdtree}"));
  EXPECT_TRUE(m.mutual);
  EXPECT_EQ(m.search, "kdtree");
  IssConfig i;
  EXPECT_THROW(config::apply_yaml(i, YAML::Load("{salient_radus: 0.1}")), ConfigError);
}
