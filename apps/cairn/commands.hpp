#pragma once
#include <CLI/CLI.hpp>
#include <functional>

namespace cairn::app {
// Each subcommand registers itself and, when chosen, sets `run` to its action.
void add_segment_command(CLI::App& app, std::function<int()>& run);
void add_config_command(CLI::App& app, std::function<int()>& run);
void add_info_command(CLI::App& app, std::function<int()>& run);
void add_demo_command(CLI::App& app, std::function<int()>& run);
void add_pipeline_command(CLI::App& app, std::function<int()>& run);
void add_simulate_command(CLI::App& app, std::function<int()>& run);
void add_map_command(CLI::App& app, std::function<int()>& run);
void add_scale_command(CLI::App& app, std::function<int()>& run);
void add_register_command(CLI::App& app, std::function<int()>& run);
void add_protocol_command(CLI::App& app, std::function<int()>& run);
void add_grasp_trial_command(CLI::App& app, std::function<int()>& run);
void add_grasp_baseline_command(CLI::App& app, std::function<int()>& run);
void add_objects_command(CLI::App& app, std::function<int()>& run);
void add_grasp_command(CLI::App& app, std::function<int()>& run);
void add_grasp_trials_command(CLI::App& app, std::function<int()>& run);
}  // namespace cairn::app
