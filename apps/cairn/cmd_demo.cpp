// cairn demo: the main job on the built-in simulated site. Today: generate the stone site
// (procedural, 7 stones of 0.5–1 m³), voxelise it as the LiDAR map would be (Table 3), segment
// it (Sec. 4.3) and score the result against the simulator's ground truth. Later stages (LiDAR
// mapping, drone registration, grasping) join this chain as they land.
#include <spdlog/spdlog.h>

#include <fstream>
#include <iostream>

#include "app_config.hpp"
#include "cairn/core/image.hpp"
#include "cairn/core/io/io.hpp"
#include "cairn/segmentation/evaluation.hpp"
#include "cairn/segmentation/output.hpp"
#include "cairn/sim/procedural_site.hpp"
#include "commands.hpp"

namespace cairn::app {
namespace {

constexpr double kTopViewPixelsPerMetre = 60.0;

struct DemoArgs {
  std::string out = "cairn_demo";
  std::uint64_t seed = 1;
  int stones = 7;
  CommonOptions common;
};

int run_demo(const DemoArgs& a) {
  const AppConfig cfg = a.common.load();
  Timings t;
  Stopwatch sw;
  sim::SiteConfig site_cfg;
  site_cfg.stones.count = a.stones;
  spdlog::info("demo [1/4] simulating a {} m × {} m site with {} stones (seed {})", site_cfg.terrain.size_x,
               site_cfg.terrain.size_y, a.stones, a.seed);
  const sim::Site site = sim::generate_site(site_cfg, a.seed);
  const sim::SampledSite sampled = sim::sample_site(site, {}, a.seed);
  t.add("simulate", sw.lap_ms());

  spdlog::info("demo [2/4] voxel map at res_voxel = {} m from {} points", cfg.voxel.res_voxel, sampled.cloud.size());
  const PointCloud map = voxel_downsample(sampled.cloud, cfg.voxel);  // labels: truth by majority
  t.add("voxel_map", sw.lap_ms());

  spdlog::info("demo [3/4] segmenting {} map points", map.size());
  const SegmentationResult seg = segment(map, cfg.segmentation);
  t.add("segmentation", sw.lap_ms());
  seg.timings.log("demo   segmentation:");

  spdlog::info("demo [4/4] scoring against ground truth and writing {}", a.out);
  const SegmentationScore score = score_segmentation(seg.labels, map.labels, int(site.stones.size()));
  write_segmentation(a.out, map, seg, seg.labels);
  io::write_ply(std::filesystem::path(a.out) / "map.ply", map);
  std::vector<Rgb> colors(map.size());
  for (std::size_t i = 0; i < map.size(); ++i) colors[i] = label_color(seg.labels[i]);
  write_png(std::filesystem::path(a.out) / "top_view.png", render_top_view(map, colors, kTopViewPixelsPerMetre));
  t.add("write", sw.lap_ms());

  nlohmann::json summary{{"seed", a.seed},
                         {"stones", site.stones.size()},
                         {"map_points", map.size()},
                         {"segments", seg.num_objects()},
                         {"score", score.to_json()},
                         {"out", a.out}};
  for (const auto& [name, ms] : t.stages) summary["timings_ms"][name] = ms;
  for (const auto& [name, ms] : seg.timings.stages) summary["segmentation_timings_ms"][name] = ms;
  std::ofstream(std::filesystem::path(a.out) / "summary.json") << summary.dump(2) << "\n";
  std::cout << summary.dump(2) << std::endl;
  spdlog::info("demo: {} of {} stones found as single complete segments; picture: {}/top_view.png",
               score.found(), site.stones.size(), a.out);
  return kExitOk;
}

}  // namespace

void add_demo_command(CLI::App& app, std::function<int()>& run) {
  auto args = std::make_shared<DemoArgs>();
  auto* cmd = app.add_subcommand("demo", "Run the main job on the built-in simulated stone site");
  cmd->add_option("--out", args->out, "output directory")->capture_default_str();
  cmd->add_option("--seed", args->seed, "site seed (same seed, same site)")->capture_default_str();
  cmd->add_option("--stones", args->stones, "number of stones")->capture_default_str()->check(CLI::Range(1, 30));
  args->common.add_to(*cmd);
  cmd->callback([&run, args] { run = [args] { return run_demo(*args); }; });
}

}  // namespace cairn::app
