#include "bag_support.hpp"

#include <spdlog/spdlog.h>

#include "cairn/core/error.hpp"
#if defined(CAIRN_WITH_ROS)
#include "cairn_ros/run_bag.hpp"
#endif

namespace cairn::app {

#if defined(CAIRN_WITH_ROS)
void require_bag_support() {}

nlohmann::json write_bag(const io::RunDirectory& run, const std::filesystem::path& bag, const io::BagTopics& topics) {
  const bag::BagWriteSummary s = bag::write_run_bag(run, bag, topics);
  nlohmann::json j;
  for (const auto& [topic, n] : s.messages) j[topic] = n;
  return j;
}

MapRunResult map_from_bag(const std::filesystem::path& file, const MappingConfig& config, const MappingProgress& progress,
                          const io::BagTopics& topics) {
  const bag::BagRun run = bag::open_run_bag(file, topics);
  for (const auto& [sensor, n] : run.sweeps)
    spdlog::info("map: {} sweeps of LiDAR {}, period {:.4f} s", n, sensor, run.sweep_period.at(sensor));
  return bag::map_bag(run, config, progress, topics);
}
#else
namespace {
[[noreturn]] void no_ros() {
  throw InputError("--bag: this cairn was built without ROS 1 (scripts/install_deps.sh installs it; then rebuild)");
}
}  // namespace
void require_bag_support() { no_ros(); }
nlohmann::json write_bag(const io::RunDirectory&, const std::filesystem::path&, const io::BagTopics&) { no_ros(); }
MapRunResult map_from_bag(const std::filesystem::path&, const MappingConfig&, const MappingProgress&, const io::BagTopics&) {
  no_ros();
}
#endif

}  // namespace cairn::app
