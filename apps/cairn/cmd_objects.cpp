// cairn objects {list, show, history, export, update}: the object database (Sec. 4.5) from the
// command line. JSON on stdout; exit 0, or 2 on bad input (missing, foreign or corrupt database,
// unknown id). Only `update` writes.
#include <spdlog/spdlog.h>

#include <cstdio>
#include <iostream>

#include "app_config.hpp"
#include "cairn/core/io/io.hpp"
#include "cairn/eval/object_tracking.hpp"
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

struct TrackArgs {
  std::string scenario = "exp2", db, out;
  std::uint64_t seed = 1;
  int rounds = 4, moves = 0;
  CommonOptions common;
};

int run_track(const TrackArgs& a) {
  AppConfig base;
  base.simulation = sim::scenario_config(a.scenario, sim::default_real_mesh_dir());
  const AppConfig cfg = a.common.load(base);
  eval::ObjectTrackingConfig c;
  c.scenario = a.scenario;
  c.seed = a.seed;
  c.rounds = a.rounds;
  c.max_moves_per_round = a.moves;
  c.database = a.db;
  c.simulation = cfg.simulation;
  c.mapping = cfg.mapping;
  c.segmentation = cfg.segmentation;
  c.objects = cfg.objects;
  const eval::ObjectTrackingResult r = eval::run_object_tracking(c, [](const std::string& what, int done, int total) {
    spdlog::info("objects track: {} {}/{}", what, done, total);
  });
  std::printf("%5s %5s %6s %7s %7s %8s %8s %8s %8s %6s %7s %7s %7s %7s %7s  %s\n", "round", "stone", "object",
              "moved_m", "settle", "eq3_cm", "eq3_deg", "err_cm", "err_deg", "ghost%", "carried", "sph_gnd", "sph_nbr",
              "vox_gnd", "vox_nbr", "reason");
  for (const eval::MoveRecord& m : r.moves)
    std::printf("%5d %5d %6lld %7.2f %7.3f %8.2f %8.2f %8.2f %8.2f %6.2f %7ld %7zu %7zu %7zu %7zu  %s\n", m.round,
                m.stone, static_cast<long long>(m.object), m.moved_m, m.settle_m, 100 * m.predicted_error_m,
                m.predicted_error_deg, 100 * m.error_m, m.error_deg, 100 * m.ghost_share, m.carried_in_map,
                m.sphere.ground, m.sphere.neighbours, m.object_voxels.ground, m.object_voxels.neighbours,
                m.reason.c_str());
  for (const eval::RoundRecord& x : r.rounds)
    std::printf("round %d: %d/%d moves within 2 cm and 1 deg (max %.1f cm, %.2f deg); re-segmentation: %zu matched, "
                "%zu new (%zu on tracked stones, %zu on others, %zu on terrain), %zu vanished, %zu moved; %zu objects\n",
                x.round, x.within_tolerance, x.moves, 100 * x.max_error_m, x.max_error_deg, x.matched, x.new_objects,
                x.new_on_tracked, x.new_on_untracked, x.new_on_terrain, x.vanished, x.moved_unexpectedly, x.objects);
  for (const std::string& u : r.unmatched) spdlog::warn("objects track: {}", u);
  std::printf("%d stones, %d objects created, %d tracked; %.0f s wall\n", r.stones, r.objects_created,
              r.stones_tracked, r.wall_time);
  if (!a.out.empty()) write_out_file(a.out, eval::to_json(r).dump(1));
  return kExitOk;
}

void add_track(CLI::App& parent, std::function<int()>& run) {
  auto args = std::make_shared<TrackArgs>();
  auto* cmd = parent.add_subcommand(
      "track", "Experiment 2 in the simulator: scan, store the objects, move every stone round after round "
               "without a map reset; the database scored against the truth after every move");
  cmd->add_option("--scenario", args->scenario, "scenario (exp1, exp2)")->capture_default_str();
  cmd->add_option("--seed", args->seed, "site seed")->capture_default_str();
  cmd->add_option("--rounds", args->rounds, "rounds of moving every stone")->capture_default_str();
  cmd->add_option("--moves", args->moves, "moves per round (0: every stone)")->capture_default_str();
  cmd->add_option("--db", args->db, "object database to write (default: a temporary file)");
  cmd->add_option("--out", args->out, "write every move and round as JSON");
  args->common.add_to(*cmd);
  cmd->callback([&run, args] { run = [args] { return run_track(*args); }; });
}

}  // namespace

void add_objects_command(CLI::App& app, std::function<int()>& run) {
  auto* cmd = app.add_subcommand("objects", "The object database (paper Sec. 4.5)");
  cmd->require_subcommand(1);
  add_reader(*cmd, run, "list", "List the objects", false,
             [](const ObjectDatabase& db, const Args&) { return objects_list_json(db); });
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
  add_track(*cmd, run);
}

}  // namespace cairn::app
