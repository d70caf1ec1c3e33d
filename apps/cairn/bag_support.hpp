#pragma once
// The CLI's rosbag options (`cairn simulate --bag`, `cairn map --bag`, docs/ros.md). A cairn built
// without ROS 1 keeps the options and refuses them with exit 2 and the reason.
#include <filesystem>
#include <nlohmann/json.hpp>

#include "cairn/core/io/bag_topics.hpp"
#include "cairn/core/io/run_dir.hpp"
#include "cairn/mapping/mapper.hpp"

namespace cairn::app {

/// Throws InputError saying so when this cairn was built without ROS 1.
void require_bag_support();

/// Writes `run` as a rosbag; returns the messages per topic as JSON. Throws InputError.
nlohmann::json write_bag(const io::RunDirectory& run, const std::filesystem::path& bag, const io::BagTopics& topics);

/// Maps straight from a rosbag (no roscore). Throws InputError.
MapRunResult map_from_bag(const std::filesystem::path& bag, const MappingConfig& config, const MappingProgress& progress,
                          const io::BagTopics& topics);

}  // namespace cairn::app
