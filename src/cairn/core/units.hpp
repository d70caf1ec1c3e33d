#pragma once
// Angle units, defined once: `30.0 * kDeg` is 30 degrees in radians, `angle * kDegPerRad` degrees.
#include <numbers>

namespace cairn {

inline constexpr double kDeg = std::numbers::pi / 180.0;        // [rad] one degree
inline constexpr double kDegPerRad = 180.0 / std::numbers::pi;  // radians to degrees

}  // namespace cairn
