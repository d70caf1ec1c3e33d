#pragma once
// The static world as the sensors see it: the terrain height field triangulated on a regular
// grid plus every stone mesh, in one Embree scene. Labels follow the segmentation convention:
// terrain -1, stone k -> k, robot links kLabelRobot.
#include <cstdint>

#include "cairn/core/io/io.hpp"
#include "cairn/sim/procedural_site.hpp"
#include "cairn/sim/raycast.hpp"

namespace cairn::sim {

inline constexpr std::int32_t kLabelTerrain = -1;
inline constexpr std::int32_t kLabelRobot = -3;

/// Terrain height field triangulated over the terrain config's extent (size_x × size_y centred at
/// the origin) with the given grid spacing [m] (two triangles per cell, upward-facing).
/// Throws ConfigError for a non-positive spacing or more than 2^26 vertices.
io::Mesh terrain_mesh(const Terrain& terrain, double spacing);

/// The far ground around the site: the same height field triangulated at `spacing` [m] out to
/// `reach` [m] from the origin, leaving out the cells inside the site's extent (which
/// terrain_mesh covers finely). Without it every beam that misses the site would see nothing,
/// unlike on a real site. Returns an empty mesh when reach does not exceed the site.
io::Mesh terrain_apron(const Terrain& terrain, double spacing, double reach);

inline constexpr double kApronSpacing = 1.0;  // [m]
inline constexpr double kApronReach = 100.0;  // [m] (the VLP-16's maximum range)

/// Terrain (label -1, triangulated at `terrain_spacing`, plus the coarse apron out to the
/// LiDAR's range) and all stones (label = index) but `left_out` (a stone held by the gripper,
/// ray-cast with the robot instead; -1: none), committed.
RayScene make_world_scene(const Site& site, double terrain_spacing = 0.05, std::int64_t left_out = -1);

}  // namespace cairn::sim
