#include "cairn/registration/consistency_grouping.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <optional>
#include <string>

#include "cairn/core/error.hpp"
#include "cairn/registration/umeyama.hpp"

namespace cairn {

void GroupingConfig::validate() const {
  if (!(consensus_size > 0.0)) throw ConfigError("grouping.consensus_size must be positive");
  if (min_votes < 2) throw ConfigError("grouping.min_votes must be at least 2 (a cluster needs 3 pairs for a transform)");
  if (max_candidates < 1) throw ConfigError("grouping.max_candidates must be at least 1");
}

namespace {

/// PCL's pairwise test, in float as PCL: | |s_k − s_j| − |t_k − t_j| | ≤ size.
inline bool consistent(const Vec3f& sk, const Vec3f& tk, const Vec3f& sj, const Vec3f& tj, double size) {
  const Vec3f dist_ref = tk - tj;
  const Vec3f dist_trg = sk - sj;
  const double distance = std::abs(dist_ref.norm() - dist_trg.norm());
  return !(distance > size);
}

struct Fit {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  bool ok = false;
};

Fit rigid_fit(std::span<const Vec3f> source, std::span<const Vec3f> target, std::span<const Correspondence> pairs) {
  std::vector<Vec3d> s, t;
  s.reserve(pairs.size());
  t.reserve(pairs.size());
  for (const auto& c : pairs) {
    s.push_back(source[c.source].cast<double>());
    t.push_back(target[c.target].cast<double>());
  }
  Fit f;
  try {
    const UmeyamaResult r = umeyama(s, t, {.with_scale = false});
    f.T.linear() = r.transform.rotation;
    f.T.translation() = r.transform.translation;
    f.ok = true;
  } catch (const InputError&) {  // collinear / coincident keypoints: no unique transform
  }
  return f;
}

double rms_of(std::span<const Vec3f> source, std::span<const Vec3f> target, std::span<const Correspondence> pairs,
              const Eigen::Isometry3d& T) {
  if (pairs.empty()) return 0.0;
  double sum = 0.0;
  for (const auto& c : pairs) sum += (target[c.target].cast<double>() - T * source[c.source].cast<double>()).squaredNorm();
  return std::sqrt(sum / double(pairs.size()));
}

}  // namespace

std::vector<std::vector<Correspondence>> consistency_clusters(std::span<const Vec3f> source_keypoints,
                                                              std::span<const Vec3f> target_keypoints,
                                                              std::span<const Correspondence> matches,
                                                              const GroupingConfig& cfg) {
  cfg.validate();
  check_correspondence_indices(source_keypoints, target_keypoints, matches, "geometric_consistency_grouping");
  // Same container, same comparator, same std::sort as PCL: ties in distance end up in the same
  // order as PCL's.
  std::vector<Correspondence> sorted(matches.begin(), matches.end());
  std::sort(sorted.begin(), sorted.end(),
            [](const Correspondence& a, const Correspondence& b) { return a.squared_distance < b.squared_distance; });
  const std::size_t n = sorted.size();
  std::vector<Vec3f> s(n), t(n);
  // Structure of arrays for the vectorised test against the seed.
  Eigen::ArrayXf sx(n), sy(n), sz(n), tx(n), ty(n), tz(n);
  for (std::size_t i = 0; i < n; ++i) {
    s[i] = source_keypoints[sorted[i].source];
    t[i] = target_keypoints[sorted[i].target];
    const auto k = Eigen::Index(i);
    sx[k] = s[i].x(), sy[k] = s[i].y(), sz[k] = s[i].z();
    tx[k] = t[i].x(), ty[k] = t[i].y(), tz[k] = t[i].z();
  }
  // float(d) > consensus_size (double) ⇔ float(d) > size_f, size_f the largest float ≤ consensus_size.
  float size_f = static_cast<float>(cfg.consensus_size);
  if (double(size_f) > cfg.consensus_size) size_f = std::nextafter(size_f, 0.0f);

  std::vector<std::uint8_t> taken(n, 0), with_seed(n, 0);
  std::vector<std::uint32_t> members;
  std::vector<std::vector<Correspondence>> clusters;
  for (std::size_t i = 0; i < n; ++i) {
    if (taken[i]) continue;
    // Every candidate must be consistent with the seed, whatever joined before it: test that
    // first for all candidates at once (SIMD; same float operations as Eigen's Vector3f::norm,
    // x² + (y² + z²), so the same decisions as PCL), then grow the cluster in PCL's order over
    // the survivors only.
    const auto test_seed = [&](Eigen::Index j0, Eigen::Index len) {
      const auto k = Eigen::Index(i);
      const Eigen::ArrayXf dt = ((tx[k] - tx.segment(j0, len)).square() +
                                 ((ty[k] - ty.segment(j0, len)).square() + (tz[k] - tz.segment(j0, len)).square()))
                                    .sqrt();
      const Eigen::ArrayXf ds = ((sx[k] - sx.segment(j0, len)).square() +
                                 ((sy[k] - sy.segment(j0, len)).square() + (sz[k] - sz.segment(j0, len)).square()))
                                    .sqrt();
      const Eigen::ArrayXf d = (dt - ds).abs();
      for (Eigen::Index j = 0; j < len; ++j) {
        const auto jj = std::size_t(j0 + j);
        with_seed[jj] = jj != i && !taken[jj] && !(d[j] > size_f);
      }
    };
    if (n >= 8192)
      tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 2048), [&](const auto& r) {
        test_seed(Eigen::Index(r.begin()), Eigen::Index(r.end() - r.begin()));
      });
    else
      test_seed(0, Eigen::Index(n));
    members.assign(1, std::uint32_t(i));
    for (std::size_t j = 0; j < n; ++j) {
      if (!with_seed[j]) continue;
      bool good = true;
      for (std::size_t m = 1; m < members.size() && good; ++m) {
        const std::uint32_t k = members[m];
        good = consistent(s[k], t[k], s[j], t[j], cfg.consensus_size);
      }
      if (good) members.push_back(std::uint32_t(j));
    }
    if (members.size() > std::size_t(cfg.min_votes)) {
      std::vector<Correspondence> cluster;
      cluster.reserve(members.size());
      for (auto m : members) {
        taken[m] = 1;
        cluster.push_back(sorted[m]);
      }
      clusters.push_back(std::move(cluster));
    }
  }
  return clusters;
}

void check_correspondence_indices(std::span<const Vec3f> source, std::span<const Vec3f> target,
                                  std::span<const Correspondence> m, const std::string& what) {
  for (std::size_t i = 0; i < m.size(); ++i)
    if (m[i].source >= source.size() || m[i].target >= target.size())
      throw InputError(what + ": correspondence " + std::to_string(i) + " (" + std::to_string(m[i].source) + " -> " +
                       std::to_string(m[i].target) + ") is out of range of the keypoints (" +
                       std::to_string(source.size()) + " source, " + std::to_string(target.size()) + " target)");
}

std::optional<TransformCandidate> fit_candidate(std::span<const Vec3f> source_keypoints,
                                                std::span<const Vec3f> target_keypoints,
                                                std::vector<Correspondence> members, double tolerance, int refits) {
  Fit fit = rigid_fit(source_keypoints, target_keypoints, members);
  if (!fit.ok) return std::nullopt;
  TransformCandidate cand;
  cand.votes = members.size();
  cand.inliers = std::move(members);
  // Sec. 4.4 step 4: the transform from the consistent members; pairs that the fit places farther
  // than the tolerance from their partner are dropped and the fit repeated.
  const double t2 = tolerance * tolerance;
  const std::vector<Correspondence> all = cand.inliers;  // every round filters all the members
  for (int round = 0; round < refits; ++round) {
    std::vector<Correspondence> in;
    for (const auto& m : all)
      if ((target_keypoints[m.target].cast<double>() - fit.T * source_keypoints[m.source].cast<double>()).squaredNorm() <
          t2)
        in.push_back(m);
    if (in.size() < 3) break;
    const Fit refit = rigid_fit(source_keypoints, target_keypoints, in);
    if (!refit.ok) break;
    fit = refit;
    cand.inliers = std::move(in);
  }
  cand.T_target_source = fit.T;
  cand.rms = rms_of(source_keypoints, target_keypoints, cand.inliers, fit.T);
  return cand;
}

std::vector<TransformCandidate> geometric_consistency_grouping(std::span<const Vec3f> source_keypoints,
                                                               std::span<const Vec3f> target_keypoints,
                                                               std::span<const Correspondence> matches,
                                                               const GroupingConfig& cfg) {
  auto clusters = consistency_clusters(source_keypoints, target_keypoints, matches, cfg);
  std::vector<std::size_t> order(clusters.size());
  std::iota(order.begin(), order.end(), std::size_t(0));
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return clusters[a].size() > clusters[b].size(); });

  std::vector<TransformCandidate> out;
  for (std::size_t c : order) {
    if (out.size() >= std::size_t(cfg.max_candidates)) break;
    if (auto cand = fit_candidate(source_keypoints, target_keypoints, std::move(clusters[c]), cfg.consensus_size,
                                  cfg.refine ? 2 : 0))
      out.push_back(std::move(*cand));
  }
  return out;
}

}  // namespace cairn
