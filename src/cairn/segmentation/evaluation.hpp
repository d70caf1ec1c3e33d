#pragma once
// Scoring a segmentation against per-point ground truth (simulator labels: -1 terrain, k object).
#include <cstdint>
#include <nlohmann/json.hpp>
#include <vector>

#include "cairn/core/point_cloud.hpp"

namespace cairn {

struct ObjectScore {
  std::size_t points = 0;              // true points of the object
  std::size_t best_overlap = 0;        // of them, in the segment holding most of them
  std::int32_t best_segment = -1;
  std::size_t significant_segments = 0;  // segments holding >= split_fraction of the object
  std::size_t segment_points = 0;        // size of the best segment
  [[nodiscard]] double completeness() const { return points ? double(best_overlap) / double(points) : 0.0; }
  /// Share of the best segment that is this object.
  [[nodiscard]] double purity() const { return segment_points ? double(best_overlap) / double(segment_points) : 0.0; }
};

struct SegmentationScore {
  std::vector<ObjectScore> objects;
  std::size_t segments = 0;          // object segments produced
  std::size_t terrain_segments = 0;  // segments whose majority is terrain (truth < 0)
  std::size_t merged = 0;            // segments that are the best segment of several objects
  /// Objects found as exactly one segment holding >= `complete` of their points, not merged.
  [[nodiscard]] std::size_t found(double complete = 0.95) const;
  /// Piles (issue #21): objects whose best segment holds >= `complete` of their points and is
  /// >= `pure` that object (a stone split off with a little of its neighbour still counts).
  [[nodiscard]] std::size_t single(double complete = 0.9, double pure = 0.9) const;
  [[nodiscard]] nlohmann::json to_json(double complete = 0.95) const;
};

/// `labels`: segment id per point (negative: none); `truth`: object index per point (negative:
/// terrain/none); `num_objects`: number of true objects.
[[nodiscard]] SegmentationScore score_segmentation(const std::vector<std::int32_t>& labels,
                                                   const std::vector<std::int32_t>& truth, int num_objects,
                                                   double split_fraction = 0.05);

/// A binary labelling (e.g. ground / not ground) against per-point truth.
struct BinaryScore {
  std::size_t true_positive = 0, false_positive = 0, false_negative = 0, true_negative = 0;
  [[nodiscard]] double precision() const;  // 0 when nothing was predicted
  [[nodiscard]] double recall() const;     // 0 when nothing is true
  [[nodiscard]] double f1() const;         // harmonic mean of the two; 0 when both are 0
};

/// `predicted` and `truth`: one flag per point, equal lengths (throws InputError otherwise).
[[nodiscard]] BinaryScore score_binary(const std::vector<std::uint8_t>& predicted, const std::vector<std::uint8_t>& truth);

/// Ground truth for points that carry none (e.g. a map built by the mapping stage): the label of
/// the nearest point of a labelled reference cloud (e.g. the simulator's truth/map_snapshot.ply),
/// or `unmatched` when that point is farther than `max_distance` [m]. Both clouds in one frame
/// (world coordinates, origins honoured).
[[nodiscard]] std::vector<std::int32_t> transfer_labels(const PointCloud& reference, const PointCloud& points,
                                                        double max_distance, std::int32_t unmatched = -2);

}  // namespace cairn
