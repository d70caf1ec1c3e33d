#include "cairn/registration/global_steps.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include "cairn/core/units.hpp"

namespace cairn {
namespace {

// Two coarse candidates closer than this are one alignment (ICP's basin is wider).
constexpr double kSameCandidateDistance = 0.2;      // [m]
constexpr double kSameCandidateAngle = 2.0 * kDeg;  // [rad]
// Centroid hypotheses closer than this share of d_match and this angle are one.
constexpr double kSameHypothesisShare = 0.5;
constexpr double kSameHypothesisAngle = 5.0 * kDeg;  // [rad]

/// True when `T` is (within ICP's basin) one of the alignments already tried.
bool already_tried(const std::vector<Eigen::Isometry3d>& tried, const Eigen::Isometry3d& T) {
  return std::any_of(tried.begin(), tried.end(), [&](const Eigen::Isometry3d& T0) {
    return (T0.translation() - T.translation()).norm() < kSameCandidateDistance &&
           rotation_angle(T0.linear().transpose() * T.linear()) < kSameCandidateAngle;
  });
}

/// Sum of squared nearest distances below `distance` and their count, over fixed chunks summed
/// in order: the same result on any number of threads.
std::pair<double, std::size_t> sum_within(std::span<const Vec3f> q, const KdTree& tree, double distance) {
  if (tree.size() == 0) return {0.0, 0};
  constexpr std::size_t kQueryChunk = 1024;
  const std::size_t chunks = (q.size() + kQueryChunk - 1) / kQueryChunk;
  std::vector<double> sq(chunks, 0.0);
  std::vector<std::size_t> n(chunks, 0);
  const float bound = sq_dist_bound(distance);
  tbb::parallel_for(std::size_t(0), chunks, [&](std::size_t c) {
    for (std::size_t i = c * kQueryChunk; i < std::min(q.size(), (c + 1) * kQueryChunk); ++i) {
      float d2 = 0.0f;
      (void)tree.nearest_within(q[i], bound, &d2);
      if (double(d2) < distance * distance) {
        sq[c] += double(d2);
        ++n[c];
      }
    }
  });
  return {std::accumulate(sq.begin(), sq.end(), 0.0), std::accumulate(n.begin(), n.end(), std::size_t{0})};
}

/// The yaw + translation taking source pair (a0, a1) onto target pair (b0, b1) in the horizontal
/// plane, midpoint onto midpoint.
Eigen::Isometry3d pair_alignment(const Vec3f& a0, const Vec3f& a1, const Vec3f& b0, const Vec3f& b1) {
  const Eigen::Vector2d a = (a1 - a0).head<2>().cast<double>(), b = (b1 - b0).head<2>().cast<double>();
  const double yaw = std::atan2(b.y(), b.x()) - std::atan2(a.y(), a.x());
  Eigen::Isometry3d H = Eigen::Isometry3d::Identity();
  H.linear() = Eigen::AngleAxisd(yaw, Vec3d::UnitZ()).toRotationMatrix();
  const Vec3d ms = 0.5 * (a0 + a1).cast<double>(), mt = 0.5 * (b0 + b1).cast<double>();
  H.translation() = mt - H.linear() * ms;
  return H;
}

/// The points of segment `k` of `set`, moved by T.
std::vector<Vec3f> segment_points(const SegmentSet& set, std::size_t k, const Eigen::Isometry3f& T) {
  std::vector<Vec3f> out;
  out.reserve(set.members[k].size());
  for (std::uint32_t i : set.members[k]) out.push_back(T * set.points[i]);
  return out;
}

}  // namespace

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

Overlap mutual_overlap(std::span<const Vec3f> source, std::span<const Vec3f> target, const Eigen::Isometry3d& T,
                       double distance) {
  std::vector<Vec3f> moved(source.size());
  const Eigen::Isometry3f Tf = T.cast<float>();
  for (std::size_t i = 0; i < source.size(); ++i) moved[i] = Tf * source[i];
  const KdTree tt(target), ts(moved);
  const auto [sq_s, n_s] = sum_within(moved, tt, distance);
  const auto [sq_t, n_t] = sum_within(target, ts, distance);
  Overlap o;
  const std::size_t n = n_s + n_t;
  o.rmse = n ? std::sqrt((sq_s + sq_t) / double(n)) : std::numeric_limits<double>::infinity();
  o.share = double(n) / double(std::max<std::size_t>(1, source.size() + target.size()));
  return o;
}

bool passes_acceptance(const Overlap& overlap, std::optional<int> matched_segments,
                       const RegistrationAcceptanceConfig& c) {
  return overlap.rmse < c.e_icp && overlap.share >= c.min_overlap &&
         (!matched_segments || *matched_segments >= c.min_matched_segments);
}

std::vector<std::pair<Eigen::Isometry3d, CentroidMatch>> centroid_hypotheses(std::span<const Vec3f> S,
                                                                             std::span<const Vec3f> T,
                                                                             const GlobalRegistrationConfig& cfg) {
  // Unordered source pairs against ordered target pairs give every distinct hypothesis once; the
  // target pairs are sorted by length so that only those within d_match are visited.
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
  std::vector<std::pair<Eigen::Isometry3d, CentroidMatch>> out;
  for (std::size_t i = 0; i < S.size(); ++i)
    for (std::size_t j = i + 1; j < S.size(); ++j) {
      const double length = (S[j] - S[i]).head<2>().cast<double>().norm();
      if (length < cfg.min_centroid_baseline) continue;
      auto it = std::lower_bound(target_pairs.begin(), target_pairs.end(), length - cfg.d_match,
                                 [](const TargetPair& p, double len) { return p.length < len; });
      for (; it != target_pairs.end() && it->length <= length + cfg.d_match; ++it) {
        const Eigen::Isometry3d H = pair_alignment(S[i], S[j], T[it->k], T[it->l]);
        CentroidMatch v = match_centroids(S, T, H, cfg.d_match);
        if (v.inliers >= cfg.acceptance.min_matched_segments) out.emplace_back(H, std::move(v));
      }
    }
  std::stable_sort(out.begin(), out.end(), [](const auto& a, const auto& b) {
    if (a.second.inliers != b.second.inliers) return a.second.inliers > b.second.inliers;
    return a.second.max_distance < b.second.max_distance;
  });
  // Keep distinct hypotheses only (the same alignment arises from many pairs).
  std::vector<std::pair<Eigen::Isometry3d, CentroidMatch>> distinct;
  for (auto& c : out) {
    const bool dup = std::any_of(distinct.begin(), distinct.end(), [&](const auto& d) {
      return (d.first.translation() - c.first.translation()).norm() < kSameHypothesisShare * cfg.d_match &&
             rotation_angle(d.first.linear().transpose() * c.first.linear()) < kSameHypothesisAngle;
    });
    if (!dup) distinct.push_back(std::move(c));
    if (int(distinct.size()) >= cfg.max_centroid_candidates) break;
  }
  return distinct;
}

std::optional<std::size_t> refine_and_accept(
    std::vector<CandidateReport>& reports, const std::function<bool(std::size_t)>& eligible,
    const std::function<Refinement(std::size_t, const Eigen::Isometry3d&)>& refine,
    const std::function<Eigen::Isometry3d(const Eigen::Isometry3d&)>& to_world,
    const RegistrationAcceptanceConfig& acceptance, const RefineRule& rule, int& refined) {
  std::vector<Eigen::Isometry3d> tried;
  std::optional<std::size_t> accepted;
  refined = 0;
  for (std::size_t rank = 0; rank < reports.size() && refined < rule.max_refinements; ++rank) {
    if (!eligible(rank)) break;
    CandidateReport& rep = reports[rank];
    if (already_tried(tried, rep.T_target_source)) continue;  // refining the same alignment again cannot help
    tried.push_back(rep.T_target_source);
    ++refined;
    const Refinement f = refine(rank, rep.T_target_source);
    tried.push_back(f.T);  // later candidates that start where this one ended are the same
    rep.refined = true;
    rep.T_target_source = f.T;
    rep.T_world = to_world(f.T);
    rep.rmse = f.overlap.rmse;
    rep.overlap = f.overlap.share;
    rep.icp_rmse = f.icp_rmse;
    rep.accepted = passes_acceptance(f.overlap, f.matched ? std::optional<int>(f.matched->inliers) : std::nullopt,
                                     acceptance);
    if (rep.accepted &&
        (!accepted || (rule.largest_overlap && rep.overlap > reports[*accepted].overlap)))
      accepted = rank;
    if (accepted && !rule.largest_overlap && !rule.refine_all) break;
  }
  return accepted;
}

void merge_objects(const SegmentSet& src, const SegmentSet& tgt, const CentroidMatch& matched,
                   const Eigen::Isometry3d& T, const Vec3d& origin, const GlobalRegistrationConfig& cfg,
                   GlobalRegistrationResult& r) {
  const Eigen::Isometry3f Tf = T.cast<float>();
  const VoxelGridConfig merge_voxel{.res_voxel = cfg.merge_voxel, .n_min = 1};
  std::vector<bool> src_used(src.ids.size(), false), tgt_used(tgt.ids.size(), false);
  for (const auto& [si, ti] : matched.pairs) {
    PointCloud merged;
    merged.origin = origin;
    merged.points = segment_points(tgt, std::size_t(ti), Eigen::Isometry3f::Identity());
    for (const Vec3f& p : segment_points(src, std::size_t(si), Tf)) merged.points.push_back(p);
    r.merged_segments.push_back(voxel_downsample(merged, merge_voxel));
    r.objects.push_back({r.merged_segments.back(), src.ids[std::size_t(si)], tgt.ids[std::size_t(ti)]});
    src_used[std::size_t(si)] = tgt_used[std::size_t(ti)] = true;
  }
  // Segments without a match: a piece of a stone that one cloud split off (the LiDAR sees a
  // stone in two parts, one matched) joins the merged object it touches after alignment; the
  // others stay objects of their own (e.g. a stone only the drone saw so far).
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
        const std::uint32_t n = merged_tree.nearest_within(p, absorb * absorb, &d2);
        if (d2 < absorb * absorb) ++contacts[merged_owner[n]];
      }
    const auto most = std::max_element(contacts.begin(), contacts.end());
    if (most != contacts.end() && *most >= cfg.absorb_min_points) {
      PointCloud& obj = r.objects[std::size_t(most - contacts.begin())].cloud;
      obj.points.insert(obj.points.end(), pts.begin(), pts.end());
      return;
    }
    GlobalRegistrationResult::Object o{.cloud = {}, .source_segment = source_id, .target_segment = target_id};
    o.cloud.origin = origin;
    o.cloud.points = std::move(pts);
    r.objects.push_back(std::move(o));
  };
  for (std::size_t k = 0; k < src.ids.size(); ++k)
    if (!src_used[k]) place(segment_points(src, k, Tf), src.ids[k], -1);
  for (std::size_t k = 0; k < tgt.ids.size(); ++k)
    if (!tgt_used[k]) place(segment_points(tgt, k, Eigen::Isometry3f::Identity()), -1, tgt.ids[k]);
  for (std::size_t k = 0; k < r.merged_segments.size(); ++k)
    if (r.objects[k].cloud.size() != r.merged_segments[k].size())
      r.objects[k].cloud = voxel_downsample(r.objects[k].cloud, merge_voxel);
}

}  // namespace cairn
