// cairn info CLOUD: what a point-cloud file holds.
#include <iostream>

#include "app_config.hpp"
#include "cairn/core/io/io.hpp"
#include "commands.hpp"

namespace cairn::app {

void add_info_command(CLI::App& app, std::function<int()>& run) {
  struct Args {
    std::string cloud;
    bool drop_invalid = false;
  };
  auto args = std::make_shared<Args>();
  auto* cmd = app.add_subcommand("info", "Print a JSON summary of a point-cloud file");
  cmd->add_option("CLOUD", args->cloud, "input cloud")->required();
  cmd->add_flag("--drop-invalid", args->drop_invalid, "drop NaN/Inf points instead of failing");
  cmd->callback([&run, args] {
    run = [args] {
      io::ReadOptions ro;
      ro.drop_non_finite = args->drop_invalid;
      const io::ReadResult in = io::read_cloud(args->cloud, ro);
      const PointCloud& c = in.cloud;
      const Aabb box = bounds(c.points);
      const auto w = [&](const Vec3f& p) {
        const Vec3d q = c.origin + p.cast<double>();
        return nlohmann::json{q.x(), q.y(), q.z()};
      };
      nlohmann::json j{{"file", args->cloud},
                       {"num_points", c.size()},
                       {"num_input", in.num_input},
                       {"origin", {c.origin.x(), c.origin.y(), c.origin.z()}},
                       {"bbox_min", w(box.min)},
                       {"bbox_max", w(box.max)},
                       {"normals", c.has_normals()},
                       {"colors", c.has_colors()},
                       {"times", c.has_times()},
                       {"labels", c.has_labels()}};
      j["fields"] = nlohmann::json::array();
      for (const auto& f : c.fields) j["fields"].push_back(f.name);
      std::cout << j.dump(2) << std::endl;
      return kExitOk;
    };
  });
}

}  // namespace cairn::app
