// cairn config --dump: the effective configuration (defaults ← YAML file ← --set overrides).
#include <iostream>

#include "app_config.hpp"
#include "commands.hpp"

namespace cairn::app {

void add_config_command(CLI::App& app, std::function<int()>& run) {
  struct Args {
    bool dump = false, json = false;
    CommonOptions common;
  };
  auto args = std::make_shared<Args>();
  auto* cmd = app.add_subcommand("config", "Show the effective configuration");
  cmd->add_flag("--dump", args->dump, "print the effective configuration as documented YAML");
  cmd->add_flag("--json", args->json, "print it as JSON instead");
  args->common.add_to(*cmd);
  cmd->callback([&run, args] {
    run = [args] {
      const AppConfig cfg = args->common.load();
      if (args->json)
        std::cout << config::to_json(cfg).dump(2) << std::endl;
      else
        std::cout << config::to_yaml(cfg);
      return kExitOk;
    };
  });
}

}  // namespace cairn::app
