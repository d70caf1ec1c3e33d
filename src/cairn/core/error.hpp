#pragma once
// Errors at API boundaries: exceptions carrying a message that names the input and the problem.
#include <stdexcept>
#include <string>

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

}  // namespace cairn
