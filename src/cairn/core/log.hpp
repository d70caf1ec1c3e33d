#pragma once
// Logging (spdlog, to stderr) and per-stage wall-clock timings.
#include <chrono>
#include <map>
#include <string>
#include <vector>

namespace cairn {

/// Sets the stderr logger's level: trace, debug, info, warn, error, off.
void set_log_level(const std::string& level);

/// Wall-clock milliseconds since construction or the last lap().
class Stopwatch {
 public:
  Stopwatch() : start_(Clock::now()) {}
  [[nodiscard]] double elapsed_ms() const {
    return std::chrono::duration<double, std::milli>(Clock::now() - start_).count();
  }
  double lap_ms() {
    const double ms = elapsed_ms();
    start_ = Clock::now();
    return ms;
  }

 private:
  using Clock = std::chrono::steady_clock;
  Clock::time_point start_;
};

/// Ordered stage name → milliseconds, as the paper's Table 1.
struct Timings {
  std::vector<std::pair<std::string, double>> stages;
  void add(const std::string& stage, double ms);
  [[nodiscard]] double get(const std::string& stage) const;  // 0 if absent
  [[nodiscard]] double total() const;
  /// Logs "<prefix> stage: x ms" lines at info level.
  void log(const std::string& prefix) const;
};

}  // namespace cairn
