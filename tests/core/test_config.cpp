#include <gtest/gtest.h>

#include <fstream>

#include "cairn/core/config.hpp"
#include "cairn/core/voxel_grid.hpp"
#include "support/test_data.hpp"

using namespace cairn;

namespace {
struct Inner {
  double a = 1.5;
  std::string mode = "grid";
  template <class V>
  void visit(V& v) {
    v("a", a, "a number");
    v("mode", mode, "a string");
  }
};
struct Outer {
  VoxelGridConfig voxel;
  Inner inner;
  bool flag = false;
  std::uint64_t seed = 42;
  template <class V>
  void visit(V& v) {
    v("voxel", voxel, "voxels");
    v("inner", inner, "inner section");
    v("flag", flag, "a flag");
    v("seed", seed, "a seed");
  }
};
}  // namespace

TEST(Config, DefaultsAreTable3) {
  const VoxelGridConfig v;
  EXPECT_DOUBLE_EQ(v.res_voxel, 0.03);
  EXPECT_EQ(v.n_min, 1);
}

TEST(Config, YamlDumpLoadRoundTrip) {
  Outer o;
  o.voxel.res_voxel = 0.05;
  o.inner.mode = "plane";
  o.flag = true;
  o.seed = 7;
  const std::string yaml = config::to_yaml(o);
  EXPECT_NE(yaml.find("# voxel grid resolution"), std::string::npos);  // documented
  Outer back;
  config::apply_yaml(back, YAML::Load(yaml));
  EXPECT_DOUBLE_EQ(back.voxel.res_voxel, 0.05);
  EXPECT_EQ(back.inner.mode, "plane");
  EXPECT_TRUE(back.flag);
  EXPECT_EQ(back.seed, 7u);
  EXPECT_EQ(config::to_json(back), config::to_json(o));
}

TEST(Config, OverridesAndErrors) {
  Outer o;
  config::apply_override(o, "inner.a=2.25");
  config::apply_override(o, "voxel.n_min=3");
  EXPECT_DOUBLE_EQ(o.inner.a, 2.25);
  EXPECT_EQ(o.voxel.n_min, 3);
  EXPECT_THROW(config::apply_override(o, "inner.b=1"), ConfigError);         // unknown key
  EXPECT_THROW(config::apply_override(o, "voxel.n_min=abc"), ConfigError);   // wrong type
  EXPECT_THROW(config::apply_override(o, "novalue"), ConfigError);
  EXPECT_THROW(config::apply_override(o, "inner=3"), ConfigError);           // section, not value
  try {
    config::apply_override(o, "voxel.res_voxl=1");
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("voxel.res_voxl"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("res_voxel"), std::string::npos);  // lists known keys
  }
}

TEST(Config, FileErrorsNameTheFile) {
  Outer o;
  const auto dir = test::temp_dir("config");
  EXPECT_THROW(config::load_yaml_file(o, dir / "missing.yaml"), ConfigError);
  std::ofstream(dir / "bad.yaml") << "voxel: [1, 2\n";
  try {
    config::load_yaml_file(o, dir / "bad.yaml");
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("bad.yaml"), std::string::npos);
  }
  std::ofstream(dir / "ok.yaml") << "inner:\n  a: 9\n";
  config::load_yaml_file(o, dir / "ok.yaml");
  EXPECT_DOUBLE_EQ(o.inner.a, 9.0);
  EXPECT_DOUBLE_EQ(o.voxel.res_voxel, 0.03);  // untouched
}
