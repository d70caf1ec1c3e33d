#pragma once
// Errors at API boundaries: exceptions carrying a message that names the input and the problem.
#include <stdexcept>
#include <string>
#include <string_view>

namespace cairn {

/// Bad or unreadable input data (file missing, wrong format, NaN coordinates, empty cloud, ...).
class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Invalid configuration value or usage.
class ConfigError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Config validation's one check: throws ConfigError "config: <section>.<key> <what>" unless `ok`.
inline void require_config(bool ok, std::string_view section, std::string_view key, std::string_view what) {
  if (ok) return;
  std::string msg = "config: ";  // built step by step: GCC 12's -Wrestrict misfires on a + b + c
  msg += section;
  msg += '.';
  msg += key;
  msg += ' ';
  msg += what;
  throw ConfigError(msg);
}

}  // namespace cairn
