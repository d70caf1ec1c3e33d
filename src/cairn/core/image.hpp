#pragma once
// RGB images and PNG output (zlib), for pictures a person would rather look at than read.
#include <cstdint>
#include <filesystem>
#include <vector>

#include "cairn/core/point_cloud.hpp"

namespace cairn {

struct Image {
  int width = 0, height = 0;
  std::vector<Rgb> pixels;  // row-major, top row first
  Image(int w, int h, Rgb fill = {255, 255, 255}) : width(w), height(h), pixels(std::size_t(w) * h, fill) {}
  Rgb& at(int x, int y) { return pixels[std::size_t(y) * width + x]; }
};

/// Writes an 8-bit RGB PNG. Throws InputError on failure.
void write_png(const std::filesystem::path& path, const Image& image);

/// Top view (x right, y up) of a cloud, one colour per point; higher points drawn over lower
/// ones, shaded by height. `pixels_per_metre` sets the scale.
[[nodiscard]] Image render_top_view(const PointCloud& cloud, const std::vector<Rgb>& colors,
                                    double pixels_per_metre);
/// The same over a given box (points outside it are left out), so several views share one scale
/// and extent. Height shading uses the box's z range.
[[nodiscard]] Image render_top_view(const PointCloud& cloud, const std::vector<Rgb>& colors,
                                    double pixels_per_metre, const Aabb& box);

/// Two images next to each other with a white gap of `gap` pixels.
[[nodiscard]] Image side_by_side(const Image& left, const Image& right, int gap = 20);

}  // namespace cairn
