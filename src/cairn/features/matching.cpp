#include "cairn/features/matching.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <limits>
#include <nanoflann.hpp>

#include "cairn/core/error.hpp"

namespace cairn {

void MatchConfig::validate() const {
  if (!(max_squared_distance > 0.0)) throw ConfigError("matching.max_squared_distance must be positive");
  if (search != "scan" && search != "kdtree")
    throw ConfigError("matching.search: unknown value '" + search + "' (scan or kdtree)");
}

namespace {

/// nanoflann view of the valid rows of a descriptor set (no copy of the descriptors).
struct DescriptorAdaptor {
  const ShotDescriptors* set;
  std::vector<std::uint32_t> rows;  // tree index -> descriptor index
  [[nodiscard]] std::size_t kdtree_get_point_count() const { return rows.size(); }
  [[nodiscard]] float kdtree_get_pt(std::uint32_t i, std::size_t dim) const {
    return set->data[std::size_t(rows[i]) * kShotSize + dim];
  }
  template <class Box>
  bool kdtree_get_bbox(Box&) const {
    return false;
  }
};

// L2_Simple: the squared distance summed sequentially over the 352 bins in float, as FLANN's
// L2_Simple used by pcl::KdTreeFLANN, so distances agree with PCL's bit for bit.
using DescriptorIndex = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, DescriptorAdaptor>,
                                                            DescriptorAdaptor, -1, std::uint32_t>;

constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();

struct Nearest {
  std::uint32_t index = kNone;  // descriptor index in the searched set
  float squared_distance = std::numeric_limits<float>::infinity();
};

/// Nearest valid `to` descriptor of every valid `from` descriptor, by kd-tree.
std::vector<Nearest> nearest_kdtree(const ShotDescriptors& from, const ShotDescriptors& to) {
  DescriptorAdaptor adaptor{&to, {}};
  for (std::size_t i = 0; i < to.size(); ++i)
    if (to.valid[i]) adaptor.rows.push_back(std::uint32_t(i));
  std::vector<Nearest> out(from.size());
  if (adaptor.rows.empty()) return out;
  // Leaf size 15 as pcl::KdTreeFLANN (FLANN KDTreeSingleIndexParams(15)).
  const DescriptorIndex index(kShotSize, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(15));
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, from.size(), 16), [&](const auto& r) {
    for (std::size_t i = r.begin(); i != r.end(); ++i) {
      if (!from.valid[i]) continue;
      std::uint32_t row = 0;
      float d2 = 0.0f;
      if (index.knnSearch(from.descriptor(i).data(), 1, &row, &d2) == 1) out[i] = {adaptor.rows[row], d2};
    }
  });
  return out;
}

// --- Scan with lower bounds --------------------------------------------------------------------

constexpr int kLanes = 8;                       // target descriptors per block of the bound scan
using Lanes = Eigen::Array<float, kLanes, 1>;

/// Per spatial volume, the L2 norm of the descriptor's 11 bins. By the reverse triangle
/// inequality per volume, Σ_g (‖q_g‖ − ‖t_g‖)² ≤ Σ_g ‖q_g − t_g‖² = |q − t|²: a 32-dimensional
/// lower bound of the squared descriptor distance.
void volume_norms(std::span<const float> d, float* out) {
  for (int g = 0; g < kShotVolumes; ++g) {
    float s = 0.0f;
    for (int b = 0; b < kShotBinsPerVolume; ++b) {
      const float v = d[std::size_t(g * kShotBinsPerVolume + b)];
      s += v * v;
    }
    out[g] = std::sqrt(s);
  }
}

/// Volume norms of the valid `to` descriptors in blocks of kLanes, volume-major inside a block:
/// block b, volume g, lane l at norms[(b * kShotVolumes + g) * kLanes + l]; far values pad the last block.
struct BoundIndex {
  const ShotDescriptors* set = nullptr;
  std::vector<float> norms;
  std::vector<std::uint32_t> rows;  // lane index -> descriptor index
  std::size_t blocks = 0;
};

BoundIndex make_bound_index(const ShotDescriptors& to) {
  BoundIndex x;
  x.set = &to;
  for (std::size_t i = 0; i < to.size(); ++i)
    if (to.valid[i]) x.rows.push_back(std::uint32_t(i));
  x.blocks = (x.rows.size() + kLanes - 1) / kLanes;
  x.norms.assign(x.blocks * kShotVolumes * kLanes, 1e15f);
  float g[kShotVolumes];
  for (std::size_t r = 0; r < x.rows.size(); ++r) {
    volume_norms(to.descriptor(x.rows[r]), g);
    float* dst = x.norms.data() + (r / kLanes) * kShotVolumes * kLanes + r % kLanes;
    for (int v = 0; v < kShotVolumes; ++v) dst[std::size_t(v) * kLanes] = g[v];
  }
  return x;
}

/// A bound is compared with a margin, so float rounding in it can never discard a candidate whose
/// exact distance would win.
inline float with_margin(float bound) { return bound * (1.0f + 1e-4f) + 1e-7f; }

struct Candidate {
  float bound;
  std::uint32_t row;
  bool operator<(const Candidate& o) const { return bound < o.bound || (bound == o.bound && row < o.row); }
};

/// Exact nearest neighbour of `q` (lowest index on ties) when it is closer than `limit`.
Nearest nearest_scan(std::span<const float> q, const BoundIndex& x, float limit, std::vector<Candidate>& cand) {
  float gq[kShotVolumes];
  volume_norms(q, gq);
  cand.clear();
  const float keep = with_margin(limit);
  for (std::size_t blk = 0; blk < x.blocks; ++blk) {
    const float* t = x.norms.data() + blk * kShotVolumes * kLanes;
    Lanes lb = Lanes::Zero();
    for (int g = 0; g < kShotVolumes; ++g) lb += (gq[g] - Eigen::Map<const Lanes>(t + std::size_t(g) * kLanes)).square();
    if ((lb >= keep).all()) continue;
    for (int l = 0; l < kLanes; ++l) {
      const std::size_t r = blk * kLanes + std::size_t(l);
      if (r < x.rows.size() && lb[l] < keep) cand.push_back({lb[l], std::uint32_t(r)});
    }
  }
  std::sort(cand.begin(), cand.end());
  Nearest best;
  for (const Candidate& c : cand) {
    if (c.bound > with_margin(std::min(best.squared_distance, limit))) break;  // no later one can win
    // Exact distance, bin by bin in order; abandoned once the exact prefix plus the bound of the
    // remaining volumes exceeds the best distance so far (or the limit).
    const std::uint32_t index = x.rows[c.row];
    const std::span<const float> t = x.set->descriptor(index);
    const float* tn = x.norms.data() + (c.row / kLanes) * kShotVolumes * kLanes + c.row % kLanes;
    const float bound = with_margin(std::min(best.squared_distance, limit));
    float d = 0.0f, rest = c.bound;
    bool abandoned = false;
    for (int g = 0; g < kShotVolumes && !abandoned; ++g) {
      for (int b = g * kShotBinsPerVolume; b < (g + 1) * kShotBinsPerVolume; ++b) {
        const float diff = q[std::size_t(b)] - t[std::size_t(b)];
        d += diff * diff;
      }
      const float e = gq[g] - tn[std::size_t(g) * kLanes];
      rest = std::max(rest - e * e, 0.0f);
      abandoned = d + rest > bound;
    }
    if (abandoned) continue;
    if (d < best.squared_distance || (d == best.squared_distance && index < best.index)) best = {index, d};
  }
  return best;
}

/// Nearest valid `to` descriptor of every valid `from` descriptor (exact whenever it is closer
/// than `limit`).
std::vector<Nearest> nearest_scan_all(const ShotDescriptors& from, const ShotDescriptors& to, float limit) {
  const BoundIndex index = make_bound_index(to);
  std::vector<Nearest> out(from.size());
  if (index.rows.empty()) return out;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, from.size(), 16), [&](const auto& r) {
    std::vector<Candidate> cand;
    for (std::size_t i = r.begin(); i != r.end(); ++i)
      if (from.valid[i]) out[i] = nearest_scan(from.descriptor(i), index, limit, cand);
  });
  return out;
}

}  // namespace

std::vector<Correspondence> match_descriptors(const ShotDescriptors& source, const ShotDescriptors& target,
                                              const MatchConfig& cfg) {
  cfg.validate();
  if (source.data.size() != source.size() * kShotSize || target.data.size() != target.size() * kShotSize)
    throw InputError("match_descriptors: descriptor data and valid flags disagree in size");
  const float threshold = static_cast<float>(cfg.max_squared_distance);
  // Pairs at or beyond the threshold are dropped, so the scan may stop looking
  // there: the result is the same. (A mutual partner is always closer than the pair itself.)
  const auto nearest = [&](const ShotDescriptors& from, const ShotDescriptors& to) {
    return cfg.search == "kdtree" ? nearest_kdtree(from, to) : nearest_scan_all(from, to, threshold);
  };
  const std::vector<Nearest> forward = nearest(source, target);
  std::vector<Nearest> backward;
  if (cfg.mutual) backward = nearest(target, source);
  std::vector<Correspondence> out;
  for (std::size_t i = 0; i < forward.size(); ++i) {
    const Nearest& f = forward[i];
    if (f.index == kNone || !(f.squared_distance < threshold)) continue;
    if (cfg.mutual && backward[f.index].index != i) continue;
    out.push_back({std::uint32_t(i), f.index, f.squared_distance});
  }
  return out;
}

}  // namespace cairn
