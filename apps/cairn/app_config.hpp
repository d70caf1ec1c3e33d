#pragma once
// The CLI's options over the shared configuration (cairn/eval/app_config.hpp).
#include <CLI/CLI.hpp>
#include <string>
#include <vector>

#include "cairn/eval/app_config.hpp"

namespace cairn::app {

using AppConfig = ::cairn::AppConfig;

/// Options every subcommand shares: --config FILE, --set key.path=value, --log-level.
struct CommonOptions {
  std::string config_file;
  std::vector<std::string> overrides;
  std::string log_level = "info";
  void add_to(CLI::App& cmd);
  /// Defaults, then the YAML file, then the --set overrides (in order). Throws ConfigError.
  [[nodiscard]] AppConfig load() const { return load(AppConfig{}); }
  /// The same on top of `base` instead of the defaults.
  [[nodiscard]] AppConfig load(AppConfig base) const;
};

/// Exit codes of the command line contract.
/// Writes `text` and a newline to the file of an --out option; throws InputError "--out: cannot
/// write 'PATH'" when it cannot.
void write_out_file(const std::string& path, const std::string& text);

inline constexpr int kExitOk = 0;
inline constexpr int kExitBadInput = 2;
inline constexpr int kExitNoResult = 3;

}  // namespace cairn::app
