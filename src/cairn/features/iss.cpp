#include "cairn/features/iss.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <string>

#include "cairn/core/error.hpp"
#include "cairn/features/search_radius.hpp"

namespace cairn {

void IssConfig::validate() const {
  if (!(salient_radius > 0.0)) throw ConfigError("iss.salient_radius must be positive");
  if (!(non_max_radius > 0.0)) throw ConfigError("iss.non_max_radius must be positive");
  if (!(gamma_21 > 0.0)) throw ConfigError("iss.gamma_21 must be positive");
  if (!(gamma_32 > 0.0)) throw ConfigError("iss.gamma_32 must be positive");
  if (min_neighbors < 1) throw ConfigError("iss.min_neighbors must be at least 1");
}

namespace {

void check_input(std::span<const Vec3f> points, const KdTree& tree) {
  if (tree.points().data() != points.data() || tree.size() != points.size())
    throw InputError("iss_keypoints: the kd-tree does not index the given points (" + std::to_string(tree.size()) +
                     " tree points, " + std::to_string(points.size()) + " points)");
}

}  // namespace

namespace {

constexpr std::size_t kChunk = 256;  // points per parallel task (fixed: results do not depend on threads)

/// Neighbour lists within the non-maximum radius, kept from the salient-radius query when that
/// radius is not larger (one kd-tree query per point instead of two). Chunk c holds the lists of
/// points [c * kChunk, (c + 1) * kChunk).
struct NeighborChunks {
  std::vector<std::vector<std::uint32_t>> indices, offsets;
  [[nodiscard]] std::span<const std::uint32_t> of(std::size_t i) const {
    const auto& off = offsets[i / kChunk];
    const std::size_t k = i % kChunk;
    return {indices[i / kChunk].data() + off[k], off[k + 1] - off[k]};
  }
};

/// Saliency λ3 per point (Sec. 4.4 step 2, Zhong 2009; PCL getScatterMatrix + detectKeypoints);
/// fills `nms` with the neighbours within `nms_radius_sq` when it is not null.
std::vector<double> saliency_pass(std::span<const Vec3f> points, const KdTree& tree, const IssConfig& cfg,
                                  NeighborChunks* nms, float nms_radius_sq) {
  const float radius = detail::pcl_equivalent_radius(cfg.salient_radius);
  std::vector<double> saliency(points.size(), 0.0);
  const std::size_t chunks = (points.size() + kChunk - 1) / kChunk;
  if (nms) {
    nms->indices.assign(chunks, {});
    nms->offsets.assign(chunks, {});
  }
  tbb::parallel_for(std::size_t(0), chunks, [&](std::size_t c) {
    const std::size_t begin = c * kChunk, end = std::min(points.size(), begin + kChunk);
    std::vector<std::uint32_t>* list = nms ? &nms->indices[c] : nullptr;
    std::vector<std::uint32_t>* off = nms ? &nms->offsets[c] : nullptr;
    if (off) off->push_back(0);
    for (std::size_t i = begin; i < end; ++i) {
      // Scatter matrix about the point itself, accumulated in double (PCL getScatterMatrix).
      const Eigen::Vector3d center = points[i].cast<double>();
      double cov[9] = {};
      int count = 0;
      tree.for_each_in_radius(points[i], radius, [&](std::uint32_t j, float d2) {
        const Eigen::Vector3d d = points[j].cast<double>() - center;
        for (int a = 0; a < 3; ++a)
          for (int b = 0; b < 3; ++b) cov[a * 3 + b] += d[a] * d[b];
        ++count;
        if (list && d2 < nms_radius_sq) list->push_back(j);
      });
      if (off) off->push_back(std::uint32_t(list->size()));
      if (count < cfg.min_neighbors) continue;
      Eigen::Matrix3d m;
      m << cov[0], cov[1], cov[2], cov[3], cov[4], cov[5], cov[6], cov[7], cov[8];
      // Eigenvalues only: the QR iteration updates them identically with or without eigenvectors,
      // so they equal PCL's bit for bit.
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(m, Eigen::EigenvaluesOnly);
      const double e1 = solver.eigenvalues()[2], e2 = solver.eigenvalues()[1], e3 = solver.eigenvalues()[0];
      if (!std::isfinite(e1) || !std::isfinite(e2) || !std::isfinite(e3) || e3 < 0.0) continue;
      // NaN ratios (e.g. λ2 = 0) fail both comparisons, as in PCL.
      if (e2 / e1 < cfg.gamma_21 && e3 / e2 < cfg.gamma_32) saliency[i] = e3;
    }
  });
  return saliency;
}

}  // namespace

std::vector<double> iss_saliency(std::span<const Vec3f> points, const KdTree& tree, const IssConfig& cfg) {
  cfg.validate();
  check_input(points, tree);
  return saliency_pass(points, tree, cfg, nullptr, 0.0f);
}

std::vector<std::uint32_t> iss_keypoints(std::span<const Vec3f> points, const KdTree& tree, const IssConfig& cfg) {
  cfg.validate();
  check_input(points, tree);
  const float nms_radius = detail::pcl_equivalent_radius(cfg.non_max_radius);
  // The salient-radius query finds every point within the non-maximum radius too when that is
  // not larger: keep those lists instead of querying again. d² < r² in float either way.
  const bool reuse = nms_radius <= detail::pcl_equivalent_radius(cfg.salient_radius);
  NeighborChunks nms;
  const std::vector<double> saliency =
      saliency_pass(points, tree, cfg, reuse ? &nms : nullptr, nms_radius * nms_radius);
  std::vector<std::uint8_t> is_max(points.size(), 0);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, points.size(), kChunk), [&](const auto& r) {
    for (std::size_t i = r.begin(); i != r.end(); ++i) {
      const double s = saliency[i];
      if (!(s > 0.0)) continue;
      int count = 0;
      bool larger = false;
      const auto visit = [&](std::uint32_t j) {
        ++count;
        larger = larger || saliency[j] > s;
      };
      if (reuse) {
        for (auto j : nms.of(i)) visit(j);
      } else {
        tree.for_each_in_radius(points[i], nms_radius, [&](std::uint32_t j, float) { visit(j); });
      }
      is_max[i] = !larger && count >= cfg.min_neighbors;
    }
  });
  std::vector<std::uint32_t> keypoints;
  for (std::size_t i = 0; i < points.size(); ++i)
    if (is_max[i]) keypoints.push_back(std::uint32_t(i));
  return keypoints;
}

}  // namespace cairn
