#pragma once
// The report's web assets, compiled into the library (assets.cpp): three.js 0.170.0 and its
// OrbitControls from the npm registry (web/package-lock.json), the viewer and the style sheet.
#include <string_view>

namespace cairn::report::assets {

[[nodiscard]] std::string_view three_js();
[[nodiscard]] std::string_view orbit_controls_js();
[[nodiscard]] std::string_view viewer_js();
[[nodiscard]] std::string_view report_css();

}  // namespace cairn::report::assets
