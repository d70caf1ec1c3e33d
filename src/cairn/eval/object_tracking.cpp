#include "cairn/eval/object_tracking.hpp"

#include "cairn/core/log.hpp"
#include "cairn/eval/tracker.hpp"

namespace cairn::eval {
namespace {

/// Simulated time the experiment needs: the initial scan, then every move and rescan.
double duration(const ObjectTrackingConfig& c) {
  const int moves = c.max_moves_per_round > 0 ? c.max_moves_per_round : c.simulation.site.stones.count;
  return c.initial_scan + c.rounds * moves * (c.carry_time + c.rescan) + 1.0;
}

}  // namespace

ObjectTrackingResult run_object_tracking(const ObjectTrackingConfig& config, const TrackingProgress& progress) {
  Stopwatch sw;
  Tracker t(config, progress, duration(config));
  t.result.site_at_rest = true;
  t.initial_scan();
  t.populate();
  for (int r = 1; r <= config.rounds; ++r) t.run_round(r);
  t.result.wall_time = sw.lap_ms() / 1000.0;
  return t.result;
}

nlohmann::json to_json(const ObjectTrackingResult& r) {
  nlohmann::json moves = nlohmann::json::array(), rounds = nlohmann::json::array();
  auto counts = [](const RemovalCounts& c) {
    return nlohmann::json{{"object", c.object}, {"ground", c.ground}, {"neighbours", c.neighbours},
                          {"object_left", c.object_left}};
  };
  for (const MoveRecord& m : r.moves)
    moves.push_back({{"round", m.round}, {"stone", m.stone}, {"object", m.object}, {"purity", m.purity},
                     {"time", m.time},
                     {"moved_m", m.moved_m}, {"turned_deg", m.turned_deg}, {"settle_m", m.settle_m},
                     {"settle_deg", m.settle_deg}, {"predicted_error_m", m.predicted_error_m},
                     {"predicted_error_deg", m.predicted_error_deg}, {"error_m", m.error_m},
                     {"error_deg", m.error_deg}, {"found", m.found}, {"fitness", m.fitness}, {"rmse", m.rmse}, {"reason", m.reason},
                     {"removed_sphere", counts(m.sphere)}, {"removed_object_voxels", counts(m.object_voxels)},
                     {"ghost_share", m.ghost_share}, {"carried_in_map", m.carried_in_map}, {"map_points", m.map_points}});
  for (const RoundRecord& x : r.rounds)
    rounds.push_back({{"round", x.round}, {"objects", x.objects}, {"matched", x.matched},
                      {"new_objects", x.new_objects}, {"new_on_tracked", x.new_on_tracked},
                      {"new_on_untracked", x.new_on_untracked}, {"new_on_terrain", x.new_on_terrain},
                      {"vanished", x.vanished},
                      {"moved_unexpectedly", x.moved_unexpectedly}, {"moves", x.moves},
                      {"within_tolerance", x.within_tolerance}, {"max_error_m", x.max_error_m},
                      {"max_error_deg", x.max_error_deg}});
  return {{"scenario", r.scenario}, {"seed", r.seed}, {"stones", r.stones}, {"objects_created", r.objects_created},
          {"stones_tracked", r.stones_tracked}, {"unmatched", r.unmatched}, {"moves", moves}, {"rounds", rounds},
          {"wall_time", r.wall_time}};
}

}  // namespace cairn::eval
