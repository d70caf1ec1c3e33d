#include "cairn_ros/registration_core.hpp"


#include "cairn/core/error.hpp"
#include "cairn/core/io/io.hpp"
#include "cairn/eval/app_config.hpp"
#include "cairn/registration/drone_registration.hpp"
#include "cairn_ros/convert.hpp"
#include "cairn_ros/latest_cloud.hpp"

namespace cairn::bag {

struct RegistrationCore::Impl {
  AppConfig config;
  LatestCloud map, drone;
};

RegistrationCore::RegistrationCore(const std::string& config_file, const std::vector<std::string>& overrides)
    : impl_(std::make_unique<Impl>()) {
  impl_->config = load_app_config(AppConfig{}, config_file, overrides);
  impl_->config.registration.validate();
}

RegistrationCore::~RegistrationCore() = default;

const io::BagTopics& RegistrationCore::topics() const { return impl_->config.bag; }

void RegistrationCore::set_map(const file::Cloud& map) { impl_->map.set(map); }

void RegistrationCore::set_drone_cloud(const file::Cloud& cloud) { impl_->drone.set(cloud); }

RegistrationAnswer RegistrationCore::register_drone(const std::string& cloud_file, const std::string& sfm,
                                                    const std::string& metric, bool gravity_aligned,
                                                    bool estimate_scale) {
  const std::shared_ptr<const PointCloud> map = impl_->map.get();
  if (!map) throw InputError("cairn_registration: no map received yet");
  std::shared_ptr<const PointCloud> drone = impl_->drone.get();
  if (!cloud_file.empty()) drone = std::make_shared<const PointCloud>(io::load_cloud(cloud_file));
  if (!drone || drone->empty())
    throw InputError("cairn_registration: no drone cloud (give cloud_file, or publish it on " +
                     impl_->config.bag.drone_cloud + ")");
  GlobalRegistrationConfig registration = impl_->config.registration;
  if (gravity_aligned) registration.gravity_aligned = true;
  if (estimate_scale) registration.scale_check.estimate = true;
  const DroneRegistration d = cairn::register_drone(*drone, *map, sfm, metric,
                                                    impl_->config.segmentation, registration, impl_->config.scale);
  RegistrationAnswer out;
  out.success = d.result.success;
  out.message = d.result.success ? "" : d.result.reason;
  const Eigen::Matrix4d T = d.T_target_source.matrix();
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) out.T_map_drone[std::size_t(4 * r + c)] = T(r, c);
  out.json = to_json(d).dump();
  if (d.result.success) {
    PointCloud aligned = d.result.source_voxelised;
    transform_cloud(aligned, d.result.T_target_source);
    out.aligned = cloud_of(aligned, 0.0, "");
    out.merged = cloud_of(d.result.merged_map, 0.0, "");
  }
  return out;
}

}  // namespace cairn::bag
