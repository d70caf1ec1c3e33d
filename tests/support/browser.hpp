#pragma once
// Opening a report in headless Chromium (Debian `chromium`): the DOM after the page's scripts
// ran (the viewer writes its self-check into #status and data-viewer, errors into #errors) and a
// screenshot decoded (8-bit RGB/RGBA PNG) for pixel checks. In CI a missing browser is a failure.
#include <gtest/gtest.h>
#include <zlib.h>

#include <array>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <optional>
#include <string>
#include <vector>

#include "support/process.hpp"
#include "support/test_data.hpp"

namespace cairn::test {

inline std::optional<std::string> find_chromium() {
  for (const char* p : {"/usr/bin/chromium", "/usr/bin/chromium-browser", "/usr/bin/google-chrome"})
    if (std::filesystem::exists(p)) return std::string(p);
  return std::nullopt;
}

inline std::string chromium_command(const std::string& exe, const std::string& action, const std::filesystem::path& page) {
  return exe + " --headless --no-sandbox --disable-gpu --enable-unsafe-swiftshader --virtual-time-budget=15000"
               " --window-size=1280,1000 " + action + " 'file://" + std::filesystem::absolute(page).string() + "' 2>/dev/null";
}

/// The text between `open` and the next '<' in `dom` (empty when absent).
inline std::string element_text(const std::string& dom, const std::string& open) {
  const auto a = dom.find(open);
  if (a == std::string::npos) return "";
  const auto b = dom.find('<', a + open.size());
  return dom.substr(a + open.size(), b - a - open.size());
}

struct DecodedPng {
  int width = 0, height = 0, channels = 0;
  std::vector<std::uint8_t> pixels;  // row-major, `channels` bytes per pixel
};

/// Decodes a non-interlaced 8-bit RGB or RGBA PNG; nullopt otherwise.
inline std::optional<DecodedPng> read_png(const std::filesystem::path& file) {
  std::ifstream f(file, std::ios::binary);
  const std::string s{std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
  if (s.size() < 8 || s.compare(1, 3, "PNG") != 0) return std::nullopt;
  const auto be32 = [&](std::size_t i) {
    return std::uint32_t(std::uint8_t(s[i])) << 24 | std::uint32_t(std::uint8_t(s[i + 1])) << 16 |
           std::uint32_t(std::uint8_t(s[i + 2])) << 8 | std::uint32_t(std::uint8_t(s[i + 3]));
  };
  DecodedPng png;
  std::string idat;
  for (std::size_t i = 8; i + 8 <= s.size();) {
    const std::uint32_t len = be32(i);
    const std::string type = s.substr(i + 4, 4);
    if (i + 12 + len > s.size()) return std::nullopt;
    if (type == "IHDR") {
      png.width = int(be32(i + 8)), png.height = int(be32(i + 12));
      const int depth = std::uint8_t(s[i + 16]), color = std::uint8_t(s[i + 17]), interlace = std::uint8_t(s[i + 20]);
      if (depth != 8 || (color != 2 && color != 6) || interlace != 0) return std::nullopt;
      png.channels = color == 2 ? 3 : 4;
    } else if (type == "IDAT") {
      idat += s.substr(i + 8, len);
    }
    i += 12 + len;
  }
  const std::size_t stride = std::size_t(png.width) * png.channels;
  std::vector<std::uint8_t> raw((stride + 1) * png.height);
  uLongf n = raw.size();
  if (png.channels == 0 ||
      uncompress(raw.data(), &n, reinterpret_cast<const Bytef*>(idat.data()), uLong(idat.size())) != Z_OK ||
      n != raw.size())
    return std::nullopt;
  png.pixels.resize(stride * png.height);
  const int bpp = png.channels;
  for (int y = 0; y < png.height; ++y) {
    const std::uint8_t filter = raw[y * (stride + 1)];
    const std::uint8_t* in = &raw[y * (stride + 1) + 1];
    std::uint8_t* out = &png.pixels[y * stride];
    const std::uint8_t* up = y > 0 ? &png.pixels[(y - 1) * stride] : nullptr;
    for (std::size_t x = 0; x < stride; ++x) {
      const int a = x >= std::size_t(bpp) ? out[x - bpp] : 0, b = up ? up[x] : 0,
                c = up && x >= std::size_t(bpp) ? up[x - bpp] : 0;
      int pred = 0;
      if (filter == 1) pred = a;
      else if (filter == 2) pred = b;
      else if (filter == 3) pred = (a + b) / 2;
      else if (filter == 4) {
        const int p = a + b - c, pa = std::abs(p - a), pb = std::abs(p - b), pc = std::abs(p - c);
        pred = pa <= pb && pa <= pc ? a : pb <= pc ? b : c;
      }
      out[x] = std::uint8_t(in[x] + pred);
    }
  }
  return png;
}

struct PageResult {
  bool opened = false;
  std::string viewer, status, errors;
  std::optional<DecodedPng> screenshot;
};

/// Opens `page` headless: DOM (viewer state, status, errors) and a 1280x1000 screenshot.
inline PageResult open_in_chromium(const std::filesystem::path& page, const std::filesystem::path& screenshot) {
  PageResult r;
  const auto exe = find_chromium();
  if (!exe) return r;
  const std::string dom = run_command(chromium_command(*exe, "--dump-dom", page)).out;
  r.opened = dom.find("</html>") != std::string::npos;
  r.viewer = element_text(dom, "data-viewer=\"");
  if (const auto q = r.viewer.find('"'); q != std::string::npos) r.viewer.resize(q);
  r.status = element_text(dom, "<div id=\"status\">");
  r.errors = element_text(dom, "<pre id=\"errors\">");
  std::filesystem::remove(screenshot);
  (void)run_command(chromium_command(*exe, "--screenshot='" + screenshot.string() + "'", page));
  r.screenshot = read_png(screenshot);
  return r;
}

/// Share of the screenshot's pixels within `tolerance` (sum of channel differences) of `rgb`.
inline double share_of_color(const DecodedPng& png, std::array<int, 3> rgb, int tolerance) {
  std::size_t n = 0;
  for (std::size_t i = 0; i + 2 < png.pixels.size(); i += std::size_t(png.channels))
    n += std::abs(png.pixels[i] - rgb[0]) + std::abs(png.pixels[i + 1] - rgb[1]) + std::abs(png.pixels[i + 2] - rgb[2]) <= tolerance;
  return double(n) / (double(png.width) * png.height);
}

/// Share of "coloured" pixels (max - min channel above `chroma`): points and boxes, not text.
inline double share_of_chroma(const DecodedPng& png, int chroma) {
  std::size_t n = 0;
  for (std::size_t i = 0; i + 2 < png.pixels.size(); i += std::size_t(png.channels)) {
    const int hi = std::max({png.pixels[i], png.pixels[i + 1], png.pixels[i + 2]});
    const int lo = std::min({png.pixels[i], png.pixels[i + 1], png.pixels[i + 2]});
    n += hi - lo > chroma;
  }
  return double(n) / (double(png.width) * png.height);
}

/// The report check of issue #18: it opens, no console error, the viewer drew (its own check and
/// the screenshot: the canvas's background present, points on it). A missing browser skips
/// outside CI and fails in CI.
inline void expect_report_opens(const std::filesystem::path& page, const std::filesystem::path& screenshot) {
  if (!find_chromium()) {
    if (in_ci()) FAIL() << "chromium not installed (scripts/install_deps.sh --tests)";
    GTEST_SKIP() << "chromium not installed";
  }
  const PageResult r = open_in_chromium(page, screenshot);
  ASSERT_TRUE(r.opened) << page;
  EXPECT_EQ(r.errors, "") << "console errors";
  EXPECT_EQ(r.viewer, "ok") << r.status;
  ASSERT_TRUE(r.screenshot.has_value()) << screenshot;
  const double background = share_of_color(*r.screenshot, {0x1d, 0x26, 0x30}, 6);
  const double drawn = share_of_chroma(*r.screenshot, 40);
  std::printf("report: %s; screenshot %dx%d: %.1f %% canvas background, %.2f %% coloured\n", r.status.c_str(),
              r.screenshot->width, r.screenshot->height, 100 * background, 100 * drawn);
  EXPECT_GT(background, 0.10) << "the viewer's canvas is missing from the screenshot";
  EXPECT_GT(drawn, 0.0005) << "nothing coloured drawn";  // a blank canvas has none; 1 stone ~0.3 %
}

}  // namespace cairn::test
