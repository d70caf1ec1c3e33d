#include "cairn/core/config.hpp"

#include <algorithm>

namespace cairn::config {

void YamlLoader::check_unknown() const {
  for (const auto& kv : node_) {
    const auto key = kv.first.as<std::string>();
    if (std::find(known_.begin(), known_.end(), key) != known_.end()) continue;
    std::string list;
    for (const auto& k : known_) list += (list.empty() ? "" : ", ") + k;
    const std::string where = path_.empty() ? key : path_ + "." + key;
    throw ConfigError("config: unknown key '" + where + "' (known here: " + list + ")");
  }
}

}  // namespace cairn::config
