#include "cairn/segmentation/evaluation.hpp"

#include <algorithm>
#include <map>

#include "cairn/core/error.hpp"
#include "cairn/core/kdtree.hpp"

namespace cairn {

std::size_t SegmentationScore::found(double complete) const {
  std::map<std::int32_t, int> owners;
  for (const auto& o : objects) ++owners[o.best_segment];
  std::size_t n = 0;
  for (const auto& o : objects)
    n += o.completeness() >= complete && o.significant_segments == 1 && owners[o.best_segment] == 1;
  return n;
}

std::size_t SegmentationScore::single(double complete, double pure) const {
  return std::size_t(std::count_if(objects.begin(), objects.end(), [&](const ObjectScore& o) {
    return o.completeness() >= complete && o.purity() >= pure;
  }));
}

double BinaryScore::precision() const {
  const std::size_t predicted = true_positive + false_positive;
  return predicted ? double(true_positive) / double(predicted) : 0.0;
}

double BinaryScore::recall() const {
  const std::size_t positive = true_positive + false_negative;
  return positive ? double(true_positive) / double(positive) : 0.0;
}

double BinaryScore::f1() const {
  const double p = precision(), r = recall();
  return p + r > 0 ? 2 * p * r / (p + r) : 0.0;
}

BinaryScore score_binary(const std::vector<std::uint8_t>& predicted, const std::vector<std::uint8_t>& truth) {
  if (predicted.size() != truth.size())
    throw InputError("score_binary: " + std::to_string(predicted.size()) + " predictions for " +
                     std::to_string(truth.size()) + " truth labels");
  BinaryScore s;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    if (predicted[i])
      ++(truth[i] ? s.true_positive : s.false_positive);
    else
      ++(truth[i] ? s.false_negative : s.true_negative);
  }
  return s;
}

nlohmann::json SegmentationScore::to_json(double complete) const {
  nlohmann::json j{{"objects", objects.size()},
                   {"found", found(complete)},
                   {"single", single()},
                   {"segments", segments},
                   {"terrain_segments", terrain_segments},
                   {"merged_segments", merged}};
  j["completeness"] = nlohmann::json::array();
  j["purity"] = nlohmann::json::array();
  for (const auto& o : objects) {
    j["completeness"].push_back(o.completeness());
    j["purity"].push_back(o.purity());
  }
  return j;
}

SegmentationScore score_segmentation(const std::vector<std::int32_t>& labels, const std::vector<std::int32_t>& truth,
                                     int num_objects, double split_fraction) {
  if (labels.size() != truth.size())
    throw InputError("score_segmentation: " + std::to_string(labels.size()) + " labels for " +
                     std::to_string(truth.size()) + " truth values");
  SegmentationScore s;
  s.objects.resize(std::size_t(std::max(num_objects, 0)));
  std::map<std::pair<std::int32_t, std::int32_t>, std::size_t> overlap;  // (object, segment)
  std::map<std::int32_t, std::pair<std::size_t, std::size_t>> seg;       // size, terrain points
  for (std::size_t i = 0; i < truth.size(); ++i) {
    const bool object = truth[i] >= 0 && truth[i] < num_objects;
    if (object) ++s.objects[std::size_t(truth[i])].points;
    if (labels[i] < 0) continue;
    auto& [size, terrain] = seg[labels[i]];
    ++size;
    terrain += !object;
    if (object) ++overlap[{truth[i], labels[i]}];
  }
  for (const auto& [key, n] : overlap) {
    ObjectScore& o = s.objects[std::size_t(key.first)];
    if (n > o.best_overlap) o.best_overlap = n, o.best_segment = key.second;
    if (double(n) >= split_fraction * double(o.points)) ++o.significant_segments;
  }
  for (auto& o : s.objects)
    if (o.best_segment >= 0) o.segment_points = seg[o.best_segment].first;
  s.segments = seg.size();
  for (const auto& [id, st] : seg) s.terrain_segments += st.second * 2 > st.first;
  std::map<std::int32_t, int> owners;
  for (const auto& o : s.objects)
    if (o.best_segment >= 0) ++owners[o.best_segment];
  for (const auto& [id, n] : owners) s.merged += n > 1;
  return s;
}

std::vector<std::int32_t> transfer_labels(const PointCloud& reference, const PointCloud& points, double max_distance,
                                          std::int32_t unmatched) {
  if (reference.labels.size() != reference.size())
    throw InputError("transfer_labels: the reference cloud has no labels");
  std::vector<std::int32_t> out(points.size(), unmatched);
  if (reference.empty() || points.empty()) return out;
  const KdTree tree(reference.points);
  const Eigen::Vector3d shift = points.origin - reference.origin;  // points -> reference coordinates
  const double max_d2 = max_distance * max_distance;
  Neighbors nn;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Vec3f q = (points.points[i].cast<double>() + shift).cast<float>();
    tree.knn(q, 1, nn);
    if (!nn.indices.empty() && double(nn.sq_dists[0]) <= max_d2) out[i] = reference.labels[nn.indices[0]];
  }
  return out;
}

}  // namespace cairn
