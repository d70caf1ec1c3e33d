#include "cairn/core/log.hpp"

#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include "cairn/core/error.hpp"

namespace cairn {

void set_log_level(const std::string& level) {
  static const bool init = [] {
    auto logger = spdlog::stderr_color_mt("cairn");
    logger->set_pattern("[%H:%M:%S.%e] [%^%l%$] %v");
    spdlog::set_default_logger(logger);
    return true;
  }();
  (void)init;
  const auto lvl = spdlog::level::from_str(level);
  if (lvl == spdlog::level::off && level != "off")
    throw ConfigError("unknown log level '" + level + "' (trace, debug, info, warn, error, off)");
  spdlog::set_level(lvl);
}

void Timings::add(const std::string& stage, double ms) {
  for (auto& [name, value] : stages)
    if (name == stage) {
      value += ms;
      return;
    }
  stages.emplace_back(stage, ms);
}

double Timings::get(const std::string& stage) const {
  for (const auto& [name, value] : stages)
    if (name == stage) return value;
  return 0.0;
}

double Timings::total() const {
  double t = 0.0;
  for (const auto& s : stages) t += s.second;
  return t;
}

void Timings::log(const std::string& prefix) const {
  for (const auto& [name, ms] : stages) spdlog::info("{} {:<22} {:9.2f} ms", prefix, name, ms);
}

}  // namespace cairn
