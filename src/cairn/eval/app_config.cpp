#include "cairn/eval/app_config.hpp"

namespace cairn {

AppConfig load_app_config(AppConfig base, const std::filesystem::path& file, const std::vector<std::string>& overrides) {
  if (!file.empty()) config::load_yaml_file(base, file);
  for (const auto& o : overrides) config::apply_override(base, o);
  return base;
}

}  // namespace cairn
