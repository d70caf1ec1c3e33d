#pragma once
// Small sample statistics shared by the stages and the evaluation (one definition of each).

#include <algorithm>
#include <cstddef>
#include <limits>
#include <vector>

namespace cairn {

/// The median of a sample (the mean of the two middle values when the count is even); NaN when
/// the sample is empty.
[[nodiscard]] inline double median(std::vector<double> v) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  const auto mid = v.begin() + std::ptrdiff_t(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  if (v.size() % 2) return *mid;
  return 0.5 * (*mid + *std::max_element(v.begin(), mid));
}

}  // namespace cairn
