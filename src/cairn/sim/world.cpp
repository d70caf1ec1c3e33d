#include "cairn/sim/world.hpp"

#include <cmath>
#include <string>

#include "cairn/core/error.hpp"

namespace cairn::sim {

namespace {
constexpr double kMaxTerrainVertices = 67108864.0;  // 2^26
}

io::Mesh terrain_mesh(const Terrain& terrain, double spacing) {
  const auto& c = terrain.config;
  if (!(spacing > 0.0)) throw ConfigError("terrain_mesh: spacing must be positive");
  const int nx = static_cast<int>(std::ceil(c.size_x / spacing)) + 1;
  const int ny = static_cast<int>(std::ceil(c.size_y / spacing)) + 1;
  if (static_cast<double>(nx) * ny > kMaxTerrainVertices) {
    throw ConfigError("terrain_mesh: spacing " + std::to_string(spacing) + " m gives too many vertices");
  }
  const double dx = c.size_x / (nx - 1), dy = c.size_y / (ny - 1);
  io::Mesh mesh;
  mesh.vertices.points.reserve(static_cast<std::size_t>(nx) * ny);
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) {
      const double x = -0.5 * c.size_x + i * dx, y = -0.5 * c.size_y + j * dy;
      mesh.vertices.points.emplace_back(static_cast<float>(x), static_cast<float>(y),
                                        static_cast<float>(terrain.height(x, y)));
    }
  }
  mesh.triangles.reserve(static_cast<std::size_t>(nx - 1) * (ny - 1) * 2);
  for (int j = 0; j + 1 < ny; ++j) {
    for (int i = 0; i + 1 < nx; ++i) {
      const auto v00 = static_cast<std::uint32_t>(j * nx + i), v10 = v00 + 1;
      const auto v01 = static_cast<std::uint32_t>(v00 + nx), v11 = v01 + 1;
      mesh.triangles.push_back({v00, v10, v11});  // counter-clockwise seen from above
      mesh.triangles.push_back({v00, v11, v01});
    }
  }
  return mesh;
}

io::Mesh terrain_apron(const Terrain& terrain, double spacing, double reach) {
  const auto& c = terrain.config;
  if (!(spacing > 0.0)) throw ConfigError("terrain_apron: spacing must be positive");
  io::Mesh mesh;
  if (reach <= 0.5 * std::max(c.size_x, c.size_y)) return mesh;
  const int n = static_cast<int>(std::ceil(2.0 * reach / spacing)) + 1;
  if (static_cast<double>(n) * n > kMaxTerrainVertices) throw ConfigError("terrain_apron: too many vertices");
  const double d = 2.0 * reach / (n - 1);
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const double x = -reach + i * d, y = -reach + j * d;
      mesh.vertices.points.emplace_back(static_cast<float>(x), static_cast<float>(y), static_cast<float>(terrain.height(x, y)));
    }
  }
  for (int j = 0; j + 1 < n; ++j) {
    for (int i = 0; i + 1 < n; ++i) {
      // Skip cells entirely inside the finely meshed site.
      const double x0 = -reach + i * d, y0 = -reach + j * d;
      if (x0 >= -0.5 * c.size_x && x0 + d <= 0.5 * c.size_x && y0 >= -0.5 * c.size_y && y0 + d <= 0.5 * c.size_y) continue;
      const auto v00 = static_cast<std::uint32_t>(j * n + i), v10 = v00 + 1;
      const auto v01 = static_cast<std::uint32_t>(v00 + n), v11 = v01 + 1;
      mesh.triangles.push_back({v00, v10, v11});
      mesh.triangles.push_back({v00, v11, v01});
    }
  }
  return mesh;
}

RayScene make_world_scene(const Site& site, double terrain_spacing, std::int64_t left_out) {
  RayScene scene;
  scene.add_mesh(terrain_mesh(site.terrain, terrain_spacing), kLabelTerrain);
  const io::Mesh apron = terrain_apron(site.terrain, kApronSpacing, kApronReach);
  if (!apron.triangles.empty()) scene.add_mesh(apron, kLabelTerrain);
  for (std::size_t k = 0; k < site.stones.size(); ++k) {
    if (static_cast<std::int64_t>(k) != left_out) scene.add_mesh(site.stones[k].mesh, static_cast<std::int32_t>(k));
  }
  scene.commit();
  return scene;
}

}  // namespace cairn::sim
