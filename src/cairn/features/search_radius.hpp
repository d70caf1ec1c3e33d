#pragma once
// Internal helper of cairn_features: the float radius for KdTree::for_each_in_radius that selects
// exactly the neighbours PCL's KdTreeFLANN::radiusSearch selects. PCL passes
// float(radius * radius) (squared in double) to FLANN, which keeps d² < that; cairn's KdTree keeps
// d² < r_f * r_f (squared in float). The two thresholds can differ in the last bit, so pick the
// float r_f whose float square equals PCL's threshold (or the largest one below it).
#include <cmath>

namespace cairn::detail {

[[nodiscard]] inline float pcl_equivalent_radius(double radius) {
  const float target = static_cast<float>(radius * radius);
  float r = static_cast<float>(std::sqrt(static_cast<double>(target)));
  for (int i = 0; i < 4 && r * r > target; ++i) r = std::nextafter(r, 0.0f);
  for (int i = 0; i < 4; ++i) {
    const float up = std::nextafter(r, 1e30f);
    if (up * up <= target) r = up;
  }
  return r;
}

}  // namespace cairn::detail
