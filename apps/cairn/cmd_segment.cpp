// cairn segment CLOUD --out DIR: Sec. 4.3 segmentation with the file contract of the architecture.
#include <spdlog/spdlog.h>

#include <iostream>

#include "app_config.hpp"
#include "cairn/core/io/io.hpp"
#include "cairn/segmentation/output.hpp"
#include "commands.hpp"

namespace cairn::app {

void add_segment_command(CLI::App& app, std::function<int()>& run) {
  struct Args {
    std::string cloud, out;
    bool drop_invalid = false;
    CommonOptions common;
  };
  auto args = std::make_shared<Args>();
  auto* cmd = app.add_subcommand("segment", "Segment a point cloud into ground and objects (paper Sec. 4.3)");
  cmd->add_option("CLOUD", args->cloud, "input cloud (PLY, PCD, XYZ/TXT, KITTI .bin, VTK, NPY)")->required();
  cmd->add_option("--out", args->out, "output directory (segments.json, labels.txt, segments.ply)")->required();
  cmd->add_flag("--drop-invalid", args->drop_invalid,
                "drop NaN/Inf points instead of failing (they are labelled -2 in labels.txt)");
  args->common.add_to(*cmd);
  cmd->callback([&run, args] {
    run = [args] {
      const AppConfig cfg = args->common.load();
      Stopwatch sw;
      io::ReadOptions ro;
      ro.drop_non_finite = args->drop_invalid;
      const io::ReadResult in = io::read_cloud(args->cloud, ro);
      const double load_ms = sw.lap_ms();
      spdlog::info("segment: read {} points from {} ({:.1f} ms)", in.cloud.size(), args->cloud, load_ms);
      SegmentationResult res = segment(in.cloud, cfg.segmentation);
      res.timings.log("segment:");
      // Labels in input order; dropped invalid points are "no object".
      std::vector<std::int32_t> input_labels = res.labels;
      if (!in.kept_indices.empty()) {
        input_labels.assign(in.num_input, kLabelNone);
        for (std::size_t k = 0; k < in.kept_indices.size(); ++k) input_labels[in.kept_indices[k]] = res.labels[k];
      }
      write_segmentation(args->out, in.cloud, res, input_labels);
      spdlog::info("segment: {} objects, {} ground points; wrote {}", res.num_objects(), res.num_ground, args->out);
      nlohmann::json summary = segments_json(in.cloud, res);
      summary["timings_ms"]["read"] = load_ms;
      std::cout << summary.dump(2) << std::endl;
      return kExitOk;
    };
  });
}

}  // namespace cairn::app
