#pragma once
// The effective configuration of every stage, as `cairn config --dump` prints it.
#include <CLI/CLI.hpp>
#include <string>
#include <vector>

#include "cairn/core/config.hpp"
#include "cairn/core/io/bag_topics.hpp"
#include "cairn/core/normals.hpp"
#include "cairn/core/voxel_grid.hpp"
#include "cairn/eval/experiment.hpp"
#include "cairn/grasp/config.hpp"
#include "cairn/mapping/config.hpp"
#include "cairn/objects/config.hpp"
#include "cairn/registration/global_registration.hpp"
#include "cairn/registration/scale_recovery.hpp"
#include "cairn/segmentation/segmenter.hpp"
#include "cairn/sim/simulation.hpp"

namespace cairn::app {

struct AppConfig {
  VoxelGridConfig voxel;
  NormalConfig normals;
  SegmentationConfig segmentation;
  MappingConfig mapping;
  ScaleRecoveryConfig scale;
  GlobalRegistrationConfig registration;
  ObjectsConfig objects;
  grasp::GraspConfig grasp;
  sim::SimulationConfig simulation;  // generic defaults; `cairn simulate` starts from its scenario
  eval::ExperimentConfig experiment;  // `cairn demo`: the experiment's own parameters
  io::BagTopics bag;                  // `--bag`: rosbag topic and frame names

  template <class V>
  void visit(V& v) {
    v("voxel", voxel, "voxel-grid downsampling (Sec. 4.2, Table 3)");
    v("normals", normals, "PCA normal estimation");
    v("segmentation", segmentation, "map segmentation (Sec. 4.3)");
    v("mapping", mapping, "LiDAR mapping (Sec. 4.2)");
    v("scale", scale, "metric scale of the drone SfM model from camera positions (Sec. 4.1)");
    v("registration", registration, "segment-based global registration (Sec. 4.4)");
    v("objects", objects, "object database: map updates under manipulation (Sec. 4.5)");
    v("grasp", grasp, "grasp pose planning (Sec. 5)");
    v("simulation", simulation, "simulator: site, excavator, LiDARs, state estimation, drone");
    v("experiment", experiment, "experiments 1 and 2 end to end (Sec. 6, `cairn demo`)");
    v("bag", bag, "rosbag topic and frame names (`--bag`, docs/ros.md)");
  }
};

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
