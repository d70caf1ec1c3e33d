#pragma once
// The frame of a 2-D grid over the xy extent of a point set: cell (ix, iy) covers
// [x0 + ix·cell, x0 + (ix+1)·cell) × [y0 + iy·cell, ...); positions outside clamp to the border.
// Shared by the ground model's height grids and the object footprint of segmentation.
#include <algorithm>
#include <span>
#include <string>

#include "cairn/core/error.hpp"
#include "cairn/core/point_cloud.hpp"

namespace cairn {

struct GridFrame {
  static constexpr std::size_t kMaxCells = 50'000'000;

  int nx = 1, ny = 1;
  float x0 = 0, y0 = 0, cell = 1;

  /// Frame covering the points' xy extent. Throws ConfigError naming `what` when the cell is so
  /// small that more than kMaxCells cells would be needed.
  static GridFrame covering(std::span<const Vec3f> pts, float cell, const std::string& what) {
    const Aabb box = bounds(pts);
    GridFrame f;
    f.cell = cell;
    f.x0 = box.min.x();
    f.y0 = box.min.y();
    f.nx = int((box.max.x() - box.min.x()) / cell) + 1;
    f.ny = int((box.max.y() - box.min.y()) / cell) + 1;
    if (std::size_t(f.nx) * std::size_t(f.ny) > kMaxCells)
      throw ConfigError(what + ": cell of " + std::to_string(cell) + " m is too small for the extent");
    return f;
  }

  [[nodiscard]] std::size_t num_cells() const { return std::size_t(nx) * std::size_t(ny); }
  [[nodiscard]] int ix(float x) const { return std::clamp(int((x - x0) / cell), 0, nx - 1); }
  [[nodiscard]] int iy(float y) const { return std::clamp(int((y - y0) / cell), 0, ny - 1); }
  [[nodiscard]] std::size_t index(int x, int y) const { return std::size_t(y) * std::size_t(nx) + std::size_t(x); }
  [[nodiscard]] std::size_t index_of(const Vec3f& p) const { return index(ix(p.x()), iy(p.y())); }
};

}  // namespace cairn
