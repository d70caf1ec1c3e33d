// Each asset as a read-only symbol pair (begin, end) in the object file: the assembler includes
// the file at build time (.incbin), so no asset is read or downloaded at run time. The paths come
// from src/cairn/report/CMakeLists.txt; a changed asset rebuilds this file (OBJECT_DEPENDS).
#include "cairn/report/assets.hpp"

#define CAIRN_ASSET(name, path)                                                             \
  __asm__(".section .rodata\n.balign 16\n.global cairn_asset_" #name "_begin\ncairn_asset_" #name \
          "_begin:\n.incbin \"" path "\"\n.global cairn_asset_" #name "_end\ncairn_asset_" #name     \
          "_end:\n.byte 0\n.previous\n");                                                   \
  extern "C" const char cairn_asset_##name##_begin[], cairn_asset_##name##_end[];

CAIRN_ASSET(three, CAIRN_THREE_JS)
CAIRN_ASSET(orbit, CAIRN_ORBIT_JS)
CAIRN_ASSET(viewer, CAIRN_VIEWER_JS)
CAIRN_ASSET(css, CAIRN_REPORT_CSS)

namespace cairn::report::assets {
namespace {
std::string_view view(const char* begin, const char* end) { return {begin, std::size_t(end - begin)}; }
}  // namespace

std::string_view three_js() { return view(cairn_asset_three_begin, cairn_asset_three_end); }
std::string_view orbit_controls_js() { return view(cairn_asset_orbit_begin, cairn_asset_orbit_end); }
std::string_view viewer_js() { return view(cairn_asset_viewer_begin, cairn_asset_viewer_end); }
std::string_view report_css() { return view(cairn_asset_css_begin, cairn_asset_css_end); }

}  // namespace cairn::report::assets
