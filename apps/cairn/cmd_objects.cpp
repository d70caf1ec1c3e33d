// cairn objects {list, show, history, export, update}: the object database (Sec. 4.5) from the
// command line. JSON on stdout; exit 0, or 2 on bad input (missing, foreign or corrupt database,
// unknown id). Only `update` writes.
#include <spdlog/spdlog.h>

#include <iostream>

#include "app_config.hpp"
#include "cairn/core/io/io.hpp"
#include "cairn/objects/pipeline.hpp"
#include "commands.hpp"

namespace cairn::app {
namespace {

ObjectRecord find_object(const ObjectDatabase& db, std::int64_t id) {
  std::optional<ObjectRecord> r = db.object(id);
  if (!r) throw InputError(db.file().string() + ": no object " + std::to_string(id));
  return std::move(*r);
}

struct Args {
  std::string db, map, out, source = "segmentation";
  std::int64_t id = 0;
  double time = 0.0;
  CommonOptions common;
};

void add_reader(CLI::App& parent, std::function<int()>& run, const std::string& name, const std::string& help,
                bool needs_id, std::function<nlohmann::json(const ObjectDatabase&, const Args&)> action,
                bool needs_out = false) {
  auto args = std::make_shared<Args>();
  auto* cmd = parent.add_subcommand(name, help);
  if (needs_id) cmd->add_option("ID", args->id, "object id")->required();
  cmd->add_option("--db", args->db, "object database (SQLite)")->required();
  if (needs_out) cmd->add_option("--out", args->out, "output PLY file")->required();
  cmd->callback([&run, args, action] {
    run = [args, action] {
      const ObjectDatabase db(args->db, ObjectDatabase::Mode::read_only);
      std::cout << action(db, *args).dump(2) << std::endl;
      return kExitOk;
    };
  });
}

void add_update(CLI::App& parent, std::function<int()>& run) {
  auto args = std::make_shared<Args>();
  auto* cmd = parent.add_subcommand(
      "update", "Segment a map and associate its segments with the database's objects (created when missing)");
  cmd->add_option("--db", args->db, "object database (SQLite; created when missing)")->required();
  cmd->add_option("--map", args->map, "the map (any cloud format)")->required();
  cmd->add_option("--time", args->time, "time of the map [s] (stored with the operation)");
  cmd->add_option("--source", args->source, "where new objects' models come from (stored)");
  args->common.add_to(*cmd);
  cmd->callback([&run, args] {
    run = [args] {
      const AppConfig cfg = args->common.load();
      cfg.objects.validate();
      const PointCloud map = io::read_cloud(args->map).cloud;
      const SegmentationResult seg = segment(map, cfg.segmentation);
      const std::vector<PointCloud> segments = object_segments(map, seg);
      ObjectDatabase db(args->db, ObjectDatabase::Mode::create);
      const ObjectsUpdate u = update_objects(db, map, segments, cfg.objects.association, args->time, args->source);
      spdlog::info("objects: {} segments: {} matched, {} moved, {} new, {} vanished", segments.size(),
                   u.association.matched.size(), u.association.moved.size(), u.association.new_segments.size(),
                   u.association.vanished.size());
      std::cout << association_json(u).dump(2) << std::endl;
      return kExitOk;
    };
  });
}

}  // namespace

void add_objects_command(CLI::App& app, std::function<int()>& run) {
  auto* cmd = app.add_subcommand("objects", "The object database (paper Sec. 4.5)");
  cmd->require_subcommand(1);
  add_reader(*cmd, run, "list", "List the objects", false, [](const ObjectDatabase& db, const Args&) {
    nlohmann::json a = nlohmann::json::array();
    for (const ObjectRecord& r : db.objects(false)) a.push_back(object_summary_json(r));
    return nlohmann::json{{"objects", a}};
  });
  add_reader(*cmd, run, "show", "One object", true, [](const ObjectDatabase& db, const Args& a) {
    return object_json(find_object(db, a.id));
  });
  add_reader(*cmd, run, "history", "Every pose and status change of an object", true,
             [](const ObjectDatabase& db, const Args& a) {
               (void)find_object(db, a.id);
               return nlohmann::json{{"id", a.id}, {"history", history_json(db.history(a.id))}};
             });
  add_reader(
      *cmd, run, "export", "Write an object's cloud as PLY", true,
      [](const ObjectDatabase& db, const Args& a) {
        const ObjectRecord r = find_object(db, a.id);
        io::write_ply(a.out, r.cloud);
        return nlohmann::json{{"id", a.id}, {"file", a.out}, {"num_points", r.num_points}};
      },
      true);
  add_update(*cmd, run);
}

}  // namespace cairn::app
