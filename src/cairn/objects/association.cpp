#include "cairn/objects/association.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <numbers>
#include <set>

#include <spdlog/spdlog.h>

#include "cairn/core/error.hpp"
#include "cairn/core/kdtree.hpp"
#include "cairn/core/transform.hpp"
#include "cairn/registration/icp.hpp"
#include "cairn/core/units.hpp"

namespace cairn {
namespace {

/// A cloud's points relative to `o` (the association's working frame).
std::vector<Vec3f> relative_to(const PointCloud& c, const Vec3d& o) {
  std::vector<Vec3f> out(c.size());
  for (std::size_t i = 0; i < c.size(); ++i) out[i] = (c.world(i) - o).cast<float>();
  return out;
}

std::size_t count_near(const std::vector<Vec3f>& points, const KdTree& tree, double distance) {
  std::size_t n = 0;
  const float d2 = float(distance * distance);
  for (const Vec3f& p : points) {
    float sq = 0.0f;
    (void)tree.nearest_within(p, d2, &sq);
    if (sq <= d2) ++n;
  }
  return n;
}

struct Entity {  // an object or a segment in the working frame
  std::vector<Vec3f> points;
  Vec3f centroid = Vec3f::Zero();
  float radius = 0.0f;
  std::unique_ptr<KdTree> tree;
  void prepare(std::vector<Vec3f> p) {
    points = std::move(p);
    centroid = cairn::centroid(points);
    for (const Vec3f& q : points) radius = std::max(radius, (q - centroid).norm());
    tree = std::make_unique<KdTree>(points);
  }
};


/// The starting rotations: yaw_seeds about the vertical, with all_faces for each of the six faces
/// of a box turned down (a stone that fell or rolled).
std::vector<Eigen::Matrix3d> start_rotations(int yaw_seeds, bool all_faces) {
  std::vector<Eigen::Matrix3d> faces = {Eigen::Matrix3d::Identity()};
  if (all_faces) {
    const double h = 0.5 * std::numbers::pi;
    for (const auto& [angle, axis] : {std::pair{h, Eigen::Vector3d::UnitX()}, std::pair{-h, Eigen::Vector3d::UnitX()},
                                      std::pair{h, Eigen::Vector3d::UnitY()}, std::pair{-h, Eigen::Vector3d::UnitY()},
                                      std::pair{2 * h, Eigen::Vector3d::UnitX()}})
      faces.push_back(Eigen::AngleAxisd(angle, axis).toRotationMatrix());
  }
  std::vector<Eigen::Matrix3d> out;
  for (const Eigen::Matrix3d& f : faces)
    for (int k = 0; k < yaw_seeds; ++k)
      out.push_back(Eigen::AngleAxisd(2.0 * std::numbers::pi * k / yaw_seeds, Eigen::Vector3d::UnitZ()) * f);
  return out;
}

/// ICP of the segment onto the object's model from the starting rotations; the best fit.
ModelFit fit_segment_to_model(const Entity& seg, const Entity& model, const Vec3d& o, const AssociationConfig& config,
                              bool all_faces) {
  const Vec3f cm = model.centroid;
  std::vector<Vec3f> target_pts(model.points.size()), source(seg.points.size());
  for (std::size_t i = 0; i < model.points.size(); ++i) target_pts[i] = model.points[i] - cm;
  for (std::size_t i = 0; i < seg.points.size(); ++i) source[i] = seg.points[i] - seg.centroid;
  const IcpTarget target(std::move(target_pts), NormalConfig{.k = 20});
  IcpConfig icp;
  std::vector<ModelFit> fits;
  for (const Eigen::Matrix3d& R : start_rotations(config.yaw_seeds, all_faces)) {
    // T maps the segment (centred at its centroid) into the model's frame (centred at cm).
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = R;
    // Coarse: the centroids of a partial view and of the whole model differ by up to ~radius/2.
    const double coarse = std::max(4.0 * config.overlap_distance, double(model.radius) / 2.0);
    for (double d : {coarse, config.overlap_distance}) {
      icp.max_correspondence_distance = d;
      const IcpResult r = register_icp(source, target, T, icp);
      if (r.T_target_source.matrix().allFinite()) T = r.T_target_source;
    }
    const IcpResult e = evaluate_alignment(source, target, T, config.overlap_distance);
    // world: model = o + cm + T (seg - o - cs)  ⇒  the model moves by M = (T_seg-frame ∘ T^-1 ∘ model-frame).
    const Eigen::Vector3d wm = o + cm.cast<double>(), ws = o + seg.centroid.cast<double>();
    fits.push_back({.fitness = e.fitness, .rmse = e.rmse,
                    .motion = Eigen::Translation3d(ws) * T.inverse() * Eigen::Translation3d(-wm)});
  }
  const auto better = [](const ModelFit& a, const ModelFit& b) {
    return a.fitness > b.fitness || (a.fitness == b.fitness && a.rmse < b.rmse);
  };
  ModelFit best;
  for (const ModelFit& f : fits)
    if (better(f, best)) best = f;
  // The best fit of a pose clearly different from the best one (a round or symmetric stone fits
  // several ways): how close it comes tells whether the best is ambiguous.
  // (A pose that lays the model onto its own surface — a symmetric stone turned — is the same.)
  for (const ModelFit& f : fits) {
    if (f.fitness <= best.runner_up) continue;
    const Eigen::Isometry3d D = best.motion.inverse() * f.motion;  // world frame, model onto itself?
    if (rotation_angle(D.linear()) <= config.distinct_rotation_deg / kDegPerRad) continue;
    std::vector<Vec3f> moved(model.points.size());
    for (std::size_t i = 0; i < moved.size(); ++i)
      moved[i] = (D * (o + model.points[i].cast<double>()) - o).cast<float>();
    if (double(count_near(moved, *model.tree, config.overlap_distance)) >= 0.8 * double(moved.size())) continue;
    best.runner_up = f.fitness;
  }
  return best;
}

}  // namespace

struct SegmentOwners::Owner {
  std::int64_t id = 0;
  std::vector<Vec3f> points;  // relative to center_
  std::unique_ptr<KdTree> tree;
};

SegmentOwners::SegmentOwners(const std::vector<ObjectRecord>& objects, std::int64_t self, const PointCloud& map,
                             const Vec3d& center, double reach, const AssociationConfig& config)
    : center_(center), config_(config) {
  double extent = 0.0;  // horizontal distance from center_ within which the candidates' points lie
  for (const ObjectRecord& r : objects) {
    const bool seen_there = r.status == ObjectStatus::on_ground || r.status == ObjectStatus::placed;
    if (r.id == self || !seen_there || r.cloud.empty()) continue;
    auto o = std::make_unique<Owner>();
    o->id = r.id;
    o->points = relative_to(r.cloud, center);
    const Vec3f c = cairn::centroid(o->points);
    double radius = 0.0;
    for (const Vec3f& q : o->points) radius = std::max(radius, double((q - c).norm()));
    if (double(c.head<2>().norm()) > reach + radius + config.overlap_distance) continue;
    extent = std::max(extent, double(c.head<2>().norm()) + radius + config.overlap_distance);
    owners_.push_back(std::move(o));
  }
  std::vector<Vec3f> near;  // the map where the candidates are
  for (std::size_t i = 0; i < map.size(); ++i) {
    const Vec3d d = map.world(i) - center;
    if (d.head<2>().norm() <= extent) near.push_back(d.cast<float>());
  }
  const std::unique_ptr<KdTree> map_tree = near.empty() ? nullptr : std::make_unique<KdTree>(near);
  std::erase_if(owners_, [&](const std::unique_ptr<Owner>& o) {  // not where its cloud is: moved, or gone unnoticed
    return !map_tree || double(count_near(o->points, *map_tree, config.overlap_distance)) <
                            config.min_support * double(o->points.size());
  });
  for (auto& o : owners_) o->tree = std::make_unique<KdTree>(o->points);
}

SegmentOwners::~SegmentOwners() = default;

std::optional<std::int64_t> SegmentOwners::owner(const PointCloud& segment) const {
  if (segment.empty() || owners_.empty()) return std::nullopt;
  const std::vector<Vec3f> points = relative_to(segment, center_);
  double best = 0.0;
  std::optional<std::int64_t> id;
  for (const auto& o : owners_) {
    const double f = double(count_near(points, *o->tree, config_.overlap_distance)) / double(points.size());
    if (f > best) best = f, id = o->id;
  }
  return best >= config_.min_overlap ? id : std::nullopt;
}

ModelFit fit_model_to_segment(const PointCloud& segment, const PointCloud& model, const AssociationConfig& config,
                              bool all_faces) {
  if (segment.empty() || model.empty()) throw InputError("fit_model_to_segment: empty cloud");
  const Vec3d o = model.origin;
  Entity seg, mod;
  seg.prepare(relative_to(segment, o));
  mod.prepare(relative_to(model, o));
  return fit_segment_to_model(seg, mod, o, config, all_faces);
}

Association associate(const std::vector<PointCloud>& segments, const std::vector<ObjectRecord>& objects,
                      const PointCloud& map, const AssociationConfig& config) {
  map.check_finite("association: map");
  const Vec3d o = map.origin;
  Association a;
  std::vector<Entity> segs(segments.size());
  for (std::size_t i = 0; i < segments.size(); ++i) {
    segments[i].check_finite("association: segment " + std::to_string(i));
    segs[i].prepare(relative_to(segments[i], o));
  }
  std::vector<const ObjectRecord*> objs;
  std::vector<Entity> models;
  for (const ObjectRecord& r : objects) {
    if (r.status == ObjectStatus::grasped || r.cloud.empty()) continue;
    objs.push_back(&r);
    models.emplace_back().prepare(relative_to(r.cloud, o));
  }
  const std::unique_ptr<KdTree> map_tree = map.empty() ? nullptr : std::make_unique<KdTree>(map.points);

  // 1. Support and view.
  std::vector<bool> present(objs.size(), false), in_view(objs.size(), false);
  for (std::size_t j = 0; j < objs.size(); ++j) {
    if (!map_tree) continue;
    const double support = double(count_near(models[j].points, *map_tree, config.overlap_distance)) /
                           double(models[j].points.size());
    present[j] = support >= config.min_support;
    spdlog::debug("association: object {} support {:.2f}", objs[j]->id, support);
    std::size_t near = 0;
    map_tree->for_each_in_radius((objs[j]->centroid - o).cast<float>(), float(config.in_view_radius),
                                 [&](std::uint32_t, float) { ++near; });
    in_view[j] = near >= std::size_t(config.in_view_min_points);
  }
  // 2. Overlap: each segment to the object sharing most of its points.
  std::vector<bool> matched_obj(objs.size(), false);
  std::vector<std::size_t> unmatched;
  for (std::size_t i = 0; i < segs.size(); ++i) {
    double best = 0.0;
    std::size_t best_j = objs.size();
    for (std::size_t j = 0; j < objs.size(); ++j) {
      if ((segs[i].centroid - models[j].centroid).norm() > segs[i].radius + models[j].radius) continue;
      const double f = double(count_near(segs[i].points, *models[j].tree, config.overlap_distance)) /
                       double(segs[i].points.size());
      if (f > best) best = f, best_j = j;
    }
    if (best >= config.min_overlap) {
      a.matched.emplace_back(i, objs[best_j]->id);
      matched_obj[best_j] = present[best_j] = true;
    } else {
      unmatched.push_back(i);
    }
  }
  for (std::size_t j = 0; j < objs.size(); ++j)
    if (present[j]) a.present.push_back(objs[j]->id);
  // 3. Moved: unmatched segments tried as objects that are no longer where they were.
  struct Candidate {
    std::size_t seg, obj;
    ModelFit fit;
  };
  std::vector<Candidate> fits;
  for (std::size_t i : unmatched) {
    if (segs[i].points.size() < std::size_t(config.min_segment_points)) continue;
    for (std::size_t j = 0; j < objs.size(); ++j) {
      if (present[j]) continue;
      const bool lost = objs[j]->status == ObjectStatus::lost;
      if (!lost && (segs[i].centroid - models[j].centroid).norm() > config.search_radius) continue;
      // A lost object may have fallen or rolled: every face down is tried.
      const ModelFit f = fit_segment_to_model(segs[i], models[j], o, config, /*all_faces=*/lost);
      spdlog::debug("association: segment {} as object {} moved: fitness {:.2f}, rmse {:.3f} m", i, objs[j]->id,
                    f.fitness, f.rmse);
      if (f.fitness >= config.min_fitness && f.rmse <= config.max_rmse && f.unambiguous(config.ambiguity_margin))
        fits.push_back({i, j, f});
    }
  }
  std::sort(fits.begin(), fits.end(), [](const Candidate& x, const Candidate& y) { return x.fit.fitness > y.fit.fitness; });
  std::set<std::size_t> used_seg, used_obj;
  for (const Candidate& c : fits) {
    if (used_seg.contains(c.seg) || used_obj.contains(c.obj)) continue;
    used_seg.insert(c.seg);
    used_obj.insert(c.obj);
    a.moved.push_back({.id = objs[c.obj]->id, .segment = c.seg, .motion = c.fit.motion,
                       .fitness = c.fit.fitness, .rmse = c.fit.rmse});
  }
  // 4. New segments; objects gone.
  for (std::size_t i : unmatched) {
    if (used_seg.contains(i)) continue;
    if (segs[i].points.size() < std::size_t(config.min_segment_points)) a.ignored_segments.push_back(i);
    else a.new_segments.push_back(i);
  }
  for (std::size_t j = 0; j < objs.size(); ++j) {
    if (present[j] || used_obj.contains(j)) continue;
    if (in_view[j]) a.vanished.push_back(objs[j]->id);
    else a.out_of_view.push_back(objs[j]->id);
  }
  return a;
}

Operation association_operation(const Association& a, const std::vector<PointCloud>& segments,
                                const std::vector<ObjectRecord>& objects, double time, const std::string& source) {
  auto find = [&](std::int64_t id) -> const ObjectRecord& {
    for (const ObjectRecord& r : objects)
      if (r.id == id) return r;
    throw InputError("association: no object " + std::to_string(id));
  };
  Operation op{.time = time, .kind = "associate", .changes = {}, .map_edits = {}};
  auto change = [](std::int64_t id, ObjectStatus s, std::string reason, PoseCause cause) {
    return ObjectChange{.id = id, .status = s, .reason = std::move(reason), .source = "", .cloud = std::nullopt,
                        .T_map_gripper_grasp = std::nullopt, .cause = cause,
                        .transform = Eigen::Isometry3d::Identity()};
  };
  for (std::int64_t id : a.present)
    if (find(id).status == ObjectStatus::lost)
      op.changes.push_back(change(id, ObjectStatus::on_ground, "seen again at its stored pose", PoseCause::reassociated));
  for (const Association::Moved& m : a.moved) {
    const ObjectRecord& r = find(m.id);
    PointCloud cloud = r.cloud;
    transform_cloud(cloud, m.motion);
    char why[160];
    std::snprintf(why, sizeof(why), "%s: moved %.2f m, turned %.1f deg without a grasp",
                  r.status == ObjectStatus::lost ? "found again" : "bumped",
                  (m.motion * r.centroid - r.centroid).norm(), rotation_angle(m.motion.linear()) * 180.0 / std::numbers::pi);
    ObjectChange c = change(m.id, r.status == ObjectStatus::lost ? ObjectStatus::on_ground : r.status, why,
                            PoseCause::reassociated);
    c.cloud = std::move(cloud);
    c.transform = m.motion;
    op.changes.push_back(std::move(c));
  }
  for (std::int64_t id : a.vanished)
    if (find(id).status != ObjectStatus::lost)
      op.changes.push_back(change(id, ObjectStatus::lost,
                                  "not seen at its pose in the rescan, and no segment fits its model", PoseCause::lost));
  for (std::size_t i : a.new_segments) {
    ObjectChange c = change(0, ObjectStatus::on_ground, "", PoseCause::created);
    c.source = source;
    c.cloud = segments[i];
    op.changes.push_back(std::move(c));
  }
  return op;
}

}  // namespace cairn
