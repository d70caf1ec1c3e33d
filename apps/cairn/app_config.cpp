#include "app_config.hpp"

#include <fstream>

#include "cairn/core/error.hpp"
#include "cairn/core/log.hpp"

namespace cairn::app {

void CommonOptions::add_to(CLI::App& cmd) {
  cmd.add_option("--config", config_file, "YAML configuration file (see `cairn config --dump`)");
  cmd.add_option("--set", overrides, "override one parameter, e.g. --set segmentation.ground.d_plane=0.08")
      ->take_all();
  cmd.add_option("--log-level", log_level, "trace, debug, info, warn, error, off");
}

AppConfig CommonOptions::load(AppConfig cfg) const {
  set_log_level(log_level);
  return load_app_config(std::move(cfg), config_file, overrides);
}

void write_out_file(const std::string& path, const std::string& text) {
  std::ofstream f(path);
  if (!f || !(f << text << '\n')) throw InputError("--out: cannot write '" + path + "'");
}

}  // namespace cairn::app
