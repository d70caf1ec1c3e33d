#pragma once
// The object database fed from the perception stages (Sec. 4.5): segments of a (re-)segmented
// map, associated with what is stored and committed as one operation; JSON views for the CLI.
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "cairn/objects/association.hpp"
#include "cairn/objects/object_db.hpp"
#include "cairn/segmentation/segmenter.hpp"

namespace cairn {

/// The object segments (not the planar ones) of a segmentation of `map`, as world clouds.
[[nodiscard]] std::vector<PointCloud> object_segments(const PointCloud& map, const SegmentationResult& result);

struct ObjectsUpdate {
  Association association;
  CommitResult commit;  // op 0 when there was nothing to store
};

/// Associates `segments` (of `map`) with the database's objects and commits the outcome: the
/// first call on an empty database creates every object. Nothing is committed when nothing changed.
ObjectsUpdate update_objects(ObjectDatabase& db, const PointCloud& map, const std::vector<PointCloud>& segments,
                             const AssociationConfig& config, double time, const std::string& source);

/// The object to grasp (Sec. 5.1): the one of id `id`, or without an id the largest (most
/// points) that is not lost. Throws InputError naming the database when there is none.
[[nodiscard]] ObjectRecord object_to_grasp(const ObjectDatabase& db, std::optional<std::int64_t> id);

/// Whether the database holds a grasp (in any run): a drone survey taken before it no longer
/// shows the site (the objects and grasp nodes stop using the registered drone cloud then).
[[nodiscard]] bool any_grasp_stored(const ObjectDatabase& db);

// ---- JSON (the `cairn objects` contract, docs/objects.md) -------------------------------------
[[nodiscard]] nlohmann::json object_summary_json(const ObjectRecord& r);  // id, status, centroid, num_points, updates
[[nodiscard]] nlohmann::json object_json(const ObjectRecord& r);          // + reason, source, bounds, grasp
/// `cairn objects list`: {"objects": [object_summary_json of each]}.
[[nodiscard]] nlohmann::json objects_list_json(const ObjectDatabase& db);
[[nodiscard]] nlohmann::json history_json(const std::vector<PoseUpdate>& history);
[[nodiscard]] nlohmann::json association_json(const ObjectsUpdate& u);

}  // namespace cairn
