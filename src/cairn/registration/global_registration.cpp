#include "cairn/registration/global_registration.hpp"
#include "cairn/registration/global_steps.hpp"

#include <spdlog/spdlog.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <map>
#include <numeric>
#include <optional>
#include <random>

#include "cairn/core/cell_map.hpp"
#include "cairn/core/error.hpp"
#include "cairn/core/kdtree.hpp"
#include "cairn/core/plane.hpp"
#include "cairn/core/transform.hpp"
#include "cairn/core/units.hpp"

namespace cairn {
namespace {

constexpr std::uint64_t kLevellingSeed = 7;  // the levelling RANSAC is deterministic

/// Normals, ISS keypoints and SHOT descriptors of the set. Normals point away from their
/// segment's centroid (consistent between sensors that see an object from different sides) when
/// `outward`, else towards cfg.normals' viewpoint.
void describe(SegmentSet& s, const GlobalRegistrationConfig& cfg, Timings& t, const std::string& which,
              bool outward = true) {
  Stopwatch sw;
  s.tree = std::make_unique<KdTree>(s.points);
  NormalResult nr = estimate_normals(s.points, *s.tree, cfg.normals);
  for (std::size_t i = 0; outward && i < s.points.size(); ++i) {
    Vec3f& n = nr.normals[i];
    if (n.dot(s.points[i] - s.centroids[std::size_t(s.segment_of[i])]) < 0.0f) n = -n;
  }
  s.normals = std::move(nr.normals);
  s.keypoints = iss_keypoints(s.points, *s.tree, cfg.iss);
  t.add("keypoints_" + which, sw.lap_ms());
  std::vector<Vec3f> kp;
  kp.reserve(s.keypoints.size());
  for (std::uint32_t i : s.keypoints) kp.push_back(s.points[i]);
  s.descriptors = compute_shot(kp, s.points, s.normals, *s.tree, cfg.shot);
  t.add("descriptors_" + which, sw.lap_ms());
}

double tilt(const Eigen::Isometry3d& T) { return std::acos(std::clamp((T.linear() * Vec3d::UnitZ()).z(), -1.0, 1.0)); }

/// Steps 2-4a on two prepared sets: keypoints + descriptors (timed as keypoints, descriptors),
/// matching (timed), and the consistency groups (their time goes to the next lap: verification),
/// without those tilting z when gravity_aligned. Fills the counts of `r`.
std::vector<TransformCandidate> descriptor_candidates(SegmentSet& src, SegmentSet& tgt, const GlobalRegistrationConfig& cfg,
                                                      bool outward_normals, GlobalRegistrationResult& r, Stopwatch& sw) {
  Timings& t = r.timings;
  Timings inner;
  describe(src, cfg, inner, "source", outward_normals);
  describe(tgt, cfg, inner, "target", outward_normals);
  r.source_keypoints = src.keypoints.size();
  r.target_keypoints = tgt.keypoints.size();
  t.add("keypoints", inner.get("keypoints_source") + inner.get("keypoints_target"));
  t.add("descriptors", inner.get("descriptors_source") + inner.get("descriptors_target"));
  sw.lap_ms();
  const std::vector<Correspondence> matches = match_descriptors(src.descriptors, tgt.descriptors, cfg.matching);
  r.correspondences = matches.size();
  t.add("matching", sw.lap_ms());
  std::vector<Vec3f> src_kp, tgt_kp;
  for (std::uint32_t i : src.keypoints) src_kp.push_back(src.points[i]);
  for (std::uint32_t i : tgt.keypoints) tgt_kp.push_back(tgt.points[i]);
  std::vector<TransformCandidate> candidates;
  if (cfg.max_clique.enabled) {
    CliqueEstimate e = max_clique_registration(src_kp, tgt_kp, matches, cfg.max_clique);
    spdlog::debug("registration: max clique of {} / {} correspondences ({} edges, {}, {} nodes)",
                  e.clique.vertices.size(), e.pairs.size(), e.edges, e.clique.exact ? "exact" : "budget reached",
                  e.clique.nodes);
    candidates = std::move(e.candidates);
  } else {
    candidates = geometric_consistency_grouping(src_kp, tgt_kp, matches, cfg.grouping);
  }
  if (cfg.gravity_aligned)
    std::erase_if(candidates, [&](const TransformCandidate& c) { return tilt(c.T_target_source) > cfg.max_tilt_deg * kDeg; });
  r.candidates = candidates.size();  // descriptor candidates (the paper's b)
  return candidates;
}

/// The two ICP passes of step 5 from T: coarse_correspondence_distance on the source thinned to
/// coarse_source_voxel, then the configured one on every point. A pass that fails (too few pairs,
/// degenerate) leaves T as it was. Returns T and the second pass's RMSE.
std::pair<Eigen::Isometry3d, double> refine_two_pass(std::span<const Vec3f> source, const IcpTarget& target,
                                                     Eigen::Isometry3d T, const GlobalRegistrationConfig& cfg) {
  IcpConfig icp = cfg.icp;
  icp.four_dof = cfg.gravity_aligned || cfg.icp.four_dof;
  IcpConfig coarse = icp;
  coarse.max_correspondence_distance = cfg.coarse_correspondence_distance;
  const auto usable = [](const IcpResult& x) {
    return x.status != IcpStatus::too_few_correspondences && x.status != IcpStatus::degenerate;
  };
  PointCloud thinned;
  std::span<const Vec3f> coarse_source = source;
  if (cfg.coarse_source_voxel > 0.0) {
    thinned.points.assign(source.begin(), source.end());
    thinned = voxel_downsample(thinned, {.res_voxel = cfg.coarse_source_voxel, .n_min = 1});
    // A small segment set keeps every point unless thinning leaves kCoarseMinPairsFactor times
    // ICP's minimum of pairs (only the overlapping part of the source finds pairs).
    constexpr std::size_t kCoarseMinPairsFactor = 4;
    if (thinned.size() >= kCoarseMinPairsFactor * std::size_t(std::max(coarse.min_correspondences, 1)))
      coarse_source = thinned.points;
  }
  const IcpResult r1 = register_icp(coarse_source, target, T, coarse);
  if (usable(r1)) T = r1.T_target_source;
  const IcpResult r2 = register_icp(source, target, T, icp);
  if (usable(r2)) T = r2.T_target_source;
  return {T, r2.rmse};
}

/// The matched segment pairs' points for the scale check, the source's moved by T.
std::vector<SegmentPair> segment_pairs(const SegmentSet& src, const SegmentSet& tgt, const CentroidMatch& v,
                                       const Eigen::Isometry3d& T) {
  const Eigen::Isometry3f Tf = T.cast<float>();
  std::vector<SegmentPair> out;
  for (const auto& [si, ti] : v.pairs) {
    SegmentPair p;
    for (std::uint32_t i : src.members[std::size_t(si)]) p.source.push_back(Tf * src.points[i]);
    for (std::uint32_t i : tgt.members[std::size_t(ti)]) {
      p.target.push_back(tgt.points[i]);
      p.target_normals.push_back(tgt.normals[i]);
    }
    out.push_back(std::move(p));
  }
  return out;
}

/// The clouds' world frames from T_local, a transform between the levelled source's and the
/// target's local coordinates (p_world_source = origin + p_local).
Eigen::Isometry3d world_transform(const Eigen::Isometry3d& T_local, const Vec3d& source_origin,
                                  const Vec3d& target_origin, const Eigen::Matrix3d& R_level) {
  Eigen::Isometry3d T = Eigen::Translation3d(target_origin) * T_local;
  T.linear() = T.linear() * R_level;
  T.translation() -= T.linear() * source_origin;
  return T;
}

CandidateReport candidate_report(const Eigen::Isometry3d& T, const char* origin, std::size_t votes) {
  CandidateReport rep;
  rep.origin = origin;
  rep.votes = votes;
  rep.T_target_source = T;
  return rep;
}

/// Target + the source moved by T (target local frame), voxelised at merge_voxel.
PointCloud merged_map(const PointCloud& target, std::span<const Vec3f> source, const Eigen::Isometry3d& T,
                      const GlobalRegistrationConfig& cfg) {
  const Eigen::Isometry3f Tf = T.cast<float>();
  PointCloud all;
  all.origin = target.origin;
  all.points = target.points;
  all.points.reserve(target.size() + source.size());
  for (const Vec3f& p : source) all.points.push_back(Tf * p);
  return voxel_downsample(all, {.res_voxel = cfg.merge_voxel, .n_min = 1});
}

/// The accepted report's figures and transform (world frames) as the result.
void take_accepted(const CandidateReport& best, const Eigen::Isometry3d& T_world, GlobalRegistrationResult& r) {
  r.success = true;
  r.rmse = best.rmse;
  r.overlap = best.overlap;
  r.T_target_source = T_world;
}

/// A failed registration's figures, when nothing else measured them: those of the refined
/// candidate that overlapped most.
void report_best_refined(GlobalRegistrationResult& r) {
  if (r.rmse != 0.0) return;
  const CandidateReport* best = nullptr;
  for (const CandidateReport& rep : r.reports)
    if (rep.refined && (best == nullptr || rep.overlap > best->overlap)) best = &rep;
  if (best == nullptr) return;
  r.rmse = best->rmse;
  r.overlap = best->overlap;
}

/// Descriptor-only registration of the whole clouds (config.segments = false): ISS + SHOT on
/// everything, consistency grouping, ICP from each of the max_refinements most-voted distinct
/// candidates, the accepted one with the largest mutual overlap wins.
GlobalRegistrationResult register_whole(const PointCloud& source, const PointCloud& target,
                                        const GlobalRegistrationConfig& cfg) {
  GlobalRegistrationResult r;
  Timings& t = r.timings;
  Stopwatch sw;
  r.source_voxelised = voxel_downsample(source, cfg.source_voxel);
  r.source_points = r.source_voxelised.size();
  r.target_points = target.size();
  SegmentSet src = whole_cloud(r.source_voxelised.points), tgt = whole_cloud(target.points);
  t.add("segmentation_source", sw.lap_ms());  // no segmentation: the source's voxel grid
  t.add("segmentation_target", 0.0);
  const auto to_world = [&](const Eigen::Isometry3d& T) {
    return world_transform(T, source.origin, target.origin, Eigen::Matrix3d::Identity());
  };
  for (const TransformCandidate& c : descriptor_candidates(src, tgt, cfg, false, r, sw)) {
    r.reports.push_back(candidate_report(c.T_target_source, "descriptors", c.votes));
    r.reports.back().T_world = to_world(c.T_target_source);
  }
  t.add("verification", sw.lap_ms());

  const IcpTarget icp_target(tgt.points, tgt.normals);
  const auto refine = [&](std::size_t, const Eigen::Isometry3d& T0) {
    const auto [T, icp_rmse] = refine_two_pass(src.points, icp_target, T0, cfg);
    return Refinement{.T = T, .icp_rmse = icp_rmse,
                      .overlap = mutual_overlap(src.points, tgt.points, T, cfg.acceptance.overlap_distance),
                      .matched = std::nullopt};
  };
  int refined = 0;
  const std::optional<std::size_t> accepted =
      refine_and_accept(r.reports, [](std::size_t) { return true; }, refine, to_world, cfg.acceptance,
                        {.largest_overlap = true, .refine_all = true, .max_refinements = cfg.max_refinements}, refined);
  t.add("refinement", sw.lap_ms());
  if (!accepted) {
    r.reason = refined > 0 ? "no refined candidate passes the acceptance test"
                           : "no geometrically consistent group of correspondences";
    report_best_refined(r);
    t.add("merge", 0.0);
    return r;
  }
  const CandidateReport& best = r.reports[*accepted];
  take_accepted(best, to_world(best.T_target_source), r);
  r.merged_map = merged_map(target, src.points, best.T_target_source, cfg);
  t.add("merge", sw.lap_ms());
  return r;
}

/// The rotation turning the ground normal `n` onto `up`; identity without a ground plane.
Eigen::Matrix3d turn_onto(const std::optional<Vec3d>& n, const Vec3d& up) {
  if (!n) return Eigen::Matrix3d::Identity();
  return Eigen::Quaterniond::FromTwoVectors(*n, up.normalized()).toRotationMatrix();
}

/// Step 1's levelling: the rotation turning the source's ground onto the target's ground plane
/// (not onto z, so that both are segmented alike and the remaining unknowns are a yaw and a
/// translation, up to the plane fits' noise). Identity when the source is gravity-aligned.
Eigen::Matrix3d source_levelling(const PointCloud& source, const PointCloud& target, const GlobalRegistrationConfig& cfg) {
  if (cfg.gravity_aligned) return Eigen::Matrix3d::Identity();
  // Two independent fits (each its own seeded RANSAC, serial inside): both at once.
  std::optional<Vec3d> up_target, n_source;
  tbb::parallel_invoke([&] { up_target = ground_normal(target.points, cfg.levelling); },
                       [&] { n_source = ground_normal(source.points, cfg.levelling); });
  if (up_target && up_target->z() < 0.0) *up_target = -*up_target;  // the map's z is up
  return turn_onto(n_source, up_target.value_or(Vec3d::UnitZ()));
}

/// Step 1's segmentation of the levelled source (seen from above: its own terrain check
/// threshold when configured) and of the target, timed.
void segment_both(const PointCloud& levelled, const PointCloud& target, const SegmentationConfig& segmentation,
                  const GlobalRegistrationConfig& cfg, GlobalRegistrationResult& r, Stopwatch& sw) {
  SegmentationConfig source_segmentation = segmentation;
  if (cfg.source_min_stacked_fraction >= 0.0)
    source_segmentation.verticality.min_stacked_fraction = cfg.source_min_stacked_fraction;
  r.source_segmentation = segment(levelled, source_segmentation);
  r.timings.add("segmentation_source", sw.lap_ms());
  r.target_segmentation = segment(target, segmentation);
  r.timings.add("segmentation_target", sw.lap_ms());
}

/// Steps 2-4: the descriptor candidates and the centroid hypotheses, each verified against the
/// segment centroids, into r.reports in the verification order (most matched centroids first,
/// ties the smaller largest distance). Returns each report's centroid matching.
std::vector<CentroidMatch> verified_reports(SegmentSet& src, SegmentSet& tgt, const GlobalRegistrationConfig& cfg,
                                            const std::function<Eigen::Isometry3d(const Eigen::Isometry3d&)>& to_world,
                                            GlobalRegistrationResult& r, Stopwatch& sw) {
  std::vector<CandidateReport> reports;
  std::vector<CentroidMatch> verified;
  for (const TransformCandidate& c : descriptor_candidates(src, tgt, cfg, true, r, sw)) {
    reports.push_back(candidate_report(c.T_target_source, "descriptors", c.votes));
    verified.push_back(match_centroids(src.centroids, tgt.centroids, c.T_target_source, cfg.d_match));
  }
  if (cfg.centroid_hypotheses) {
    for (auto& [H, v] : centroid_hypotheses(src.centroids, tgt.centroids, cfg)) {
      reports.push_back(candidate_report(H, "centroids", 0));
      verified.push_back(std::move(v));
      ++r.centroid_candidates;
    }
  }
  std::vector<std::size_t> order(reports.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    if (verified[a].inliers != verified[b].inliers) return verified[a].inliers > verified[b].inliers;
    return verified[a].max_distance < verified[b].max_distance;
  });
  std::vector<CentroidMatch> sorted;
  for (std::size_t k : order) {
    CandidateReport& rep = r.reports.emplace_back(std::move(reports[k]));
    rep.centroid_inliers = verified[k].inliers;
    rep.max_centroid_distance = verified[k].max_distance;
    rep.T_world = to_world(rep.T_target_source);
    sorted.push_back(std::move(verified[k]));
  }
  r.timings.add("verification", sw.lap_ms());
  return sorted;
}

/// Step 5 on one candidate: ICP on its matched segments only (the target's with normals) from
/// T0, the mutual overlap there and the centroid matching after refinement.
Refinement refine_matched(const SegmentSet& src, const SegmentSet& tgt, const CentroidMatch& v,
                          const Eigen::Isometry3d& T0, const GlobalRegistrationConfig& cfg) {
  std::vector<Vec3f> sp, tp, tn;
  for (const auto& [si, ti] : v.pairs) {
    for (std::uint32_t i : src.members[std::size_t(si)]) sp.push_back(src.points[i]);
    for (std::uint32_t i : tgt.members[std::size_t(ti)]) {
      tp.push_back(tgt.points[i]);
      tn.push_back(tgt.normals[i]);
    }
  }
  const IcpTarget icp_target(tp, tn);
  const auto [T, icp_rmse] = refine_two_pass(sp, icp_target, T0, cfg);
  return {.T = T, .icp_rmse = icp_rmse, .overlap = mutual_overlap(sp, tp, T, cfg.acceptance.overlap_distance),
          .matched = match_centroids(src.centroids, tgt.centroids, T, cfg.d_match)};
}

/// Step 5b (beyond the paper): the matched segments, spread over the site, aligned one by one
/// must not fit a similarity of another scale. A rigid fit of a wrongly scaled source passes the
/// overlap test near the site's centre and is wrong by decimetres at its edges; a larger error
/// fails the overlap test, and the candidate with the most matched segments tells why. Refuses
/// the accepted candidate (reason "scale: ...") when the scale is off by more than allowed.
void check_scale(const SegmentSet& src, const SegmentSet& tgt,
                 const std::map<std::size_t, std::pair<Eigen::Isometry3d, CentroidMatch>>& refined,
                 const GlobalRegistrationConfig& cfg, std::optional<std::size_t>& accepted, GlobalRegistrationResult& r) {
  std::optional<std::size_t> checked = accepted;
  for (const auto& [rank, candidate] : refined)
    if (!checked || (!accepted && candidate.second.inliers > refined.at(*checked).second.inliers)) checked = rank;
  if (!checked) return;
  const auto& [T, pairs] = refined.at(*checked);
  r.scale_fit = fit_scale(segment_pairs(src, tgt, pairs, T), cfg.scale_check);
  if (!r.scale_fit.observable || std::abs(r.scale_fit.scale - 1.0) <= cfg.scale_check.max_scale_error) return;
  char why[240];
  std::snprintf(why, sizeof why,
                "scale: a rigid fit cannot explain the matches, the source is %.1f %% %s than the target "
                "(recover its scale, or estimate it: registration.scale_check.estimate / --estimate-scale)",
                100.0 * std::abs(1.0 / r.scale_fit.scale - 1.0), r.scale_fit.scale > 1.0 ? "smaller" : "larger");
  r.reason = why;
  if (accepted) r.reports[*accepted].accepted = false;  // refused after all
  accepted.reset();
  r.rmse = r.reports[*checked].rmse;  // the figures of the candidate the check refused
  r.overlap = r.reports[*checked].overlap;
}

/// Why a segment-based registration found nothing (unless a step already said).
std::string failure_reason(const GlobalRegistrationResult& r, int refined, const GlobalRegistrationConfig& cfg) {
  if (!r.reason.empty()) return r.reason;
  if (refined > 0) return "no refined candidate passes the acceptance test";
  if (r.candidates + r.centroid_candidates == 0)
    return "no geometrically consistent group of correspondences and no centroid hypothesis";
  return "no candidate matches " + std::to_string(cfg.acceptance.min_matched_segments) +
         " segment centroids within d_match";
}

}  // namespace

CentroidMatch match_centroids(std::span<const Vec3f> source_centroids, std::span<const Vec3f> target_centroids,
                              const Eigen::Isometry3d& T, double d_match) {
  struct Pair {
    double d;
    std::int32_t s, t;
  };
  std::vector<Pair> pairs;
  for (std::size_t i = 0; i < source_centroids.size(); ++i) {
    const Vec3d p = T * source_centroids[i].cast<double>();
    for (std::size_t j = 0; j < target_centroids.size(); ++j) {
      const double d = (p - target_centroids[j].cast<double>()).norm();
      if (d < d_match) pairs.push_back({d, std::int32_t(i), std::int32_t(j)});
    }
  }
  std::sort(pairs.begin(), pairs.end(), [](const Pair& a, const Pair& b) {
    return a.d != b.d ? a.d < b.d : (a.s != b.s ? a.s < b.s : a.t < b.t);
  });
  std::vector<char> used_s(source_centroids.size(), 0), used_t(target_centroids.size(), 0);
  CentroidMatch v;
  for (const Pair& p : pairs) {
    if (used_s[std::size_t(p.s)] || used_t[std::size_t(p.t)]) continue;
    used_s[std::size_t(p.s)] = used_t[std::size_t(p.t)] = 1;
    v.pairs.emplace_back(p.s, p.t);
    v.max_distance = std::max(v.max_distance, p.d);
  }
  v.inliers = int(v.pairs.size());
  std::sort(v.pairs.begin(), v.pairs.end());
  return v;
}

void GlobalRegistrationConfig::validate() const {
  if (!(source_voxel.res_voxel > 0.0)) throw ConfigError("registration.source_voxel.res_voxel must be positive");
  if (!(d_match > 0.0)) throw ConfigError("registration.d_match must be a positive number of metres");
  if (max_refinements < 1) throw ConfigError("registration.max_refinements must be at least 1");
  if (max_clique.enabled) max_clique.validate();
  if (!(coarse_correspondence_distance > 0.0))
    throw ConfigError("registration.coarse_correspondence_distance must be positive");
  if (!(coarse_source_voxel >= 0.0))
    throw ConfigError("registration.coarse_source_voxel must be 0 (every point) or a positive voxel size");
  if (!(acceptance.e_icp > 0.0)) throw ConfigError("registration.acceptance.e_icp must be positive");
  if (!(acceptance.overlap_distance > 0.0)) throw ConfigError("registration.acceptance.overlap_distance must be positive");
  if (!(acceptance.min_overlap >= 0.0 && acceptance.min_overlap <= 1.0))
    throw ConfigError("registration.acceptance.min_overlap must be in [0, 1]");
  if (acceptance.min_matched_segments < 1)
    throw ConfigError("registration.acceptance.min_matched_segments must be at least 1");
  if (!(merge_voxel > 0.0)) throw ConfigError("registration.merge_voxel must be positive");
  if (!(absorb_distance >= 0.0)) throw ConfigError("registration.absorb_distance must be >= 0");
  if (!(levelling.plane_distance > 0.0 && levelling.refit_band > 0.0 && levelling.sign_cell > 0.0))
    throw ConfigError("registration.levelling distances must be positive");
  if (!(levelling.min_share >= 0.0 && levelling.min_share <= 1.0))
    throw ConfigError("registration.levelling.min_share must be in [0, 1]");
  if (!(max_tilt_deg >= 0.0)) throw ConfigError("registration.max_tilt_deg must be >= 0");
  icp.validate();
  scale_check.validate();
}

RegistrationError registration_error(const Similarity& estimate, const Similarity& truth, const Vec3d& at) {
  const Similarity E = estimate * truth.inverse();
  return {.rotation_deg = rotation_angle(E.rotation) / kDeg,
          .translation_m = (E * at - at).norm(),
          .scale_ratio = estimate.scale / truth.scale};
}

std::optional<Vec3d> ground_normal(std::span<const Vec3f> points, const LevellingConfig& cfg) {
  if (points.size() < 3) return std::nullopt;
  std::mt19937_64 rng(kLevellingSeed);
  RansacPlaneConfig rc;
  rc.distance = cfg.plane_distance;
  const PlaneFit fit = fit_plane_ransac(points, {}, rc, rng);
  if (!fit.found || double(fit.inliers.size()) < cfg.min_share * double(points.size())) return std::nullopt;
  // RANSAC keeps the best flat patch; on undulating terrain that patch can be tilted by a few
  // degrees against the site's mean ground. Refit by least squares over a wider band, a few times.
  Plane plane = fit.plane;
  std::vector<std::uint32_t> band;
  for (int it = 0; it < cfg.refits; ++it) {
    band.clear();
    for (std::uint32_t i = 0; i < points.size(); ++i)
      if (std::abs(plane.signed_distance(points[i])) < float(cfg.refit_band)) band.push_back(i);
    const std::optional<Plane> refit = band.size() >= 3 ? fit_plane(points, band) : std::nullopt;
    if (!refit) break;
    plane = *refit;
  }
  Vec3d n = plane.normal.cast<double>().normalized();

  // Sign: objects stand on the ground, pits are rare. In cells of the plane, the heights of a
  // cell holding part of a stone have a long tail to one side (the stone's top); the side most
  // such cells agree on is "up". A site-wide count of points above/below is fooled by terrain
  // that curves away from the plane.
  const Vec3d u = n.unitOrthogonal(), v = n.cross(u);
  const double cell = cfg.sign_cell;
  CellMap index;  // plane cell -> position in `cells`
  std::vector<std::vector<float>> cells;
  for (const Vec3f& p : points) {
    const Vec3d q = p.cast<double>();
    const auto cx = std::int64_t(std::floor(u.dot(q) / cell)), cy = std::int64_t(std::floor(v.dot(q) / cell));
    const auto next = std::uint32_t(cells.size());
    const std::uint32_t at = index.insert(CellMap::key(cx, cy, 0), next);
    if (at == next) cells.emplace_back();
    cells[at].push_back(plane.signed_distance(p));
  }
  int up = 0, down = 0;
  for (std::vector<float>& h : cells) {
    if (h.size() < cfg.sign_min_points) continue;
    const auto at = [&](double q) {
      auto it = h.begin() + std::ptrdiff_t(q * double(h.size() - 1));
      std::nth_element(h.begin(), it, h.end());
      return double(*it);
    };
    const double lo = at(0.05), med = at(0.5), hi = at(0.95);
    const double above = hi - med, below = med - lo;
    if (std::max(above, below) < cfg.sign_min_tail) continue;
    if (above > cfg.sign_tail_ratio * below) ++up;
    if (below > cfg.sign_tail_ratio * above) ++down;
  }
  if (down > up) n = -n;
  return n;
}

Eigen::Matrix3d levelling_rotation(std::span<const Vec3f> points, const Vec3d& up, const LevellingConfig& cfg) {
  return turn_onto(ground_normal(points, cfg), up);
}

GlobalRegistrationResult register_global(const PointCloud& source, const PointCloud& target,
                                         const SegmentationConfig& segmentation, const GlobalRegistrationConfig& cfg) {
  cfg.validate();
  if (source.empty()) throw InputError("registration: the source cloud is empty");
  if (target.empty()) throw InputError("registration: the target cloud is empty");
  source.check_finite("registration source");
  target.check_finite("registration target");
  if (!cfg.segments) return register_whole(source, target, cfg);
  GlobalRegistrationResult r;
  Timings& t = r.timings;
  Stopwatch sw;

  // 1. Voxel grid on the source, levelling, segmentation of both.
  r.source_voxelised = voxel_downsample(source, cfg.source_voxel);
  const Eigen::Matrix3d R_level = source_levelling(r.source_voxelised, target, cfg);
  PointCloud levelled = r.source_voxelised;
  levelled.normals.clear();
  const Eigen::Matrix3f Rf = R_level.cast<float>();
  for (Vec3f& p : levelled.points) p = Rf * p;
  r.source_points = levelled.size();
  r.target_points = target.size();
  segment_both(levelled, target, segmentation, cfg, r, sw);
  SegmentSet src = collect_segments(levelled.points, r.source_segmentation);
  SegmentSet tgt = collect_segments(target.points, r.target_segmentation);
  r.source_segments = src.ids.size();
  r.target_segments = tgt.ids.size();
  const auto to_world = [&](const Eigen::Isometry3d& T) { return world_transform(T, source.origin, target.origin, R_level); };
  if (src.ids.empty() || tgt.ids.empty()) {
    r.reason = src.ids.empty() ? "no object segments in the source" : "no object segments in the target";
    for (const char* s : {"keypoints", "descriptors", "matching", "verification", "refinement", "merge"}) t.add(s, 0.0);
    return r;
  }

  // 2.-4. Keypoints and descriptors on the object segments, matching, consistency groups,
  // centroid hypotheses, verification.
  const std::vector<CentroidMatch> verified = verified_reports(src, tgt, cfg, to_world, r, sw);

  // 5. ICP on the matched segments, acceptance test; 5b. scale check.
  std::map<std::size_t, std::pair<Eigen::Isometry3d, CentroidMatch>> refined_pairs;
  const auto refine = [&](std::size_t rank, const Eigen::Isometry3d& T0) {
    Refinement f = refine_matched(src, tgt, verified[rank], T0, cfg);
    refined_pairs[rank] = {f.T, *f.matched};
    return f;
  };
  const auto eligible = [&](std::size_t rank) { return verified[rank].inliers >= cfg.acceptance.min_matched_segments; };
  int refined = 0;
  std::optional<std::size_t> accepted =
      refine_and_accept(r.reports, eligible, refine, to_world, cfg.acceptance,
                        {.largest_overlap = false, .refine_all = cfg.refine_all, .max_refinements = cfg.max_refinements},
                        refined);
  t.add("refinement", sw.lap_ms());
  check_scale(src, tgt, refined_pairs, cfg, accepted, r);
  t.add("scale_check", sw.lap_ms());
  if (!accepted) {
    r.reason = failure_reason(r, refined, cfg);
    report_best_refined(r);
    t.add("merge", 0.0);
    return r;
  }
  const CandidateReport& best = r.reports[*accepted];
  take_accepted(best, to_world(best.T_target_source), r);
  const CentroidMatch& pairs = refined_pairs.at(*accepted).second;
  for (const auto& [si, ti] : pairs.pairs) r.matched_segments.emplace_back(src.ids[std::size_t(si)], tgt.ids[std::size_t(ti)]);

  // 6. Merge: matched segment pairs, and the aligned source into the map (target frame).
  merge_objects(src, tgt, pairs, best.T_target_source, target.origin, cfg, r);
  r.merged_map = merged_map(target, levelled.points, best.T_target_source, cfg);
  t.add("merge", sw.lap_ms());
  return r;
}

}  // namespace cairn
