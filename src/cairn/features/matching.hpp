#pragma once
// Descriptor matching (Sec. 4.4, step 3): for every source descriptor its nearest target
// descriptor in descriptor space — the exact nearest neighbour that pcl::KdTreeFLANN<pcl::SHOT352>
// returns in PCL's correspondence-grouping tutorial — kept when the squared distance is below a
// threshold.
//
// Two exact searches give the same pairs and the same (bit-identical) squared distances, summed
// bin by bin in float as FLANN's L2_Simple:
// - "scan" (default): a linear scan over the target descriptors with a lower bound: per SHOT
//   spatial volume (32 × 11 bins), |q − t|² ≥ Σ_volumes (‖q_v‖ − ‖t_v‖)² (reverse triangle
//   inequality). The 32-D bound is evaluated for every target (SIMD, 8 targets at a time); full
//   352-D distances only for targets in ascending bound order until the bound exceeds the best
//   distance so far or the acceptance threshold (pairs beyond it are dropped anyway).
// - "kdtree": nanoflann with a run-time dimension, leaf size 15 (as KdTreeFLANN). In 352
//   dimensions a kd-tree prunes little: it is several times slower than "scan" (docs/features.md).
// On equal distances (duplicate descriptors) "scan" returns the lowest target index; which one a
// kd-tree returns depends on its traversal.
#include <cstdint>
#include <string>
#include <vector>

#include "cairn/features/shot.hpp"

namespace cairn {

struct MatchConfig {
  double max_squared_distance = 0.25;  // PCL correspondence-grouping tutorial: accept when squared distance < 0.25
  bool mutual = false;                 // keep only mutual nearest neighbours
  std::string search = "scan";  // "scan" | "kdtree": same result, see above

  template <class V>
  void visit(V&& v) {
    v("max_squared_distance", max_squared_distance,
      "a descriptor pair is kept when its squared L2 distance is below this (PCL tutorial: 0.25)");
    v("mutual", mutual, "keep only pairs that are each other's nearest neighbour");
    v("search", search, "exact nearest-neighbour search: scan (lower-bound pruned linear scan) or kdtree (nanoflann)");
  }

  /// Throws ConfigError naming the key if a value is out of range.
  void validate() const;
};

/// A pair of keypoints: `source` indexes the source descriptors/keypoints, `target` the target
/// ones. squared_distance is the squared L2 distance of the two descriptors.
struct Correspondence {
  std::uint32_t source = 0, target = 0;
  float squared_distance = 0.0f;
};

/// For every valid source descriptor its nearest valid target descriptor (if below the threshold),
/// in ascending source order. Deterministic, TBB-parallel over the source descriptors. Throws
/// ConfigError on a bad config.
[[nodiscard]] std::vector<Correspondence> match_descriptors(const ShotDescriptors& source, const ShotDescriptors& target,
                                                            const MatchConfig& cfg);

}  // namespace cairn
