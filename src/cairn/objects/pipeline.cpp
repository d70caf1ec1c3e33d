#include "cairn/objects/pipeline.hpp"

#include "cairn/core/error.hpp"
#include "cairn/core/transform.hpp"

namespace cairn {
namespace {
nlohmann::json vec_json(const Vec3d& v) { return {v.x(), v.y(), v.z()}; }
}  // namespace

std::vector<PointCloud> object_segments(const PointCloud& map, const SegmentationResult& result) {
  std::vector<PointCloud> out;
  for (const Segment& s : result.segments)
    if (!s.planar) out.push_back(select(map, s.indices));
  return out;
}

ObjectsUpdate update_objects(ObjectDatabase& db, const PointCloud& map, const std::vector<PointCloud>& segments,
                             const AssociationConfig& config, double time, const std::string& source) {
  const std::vector<ObjectRecord> stored = db.objects();
  ObjectsUpdate u;
  u.association = associate(segments, stored, map, config);
  const Operation op = association_operation(u.association, segments, stored, time, source);
  if (!op.changes.empty()) u.commit = db.commit(op);
  return u;
}

nlohmann::json object_summary_json(const ObjectRecord& r) {
  return {{"id", r.id},
          {"status", to_string(r.status)},
          {"centroid", vec_json(r.centroid)},
          {"num_points", r.num_points},
          {"updates", r.updates}};
}

nlohmann::json objects_list_json(const ObjectDatabase& db) {
  nlohmann::json a = nlohmann::json::array();
  for (const ObjectRecord& r : db.objects(false)) a.push_back(object_summary_json(r));
  return nlohmann::json{{"objects", a}};
}

nlohmann::json object_json(const ObjectRecord& r) {
  nlohmann::json j = object_summary_json(r);
  j["reason"] = r.reason;
  j["source"] = r.source;
  if (!r.cloud.empty()) {
    const Aabb b = bounds(r.cloud.points);
    j["bounds"] = {{"min", vec_json(r.cloud.origin + b.min.cast<double>())},
                   {"max", vec_json(r.cloud.origin + b.max.cast<double>())}};
  }
  j["T_map_gripper_grasp"] = r.T_map_gripper_grasp ? matrix_to_json(r.T_map_gripper_grasp->matrix()) : nlohmann::json();
  return j;
}

nlohmann::json history_json(const std::vector<PoseUpdate>& history) {
  nlohmann::json a = nlohmann::json::array();
  for (const PoseUpdate& h : history)
    a.push_back({{"op", h.op},
                 {"time", h.time},
                 {"cause", to_string(h.cause)},
                 {"transform", matrix_to_json(h.transform.matrix())},
                 {"status", to_string(h.status)},
                 {"reason", h.reason}});
  return a;
}

nlohmann::json association_json(const ObjectsUpdate& u) {
  const Association& a = u.association;
  nlohmann::json matched = nlohmann::json::array(), moved = nlohmann::json::array();
  for (const auto& [seg, id] : a.matched) matched.push_back({{"segment", seg}, {"object", id}});
  for (const Association::Moved& m : a.moved)
    moved.push_back({{"segment", m.segment}, {"object", m.id}, {"motion", matrix_to_json(m.motion.matrix())},
                     {"fitness", m.fitness}, {"rmse", m.rmse}});
  nlohmann::json created = nlohmann::json::array();
  for (std::size_t k = 0; k < a.new_segments.size(); ++k)  // new objects come last in the commit
    created.push_back({{"segment", a.new_segments[k]},
                       {"object", u.commit.ids.empty() ? 0 : u.commit.ids[u.commit.ids.size() - a.new_segments.size() + k]}});
  return {{"op", u.commit.op},       {"matched", matched},          {"moved", moved},
          {"created", created},      {"vanished", a.vanished},      {"out_of_view", a.out_of_view},
          {"ignored_segments", a.ignored_segments}};
}

bool any_grasp_stored(const ObjectDatabase& db) {
  for (const OperationRecord& op : db.operations())
    if (op.kind == "grasp") return true;
  return false;
}

ObjectRecord object_to_grasp(const ObjectDatabase& db, std::optional<std::int64_t> id) {
  if (id) {
    std::optional<ObjectRecord> r = db.object(*id);
    if (!r) throw InputError(db.file().string() + ": no object " + std::to_string(*id));
    return std::move(*r);
  }
  std::optional<ObjectRecord> largest;
  for (ObjectRecord& r : db.objects())
    if (r.status != ObjectStatus::lost && (!largest || r.num_points > largest->num_points)) largest = std::move(r);
  if (!largest) throw InputError(db.file().string() + ": holds no object to grasp");
  return std::move(*largest);
}

}  // namespace cairn
