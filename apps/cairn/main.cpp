// cairn: perception and grasp planning for construction robots that build with found stones.
#include <spdlog/spdlog.h>

#include <iostream>

#include "app_config.hpp"
#include "cairn/core/error.hpp"
#include "commands.hpp"

int main(int argc, char** argv) {
  using namespace cairn;
  CLI::App app{"cairn — mapping, segmentation, registration and grasp planning for stones on site"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "cairn 0.1.0");
  std::function<int()> run;
  app::add_segment_command(app, run);
  app::add_config_command(app, run);
  app::add_info_command(app, run);
  app::add_demo_command(app, run);
  app::add_pipeline_command(app, run);
  app::add_simulate_command(app, run);
  app::add_map_command(app, run);
  app::add_scale_command(app, run);
  app::add_register_command(app, run);
  app::add_protocol_command(app, run);
  app::add_grasp_trial_command(app, run);
  app::add_grasp_baseline_command(app, run);
  app::add_objects_command(app, run);
  app::add_grasp_command(app, run);
  app::add_grasp_trials_command(app, run);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? 0 : app::kExitBadInput;
  }
  try {
    set_log_level("info");
    return run ? run() : app::kExitBadInput;
  } catch (const InputError& e) {
    spdlog::error("{}", e.what());
  } catch (const ConfigError& e) {
    spdlog::error("{}", e.what());
  } catch (const std::exception& e) {
    spdlog::error("unexpected error: {}", e.what());
  }
  return app::kExitBadInput;
}
