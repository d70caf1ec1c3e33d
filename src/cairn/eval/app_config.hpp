#pragma once
// The effective configuration of every stage, as `cairn config --dump` prints it and every front
// end (the CLI, the ROS nodes) loads it: one source of defaults, one YAML layout, one --set syntax.
#include <filesystem>
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

namespace cairn {

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

/// `base`, then the YAML file (when not empty), then the `key.path=value` overrides in order.
/// Throws ConfigError (unknown key, bad value) or InputError (unreadable file).
[[nodiscard]] AppConfig load_app_config(AppConfig base, const std::filesystem::path& file,
                                        const std::vector<std::string>& overrides);

}  // namespace cairn
