#include "cairn_ros/objects_core.hpp"

#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>

#include "cairn/core/error.hpp"
#include "cairn/core/voxel_grid.hpp"
#include "cairn/eval/app_config.hpp"
#include "cairn/objects/pipeline.hpp"
#include "cairn/objects/updates.hpp"
#include "cairn/report/report.hpp"
#include "cairn_ros/convert.hpp"
#include "cairn_ros/latest_cloud.hpp"

namespace cairn::bag {

struct ObjectsCore::Impl {
  AppConfig config;
  ObjectDatabase db;
  LatestCloud map, merged;  // merged: dropped at the first grasp
  mutable std::mutex mutex;  // the database: one service at a time

  Impl(AppConfig c, const std::string& database) : config(std::move(c)), db(database, ObjectDatabase::Mode::create) {}

  [[nodiscard]] ObjectRecord object(std::int64_t id) const {
    std::optional<ObjectRecord> r = db.object(id);
    if (!r) throw InputError(db.file().string() + ": no object " + std::to_string(id));
    return std::move(*r);
  }

  [[nodiscard]] std::shared_ptr<const PointCloud> newest_map() const {
    std::shared_ptr<const PointCloud> m = map.get();
    if (!m) throw InputError("cairn_objects: no map received yet");
    return m;
  }

  /// Commits `op` and answers with the object after it and the map edits of the operation.
  ObjectEventAnswer commit(const Operation& op, std::int64_t id) {
    (void)db.commit(op);
    ObjectEventAnswer out{.json = object_json(object(id)).dump(), .edits = {}};
    for (const MapEdit& e : op.map_edits) out.edits.push_back(to_file(e, ""));
    return out;
  }
};

ObjectsCore::ObjectsCore(const std::string& config_file, const std::vector<std::string>& overrides,
                         const std::string& database) {
  AppConfig config = load_app_config(AppConfig{}, config_file, overrides);
  config.objects.validate();
  if (database.empty()) throw InputError("cairn_objects: ~database (the SQLite file) is required");
  impl_ = std::make_unique<Impl>(std::move(config), database);
}

ObjectsCore::~ObjectsCore() = default;

void ObjectsCore::set_map(const file::Cloud& map) { impl_->map.set(map); }

void ObjectsCore::set_merged_map(const file::Cloud& merged) {
  const std::lock_guard lock(impl_->mutex);
  // The drone's survey shows the site before anything moved: once a grasp is stored (in this run
  // or an earlier one of the same database) a re-sent merged map is stale.
  if (!any_grasp_stored(impl_->db)) impl_->merged.set(merged);
}

bool ObjectsCore::has_map() const { return impl_->map.get() != nullptr; }

std::string ObjectsCore::segment(double time) {
  const std::lock_guard lock(impl_->mutex);
  const std::shared_ptr<const PointCloud> merged = impl_->merged.get();
  const std::shared_ptr<const PointCloud> newest = merged ? merged : impl_->newest_map();
  const PointCloud& map = *newest;
  const SegmentationResult seg = cairn::segment(map, impl_->config.segmentation);
  const std::vector<PointCloud> segments = object_segments(map, seg);
  const ObjectsUpdate u = update_objects(impl_->db, map, segments, impl_->config.objects.association, time,
                                         merged ? "registration" : "segmentation");
  nlohmann::json j = association_json(u);
  j["segmented"] = merged ? "merged" : "map";
  return j.dump();
}

ObjectEventAnswer ObjectsCore::grasp(std::int64_t id, const file::Transform& T_map_gripper, double time) {
  const std::lock_guard lock(impl_->mutex);
  const ObjectRecord o = impl_->object(id);
  ObjectEventAnswer a =
      impl_->commit(grasp_operation(o, from_file(T_map_gripper), time, impl_->config.objects.grasp_removal), id);
  impl_->merged.reset();  // the drone's survey no longer shows the site
  return a;
}

ObjectEventAnswer ObjectsCore::release(std::int64_t id, const file::Transform& T_map_gripper, double time) {
  const std::lock_guard lock(impl_->mutex);
  const ObjectRecord o = impl_->object(id);
  return impl_->commit(release_operation(o, from_file(T_map_gripper), time), id);
}

std::string ObjectsCore::realign(double time) {
  const std::lock_guard lock(impl_->mutex);
  const std::shared_ptr<const PointCloud> map = impl_->newest_map();
  nlohmann::json out = nlohmann::json::array();
  std::vector<ObjectRecord> objects = impl_->db.objects();
  for (ObjectRecord& o : objects) {
    if (o.status != ObjectStatus::placed) continue;
    // The search takes no segment that is another object's; those realigned before this one are
    // at their stored corrected poses.
    const RealignResult r = relocate_object(o, *map, objects, impl_->config.objects, impl_->config.segmentation);
    (void)impl_->db.commit(realign_operation(o, r, time));
    o = *impl_->db.object(o.id);
    out.push_back({{"object", o.id}, {"found", r.found}, {"large", r.large}, {"translation_m", r.translation},
                   {"rotation_deg", r.rotation_deg}, {"fitness", r.fitness}, {"reason", r.reason}});
  }
  return nlohmann::json{{"realigned", out}}.dump();
}

std::string ObjectsCore::list_json() const {
  const std::lock_guard lock(impl_->mutex);
  return objects_list_json(impl_->db).dump();
}

std::vector<ObjectView> ObjectsCore::objects(double voxel) const {
  const std::lock_guard lock(impl_->mutex);
  std::vector<ObjectView> out;
  for (const ObjectRecord& o : impl_->db.objects()) {
    const Rgb c = report::object_color(o.id);
    const PointCloud thin = voxel > 0.0 ? voxel_downsample(o.cloud, {.res_voxel = voxel, .n_min = 1}) : o.cloud;
    out.push_back({.id = o.id,
                   .status = to_string(o.status),
                   .centroid = {o.centroid.x(), o.centroid.y(), o.centroid.z()},
                   .cloud = cloud_of(thin, 0.0, ""),
                   .color = {c.r, c.g, c.b}});
  }
  return out;
}

}  // namespace cairn::bag
