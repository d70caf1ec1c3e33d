#include "cairn/registration/global_registration.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <numeric>
#include <optional>
#include <random>
#include <unordered_map>

#include "cairn/core/error.hpp"
#include "cairn/core/kdtree.hpp"
#include "cairn/core/plane.hpp"
#include "cairn/core/transform.hpp"
#include "cairn/core/units.hpp"

namespace cairn {
namespace {

constexpr std::uint64_t kLevellingSeed = 7;  // the levelling RANSAC is deterministic
// Two coarse candidates closer than this are one alignment (ICP's basin is wider).
constexpr double kSameCandidateDistance = 0.2;               // [m]
constexpr double kSameCandidateAngle = 2.0 * kDeg;      // [rad]

/// The object segments of one cloud, in the cloud's local coordinates (levelled for the source).
struct SegmentSet {
  std::vector<Vec3f> points;               // all object-segment points
  std::vector<std::int32_t> segment_of;    // segment index (into ids) per point
  std::vector<std::int32_t> ids;           // segment id per segment index
  std::vector<std::vector<std::uint32_t>> members;  // per segment index: indices into points
  std::vector<Vec3f> centroids;            // per segment index
  std::vector<Vec3f> normals;              // per point, oriented away from its segment's centroid
  std::vector<std::uint32_t> keypoints;    // indices into points
  ShotDescriptors descriptors;
  std::unique_ptr<KdTree> tree;
};

SegmentSet collect_segments(std::span<const Vec3f> points, const SegmentationResult& seg) {
  SegmentSet s;
  for (const Segment& g : seg.segments) {
    if (g.planar) continue;  // planar segments are not objects (Sec. 4.3)
    const auto k = std::int32_t(s.ids.size());
    s.ids.push_back(g.id);
    s.members.emplace_back();
    Vec3d c = Vec3d::Zero();
    for (std::uint32_t i : g.indices) {
      s.members.back().push_back(std::uint32_t(s.points.size()));
      s.points.push_back(points[i]);
      s.segment_of.push_back(k);
      c += points[i].cast<double>();
    }
    s.centroids.push_back((c / double(std::max<std::size_t>(1, g.indices.size()))).cast<float>());
  }
  return s;
}

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

using Verification = CentroidMatch;

Verification verify_centroids(const SegmentSet& src, const SegmentSet& tgt, const Eigen::Isometry3d& T,
                              double d_match) {
  return match_centroids(src.centroids, tgt.centroids, T, d_match);
}

struct Overlap {
  double rmse = 0.0, share = 0.0;
};

/// RMSE over the mutually overlapping points of the two point sets (source moved by T).
Overlap mutual_overlap(std::span<const Vec3f> source, std::span<const Vec3f> target, const Eigen::Isometry3d& T,
                       double distance) {
  std::vector<Vec3f> moved(source.size());
  const Eigen::Isometry3f Tf = T.cast<float>();
  for (std::size_t i = 0; i < source.size(); ++i) moved[i] = Tf * source[i];
  const KdTree tt(target), ts(moved);
  // Fixed chunks summed in order: the same result on any number of threads.
  const auto sum_within = [distance](std::span<const Vec3f> q, const KdTree& tree) {
    if (tree.size() == 0) return std::pair{0.0, std::size_t{0}};
    constexpr std::size_t kQueryChunk = 1024;
    const std::size_t chunks = (q.size() + kQueryChunk - 1) / kQueryChunk;
    std::vector<double> sq(chunks, 0.0);
    std::vector<std::size_t> n(chunks, 0);
    tbb::parallel_for(std::size_t(0), chunks, [&](std::size_t c) {
      for (std::size_t i = c * kQueryChunk; i < std::min(q.size(), (c + 1) * kQueryChunk); ++i) {
        float d2 = 0.0f;
        (void)tree.nearest(q[i], &d2);
        if (double(d2) < distance * distance) {
          sq[c] += double(d2);
          ++n[c];
        }
      }
    });
    return std::pair{std::accumulate(sq.begin(), sq.end(), 0.0), std::accumulate(n.begin(), n.end(), std::size_t{0})};
  };
  const auto [sq_s, n_s] = sum_within(moved, tt);
  const auto [sq_t, n_t] = sum_within(target, ts);
  Overlap o;
  const std::size_t n = n_s + n_t;
  o.rmse = n ? std::sqrt((sq_s + sq_t) / double(n)) : std::numeric_limits<double>::infinity();
  o.share = double(n) / double(std::max<std::size_t>(1, source.size() + target.size()));
  return o;
}

/// Yaw + translation hypotheses from pairs of centroids: source pair (i, j) onto target pair
/// (k, l) when their horizontal lengths agree within d_match; each verified against all centroids.
/// Unordered source pairs against ordered target pairs give every distinct hypothesis once; the
/// target pairs are sorted by length so that only those within d_match are visited.
std::vector<std::pair<Eigen::Isometry3d, Verification>> centroid_candidates(const SegmentSet& src, const SegmentSet& tgt,
                                                                              const GlobalRegistrationConfig& cfg) {
  std::vector<std::pair<Eigen::Isometry3d, Verification>> out;
  const auto& S = src.centroids;
  const auto& T = tgt.centroids;
  struct TargetPair {
    double length;
    std::size_t k, l;
  };
  std::vector<TargetPair> target_pairs;
  for (std::size_t k = 0; k < T.size(); ++k)
    for (std::size_t l = 0; l < T.size(); ++l)
      if (k != l) target_pairs.push_back({(T[l] - T[k]).head<2>().cast<double>().norm(), k, l});
  std::sort(target_pairs.begin(), target_pairs.end(), [](const TargetPair& a, const TargetPair& b) {
    return a.length != b.length ? a.length < b.length : (a.k != b.k ? a.k < b.k : a.l < b.l);
  });
  for (std::size_t i = 0; i < S.size(); ++i)
    for (std::size_t j = i + 1; j < S.size(); ++j) {
      const Eigen::Vector2d a = (S[j] - S[i]).head<2>().cast<double>();
      if (a.norm() < cfg.min_centroid_baseline) continue;
      auto it = std::lower_bound(target_pairs.begin(), target_pairs.end(), a.norm() - cfg.d_match,
                                 [](const TargetPair& p, double len) { return p.length < len; });
      for (; it != target_pairs.end() && it->length <= a.norm() + cfg.d_match; ++it) {
        const Eigen::Vector2d b = (T[it->l] - T[it->k]).head<2>().cast<double>();
        const double yaw = std::atan2(b.y(), b.x()) - std::atan2(a.y(), a.x());
        Eigen::Isometry3d H = Eigen::Isometry3d::Identity();
        H.linear() = Eigen::AngleAxisd(yaw, Vec3d::UnitZ()).toRotationMatrix();
        const Vec3d ms = 0.5 * (S[i] + S[j]).cast<double>(), mt = 0.5 * (T[it->k] + T[it->l]).cast<double>();
        H.translation() = mt - H.linear() * ms;
        Verification v = verify_centroids(src, tgt, H, cfg.d_match);
        if (v.inliers >= cfg.acceptance.min_matched_segments) out.emplace_back(H, std::move(v));
      }
    }
  std::stable_sort(out.begin(), out.end(), [](const auto& a, const auto& b) {
    if (a.second.inliers != b.second.inliers) return a.second.inliers > b.second.inliers;
    return a.second.max_distance < b.second.max_distance;
  });
  // Keep distinct hypotheses only (the same alignment arises from many pairs).
  std::vector<std::pair<Eigen::Isometry3d, Verification>> distinct;
  for (auto& c : out) {
    const bool dup = std::any_of(distinct.begin(), distinct.end(), [&](const auto& d) {
      return (d.first.translation() - c.first.translation()).norm() < 0.5 * cfg.d_match &&
             rotation_angle(d.first.linear().transpose() * c.first.linear()) < 5.0 * kDeg;
    });
    if (!dup) distinct.push_back(std::move(c));
    if (int(distinct.size()) >= cfg.max_centroid_candidates) break;
  }
  return distinct;
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
  std::vector<TransformCandidate> candidates = geometric_consistency_grouping(src_kp, tgt_kp, matches, cfg.grouping);
  if (cfg.gravity_aligned)
    std::erase_if(candidates, [&](const TransformCandidate& c) { return tilt(c.T_target_source) > cfg.max_tilt_deg * kDeg; });
  r.candidates = candidates.size();  // descriptor candidates (the paper's b)
  return candidates;
}

/// True when `T` is (within ICP's basin) one of the alignments already tried.
bool already_tried(const std::vector<Eigen::Isometry3d>& tried, const Eigen::Isometry3d& T) {
  return std::any_of(tried.begin(), tried.end(), [&](const Eigen::Isometry3d& T0) {
    return (T0.translation() - T.translation()).norm() < kSameCandidateDistance &&
           rotation_angle(T0.linear().transpose() * T.linear()) < kSameCandidateAngle;
  });
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
std::vector<SegmentPair> segment_pairs(const SegmentSet& src, const SegmentSet& tgt, const Verification& v,
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

/// The whole cloud as one set (segments = false).
SegmentSet whole_cloud(std::span<const Vec3f> points) {
  SegmentSet s;
  s.points.assign(points.begin(), points.end());
  s.segment_of.assign(points.size(), 0);
  s.ids.push_back(-1);
  s.members.emplace_back(points.size());
  std::iota(s.members.back().begin(), s.members.back().end(), std::uint32_t{0});
  Vec3d c = Vec3d::Zero();
  for (const Vec3f& p : points) c += p.cast<double>();
  s.centroids.push_back((c / double(std::max<std::size_t>(1, points.size()))).cast<float>());
  return s;
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
  const std::vector<TransformCandidate> candidates = descriptor_candidates(src, tgt, cfg, false, r, sw);
  const auto to_world = [&](const Eigen::Isometry3d& T_local) {
    Eigen::Isometry3d T = Eigen::Translation3d(target.origin) * T_local;
    T.translation() -= T.linear() * source.origin;
    return T;
  };
  for (const TransformCandidate& c : candidates) {
    CandidateReport rep;
    rep.votes = c.votes;
    rep.T_target_source = c.T_target_source;
    rep.T_world = to_world(c.T_target_source);
    r.reports.push_back(rep);
  }
  t.add("verification", sw.lap_ms());

  const IcpTarget icp_target(tgt.points, tgt.normals);
  std::vector<Eigen::Isometry3d> tried;
  std::optional<std::size_t> accepted;
  int refined = 0;
  for (std::size_t rank = 0; rank < r.reports.size() && refined < cfg.max_refinements; ++rank) {
    CandidateReport& rep = r.reports[rank];
    if (already_tried(tried, rep.T_target_source)) continue;
    tried.push_back(rep.T_target_source);
    ++refined;
    const auto [T, icp_rmse] = refine_two_pass(src.points, icp_target, rep.T_target_source, cfg);
    const Overlap o = mutual_overlap(src.points, tgt.points, T, cfg.acceptance.overlap_distance);
    tried.push_back(T);  // later candidates that start where this one ended are the same
    rep.refined = true;
    rep.T_target_source = T;
    rep.T_world = to_world(T);
    rep.rmse = o.rmse;
    rep.overlap = o.share;
    rep.icp_rmse = icp_rmse;
    rep.accepted = o.rmse < cfg.acceptance.e_icp && o.share >= cfg.acceptance.min_overlap;
    if (rep.accepted && (!accepted || rep.overlap > r.reports[*accepted].overlap)) accepted = rank;
  }
  t.add("refinement", sw.lap_ms());
  if (!accepted) {
    r.reason = refined > 0 ? "no refined candidate passes the acceptance test"
                           : "no geometrically consistent group of correspondences";
    const auto best = std::max_element(r.reports.begin(), r.reports.end(), [](const auto& a, const auto& b) {
      return a.refined != b.refined ? b.refined : a.overlap < b.overlap;
    });
    if (best != r.reports.end() && best->refined) {
      r.rmse = best->rmse;
      r.overlap = best->overlap;
    }
    t.add("merge", 0.0);
    return r;
  }
  const CandidateReport& best = r.reports[*accepted];
  r.success = true;
  r.rmse = best.rmse;
  r.overlap = best.overlap;
  r.T_target_source = to_world(best.T_target_source);
  const Eigen::Isometry3f Tf = best.T_target_source.cast<float>();
  PointCloud all;
  all.origin = target.origin;
  all.points = target.points;
  for (const Vec3f& p : src.points) all.points.push_back(Tf * p);
  r.merged_map = voxel_downsample(all, {.res_voxel = cfg.merge_voxel, .n_min = 1});
  t.add("merge", sw.lap_ms());
  return r;
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
  std::unordered_map<std::uint64_t, std::vector<float>> cells;
  for (const Vec3f& p : points) {
    const Vec3d q = p.cast<double>();
    const auto cx = std::int64_t(std::floor(u.dot(q) / cell)), cy = std::int64_t(std::floor(v.dot(q) / cell));
    cells[(std::uint64_t(cx) << 32) ^ std::uint64_t(std::uint32_t(cy))].push_back(plane.signed_distance(p));
  }
  int up = 0, down = 0;
  for (auto& [key, h] : cells) {
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
  const std::optional<Vec3d> n = ground_normal(points, cfg);
  if (!n) return Eigen::Matrix3d::Identity();
  return Eigen::Quaterniond::FromTwoVectors(*n, up.normalized()).toRotationMatrix();
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
  // The target (the LiDAR map) is gravity-aligned; its ground may slope. The source's ground is
  // turned onto the target's ground plane (not onto z) so that both are segmented alike and the
  // remaining unknowns are a yaw and a translation, up to the plane fits' noise.
  Eigen::Matrix3d R_level = Eigen::Matrix3d::Identity();
  if (!cfg.gravity_aligned) {
    std::optional<Vec3d> up_target = ground_normal(target.points, cfg.levelling);
    if (up_target && up_target->z() < 0.0) *up_target = -*up_target;  // the map's z is up
    R_level = levelling_rotation(r.source_voxelised.points, up_target.value_or(Vec3d::UnitZ()), cfg.levelling);
  }
  PointCloud levelled = r.source_voxelised;
  levelled.normals.clear();
  const Eigen::Matrix3f Rf = R_level.cast<float>();
  for (Vec3f& p : levelled.points) p = Rf * p;
  r.source_points = levelled.size();
  r.target_points = target.size();
  SegmentationConfig source_segmentation = segmentation;
  if (cfg.source_min_stacked_fraction >= 0.0)
    source_segmentation.verticality.min_stacked_fraction = cfg.source_min_stacked_fraction;
  r.source_segmentation = segment(levelled, source_segmentation);
  t.add("segmentation_source", sw.lap_ms());
  r.target_segmentation = segment(target, segmentation);
  t.add("segmentation_target", sw.lap_ms());

  SegmentSet src = collect_segments(levelled.points, r.source_segmentation);
  SegmentSet tgt = collect_segments(target.points, r.target_segmentation);
  r.source_segments = src.ids.size();
  r.target_segments = tgt.ids.size();
  const auto to_world = [&](const Eigen::Isometry3d& T_local) {
    Eigen::Isometry3d T = Eigen::Translation3d(target.origin) * T_local;
    T.linear() = T.linear() * R_level;
    T.translation() -= T.linear() * source.origin;  // p_world_source = origin + p_local
    return T;
  };
  if (src.ids.empty() || tgt.ids.empty()) {
    r.reason = src.ids.empty() ? "no object segments in the source" : "no object segments in the target";
    for (const char* s : {"keypoints", "descriptors", "matching", "verification", "refinement", "merge"}) t.add(s, 0.0);
    return r;
  }

  // 2.-4. Keypoints and descriptors on the object segments, matching, consistency groups.
  std::vector<TransformCandidate> candidates = descriptor_candidates(src, tgt, cfg, true, r, sw);
  std::vector<Verification> verified;
  std::vector<std::string> origins(candidates.size(), "descriptors");
  for (const TransformCandidate& c : candidates) verified.push_back(verify_centroids(src, tgt, c.T_target_source, cfg.d_match));
  if (cfg.centroid_hypotheses) {
    for (auto& [H, v] : centroid_candidates(src, tgt, cfg)) {
      TransformCandidate c;
      c.T_target_source = H;
      candidates.push_back(std::move(c));
      verified.push_back(std::move(v));
      origins.emplace_back("centroids");
      ++r.centroid_candidates;
    }
  }
  std::vector<std::size_t> order(candidates.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    if (verified[a].inliers != verified[b].inliers) return verified[a].inliers > verified[b].inliers;
    return verified[a].max_distance < verified[b].max_distance;
  });
  for (std::size_t k : order) {
    CandidateReport rep;
    rep.origin = origins[k];
    rep.votes = candidates[k].votes;
    rep.centroid_inliers = verified[k].inliers;
    rep.max_centroid_distance = verified[k].max_distance;
    rep.T_target_source = candidates[k].T_target_source;
    rep.T_world = to_world(rep.T_target_source);
    r.reports.push_back(rep);
  }
  t.add("verification", sw.lap_ms());

  // 5. ICP on the matched segments, acceptance test.
  int refined = 0;
  std::vector<Eigen::Isometry3d> tried;
  std::optional<std::size_t> accepted;
  Verification accepted_pairs;
  // Per refined candidate (by rank): the refined transform and its matched pairs (scale check).
  std::map<std::size_t, std::pair<Eigen::Isometry3d, Verification>> refined_pairs;
  for (std::size_t rank = 0; rank < order.size() && refined < cfg.max_refinements; ++rank) {
    const Verification& v = verified[order[rank]];
    if (v.inliers < cfg.acceptance.min_matched_segments) break;  // sorted: the rest have fewer
    const Eigen::Isometry3d& coarse_T = r.reports[rank].T_target_source;
    if (already_tried(tried, coarse_T)) continue;  // the same alignment from another group: refining it again cannot help
    tried.push_back(coarse_T);
    ++refined;
    std::vector<Vec3f> sp, tp, tn;
    for (const auto& [si, ti] : v.pairs) {
      for (std::uint32_t i : src.members[std::size_t(si)]) sp.push_back(src.points[i]);
      for (std::uint32_t i : tgt.members[std::size_t(ti)]) {
        tp.push_back(tgt.points[i]);
        tn.push_back(tgt.normals[i]);
      }
    }
    const IcpTarget icp_target(tp, tn);
    CandidateReport& rep = r.reports[rank];
    const auto [T, icp_rmse] = refine_two_pass(sp, icp_target, rep.T_target_source, cfg);
    const Overlap o = mutual_overlap(sp, tp, T, cfg.acceptance.overlap_distance);
    // The matched set after refinement (a refined transform may pair the centroids differently).
    const Verification after = verify_centroids(src, tgt, T, cfg.d_match);
    rep.refined = true;
    rep.T_target_source = T;
    rep.T_world = to_world(T);
    rep.rmse = o.rmse;
    rep.overlap = o.share;
    rep.icp_rmse = icp_rmse;
    rep.accepted = o.rmse < cfg.acceptance.e_icp && o.share >= cfg.acceptance.min_overlap &&
                   after.inliers >= cfg.acceptance.min_matched_segments;
    refined_pairs[rank] = {T, after};
    if (rep.accepted && !accepted) {
      accepted = rank;
      accepted_pairs = after;
    }
    if (accepted && !cfg.refine_all) break;
  }
  t.add("refinement", sw.lap_ms());

  // 5b. Scale check (beyond the paper): the matched segments, spread over the site, aligned one
  // by one must not fit a similarity of another scale. A rigid fit of a wrongly scaled source
  // passes the overlap test near the site's centre and is wrong by decimetres at its edges; a
  // larger error fails the overlap test, and the candidate with the most matched segments tells why.
  std::optional<std::size_t> checked = accepted;
  for (const auto& [rank, candidate] : refined_pairs)
    if (!checked || (!accepted && candidate.second.inliers > refined_pairs.at(*checked).second.inliers)) checked = rank;
  if (checked) {
    const auto& [T, pairs] = refined_pairs.at(*checked);
    r.scale_fit = fit_scale(segment_pairs(src, tgt, pairs, T), cfg.scale_check);
  }
  t.add("scale_check", sw.lap_ms());
  if (r.scale_fit.observable && std::abs(r.scale_fit.scale - 1.0) > cfg.scale_check.max_scale_error) {
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

  if (!accepted) {
    if (r.reason.empty())
      r.reason = refined > 0 ? "no refined candidate passes the acceptance test"
               : r.candidates + r.centroid_candidates == 0
                   ? "no geometrically consistent group of correspondences and no centroid hypothesis"
                   : "no candidate matches " + std::to_string(cfg.acceptance.min_matched_segments) +
                         " segment centroids within d_match";
    if (r.rmse == 0.0 && !r.reports.empty() && r.reports.front().refined) {  // else unmeasured (0)
      r.rmse = r.reports.front().rmse;
      r.overlap = r.reports.front().overlap;
    }
    t.add("merge", 0.0);
    return r;
  }
  const CandidateReport& best = r.reports[*accepted];
  r.success = true;
  r.rmse = best.rmse;
  r.overlap = best.overlap;
  r.T_target_source = to_world(best.T_target_source);
  for (const auto& [si, ti] : accepted_pairs.pairs)
    r.matched_segments.emplace_back(src.ids[std::size_t(si)], tgt.ids[std::size_t(ti)]);

  // 6. Merge: matched segment pairs, and the aligned source into the map (target frame).
  const Eigen::Isometry3f Tf = best.T_target_source.cast<float>();
  const VoxelGridConfig merge_voxel{.res_voxel = cfg.merge_voxel, .n_min = 1};
  for (const auto& [si, ti] : accepted_pairs.pairs) {
    PointCloud merged;
    merged.origin = target.origin;
    for (std::uint32_t i : tgt.members[std::size_t(ti)]) merged.points.push_back(tgt.points[i]);
    for (std::uint32_t i : src.members[std::size_t(si)]) merged.points.push_back(Tf * src.points[i]);
    r.merged_segments.push_back(voxel_downsample(merged, merge_voxel));
    r.objects.push_back({r.merged_segments.back(), src.ids[std::size_t(si)], tgt.ids[std::size_t(ti)]});
  }
  // Segments without a match: a piece of a stone that one cloud split off (the LiDAR sees a
  // stone in two parts, one matched) joins the merged object it touches after alignment; the
  // others stay objects of their own (e.g. a stone only the drone saw so far).
  std::vector<bool> src_used(src.ids.size(), false), tgt_used(tgt.ids.size(), false);
  for (const auto& [si, ti] : accepted_pairs.pairs) {
    src_used[std::size_t(si)] = true;
    tgt_used[std::size_t(ti)] = true;
  }
  std::vector<Vec3f> merged_points;
  std::vector<std::uint32_t> merged_owner;
  for (std::size_t k = 0; k < r.merged_segments.size(); ++k)
    for (const Vec3f& p : r.merged_segments[k].points) {
      merged_points.push_back(p);
      merged_owner.push_back(std::uint32_t(k));
    }
  const KdTree merged_tree(merged_points);
  const float absorb = float(cfg.absorb_distance);
  const auto place = [&](std::vector<Vec3f> pts, std::int32_t source_id, std::int32_t target_id) {
    std::vector<std::size_t> contacts(r.merged_segments.size(), 0);
    for (const Vec3f& p : pts)
      if (!merged_points.empty()) {
        float d2 = 0.0f;
        const std::uint32_t n = merged_tree.nearest(p, &d2);
        if (d2 < absorb * absorb) ++contacts[merged_owner[n]];
      }
    const auto most = std::max_element(contacts.begin(), contacts.end());
    if (most != contacts.end() && *most >= cfg.absorb_min_points) {
      PointCloud& obj = r.objects[std::size_t(most - contacts.begin())].cloud;
      obj.points.insert(obj.points.end(), pts.begin(), pts.end());
      return;
    }
    GlobalRegistrationResult::Object o{.cloud = {}, .source_segment = source_id, .target_segment = target_id};
    o.cloud.origin = target.origin;
    o.cloud.points = std::move(pts);
    r.objects.push_back(std::move(o));
  };
  for (std::size_t k = 0; k < src.ids.size(); ++k) {
    if (src_used[k]) continue;
    std::vector<Vec3f> pts;
    for (std::uint32_t i : src.members[k]) pts.push_back(Tf * src.points[i]);
    place(std::move(pts), src.ids[k], -1);
  }
  for (std::size_t k = 0; k < tgt.ids.size(); ++k) {
    if (tgt_used[k]) continue;
    std::vector<Vec3f> pts;
    for (std::uint32_t i : tgt.members[k]) pts.push_back(tgt.points[i]);
    place(std::move(pts), -1, tgt.ids[k]);
  }
  for (std::size_t k = 0; k < r.merged_segments.size(); ++k)
    if (r.objects[k].cloud.size() != r.merged_segments[k].size())
      r.objects[k].cloud = voxel_downsample(r.objects[k].cloud, merge_voxel);
  PointCloud all;
  all.origin = target.origin;
  all.points = target.points;
  all.points.reserve(target.size() + levelled.size());
  for (const Vec3f& p : levelled.points) all.points.push_back(Tf * p);
  r.merged_map = voxel_downsample(all, merge_voxel);
  t.add("merge", sw.lap_ms());
  return r;
}

}  // namespace cairn
