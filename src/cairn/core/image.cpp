#include "cairn/core/image.hpp"

#include <zlib.h>

#include <algorithm>
#include <array>
#include <fstream>
#include <limits>

#include "cairn/core/error.hpp"

namespace cairn {
namespace {

void put_u32(std::vector<std::uint8_t>& out, std::uint32_t v) {
  for (int s = 24; s >= 0; s -= 8) out.push_back(std::uint8_t(v >> s));
}

void put_chunk(std::ofstream& f, const char* type, const std::vector<std::uint8_t>& data) {
  std::vector<std::uint8_t> buf;
  put_u32(buf, std::uint32_t(data.size()));
  buf.insert(buf.end(), type, type + 4);
  buf.insert(buf.end(), data.begin(), data.end());
  const auto crc = crc32(0, buf.data() + 4, uInt(buf.size() - 4));
  put_u32(buf, std::uint32_t(crc));
  f.write(reinterpret_cast<const char*>(buf.data()), std::streamsize(buf.size()));
}

}  // namespace

void write_png(const std::filesystem::path& path, const Image& img) {
  std::vector<std::uint8_t> raw;  // each row: filter byte 0, then RGB
  raw.reserve(std::size_t(img.height) * (1 + 3 * std::size_t(img.width)));
  for (int y = 0; y < img.height; ++y) {
    raw.push_back(0);
    for (int x = 0; x < img.width; ++x) {
      const Rgb& p = img.pixels[std::size_t(y) * img.width + x];
      raw.insert(raw.end(), {p.r, p.g, p.b});
    }
  }
  uLongf size = compressBound(uLong(raw.size()));
  std::vector<std::uint8_t> packed(size);
  if (compress2(packed.data(), &size, raw.data(), uLong(raw.size()), Z_BEST_SPEED) != Z_OK)
    throw InputError(path.string() + ": PNG compression failed");
  packed.resize(size);
  std::ofstream f(path, std::ios::binary);
  if (!f) throw InputError(path.string() + ": cannot write PNG");
  constexpr std::array<std::uint8_t, 8> kSignature{0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
  f.write(reinterpret_cast<const char*>(kSignature.data()), kSignature.size());
  std::vector<std::uint8_t> ihdr;
  put_u32(ihdr, std::uint32_t(img.width));
  put_u32(ihdr, std::uint32_t(img.height));
  ihdr.insert(ihdr.end(), {8, 2, 0, 0, 0});  // 8 bit, RGB, deflate, no filter, no interlace
  put_chunk(f, "IHDR", ihdr);
  put_chunk(f, "IDAT", packed);
  put_chunk(f, "IEND", {});
  if (!f) throw InputError(path.string() + ": PNG write failed");
}

Image render_top_view(const PointCloud& cloud, const std::vector<Rgb>& colors, double ppm) {
  return render_top_view(cloud, colors, ppm, bounds(cloud.points));
}

Image side_by_side(const Image& left, const Image& right, int gap) {
  Image out(left.width + gap + right.width, std::max(left.height, right.height));
  for (int y = 0; y < left.height; ++y)
    for (int x = 0; x < left.width; ++x) out.at(x, y) = left.pixels[std::size_t(y) * left.width + x];
  for (int y = 0; y < right.height; ++y)
    for (int x = 0; x < right.width; ++x)
      out.at(left.width + gap + x, y) = right.pixels[std::size_t(y) * right.width + x];
  return out;
}

Image render_top_view(const PointCloud& cloud, const std::vector<Rgb>& colors, double ppm, const Aabb& box) {
  constexpr int kMargin = 10;
  constexpr int kSplat = 2;  // [pixels]
  const int w = int((box.max.x() - box.min.x()) * ppm) + 2 * kMargin + 1;
  const int h = int((box.max.y() - box.min.y()) * ppm) + 2 * kMargin + 1;
  Image img(std::max(w, 1), std::max(h, 1));
  std::vector<float> zbuf(img.pixels.size(), std::numeric_limits<float>::lowest());
  const float zr = std::max(1e-3f, box.max.z() - box.min.z());
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const Vec3f& p = cloud.points[i];
    if (!p.allFinite() || p.x() < box.min.x() || p.y() < box.min.y() || p.x() > box.max.x() || p.y() > box.max.y())
      continue;
    const int x0 = kMargin + int((p.x() - box.min.x()) * ppm);
    const int y0 = img.height - 1 - kMargin - int((p.y() - box.min.y()) * ppm);
    const float shade = std::clamp(0.55f + 0.45f * (p.z() - box.min.z()) / zr, 0.0f, 1.0f);  // higher = brighter
    const Rgb c = colors[i];
    for (int y = y0; y < y0 + kSplat; ++y)  // each point a small square splat
      for (int x = x0; x < x0 + kSplat; ++x) {
        if (x < 0 || y < 0 || x >= img.width || y >= img.height) continue;
        float& z = zbuf[std::size_t(y) * img.width + x];
        if (p.z() < z) continue;
        z = p.z();
        img.at(x, y) = {std::uint8_t(c.r * shade), std::uint8_t(c.g * shade), std::uint8_t(c.b * shade)};
      }
  }
  return img;
}

}  // namespace cairn
