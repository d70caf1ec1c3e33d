#pragma once
// Ground removal (Sec. 4.3). Two methods:
//  - "plane": the paper's single RANSAC plane with distance margin d_plane;
//  - "grid":  a local ground surface for sloped, undulating terrain — a progressive morphological
//    filter (Zhang et al. 2003) on a grid of lowest points separates terrain cells from object
//    cells, terrain cells get a local least-squares height (sparse cells: the plane through their
//    neighbours' lowest points), object and empty cells are filled by interpolation, optionally
//    object cells lying in the ground band rejoin the terrain (refine_iterations), and every point
//    gets its height above that surface. A point is ground within the band: d_plane, widened on
//    slopes by slope_height × slope (SMRF, Pingel et al. 2013; off by default).
#include <cstdint>
#include <random>
#include <span>
#include <string>
#include <vector>

#include "cairn/core/plane.hpp"

namespace cairn {

struct GroundConfig {
  std::string method = "grid";  // "grid" (local surface) or "plane" (one RANSAC plane)
  double d_plane = 0.10;        // Table 3: points within this height of the ground are ground [m]
  double max_tilt_deg = 30.0;   // plane method: ground normal within this angle of +z
  int ransac_iterations = 1000; // plane method: RANSAC iteration cap
  double cell_size = 0.5;       // grid method: cell edge [m]
  double max_window = 4.0;      // grid method: largest object footprint removed [m]
  double slope = 0.3;           // grid method: terrain slope tolerated by the filter (rise/run)
  double initial_height = 0.2;  // grid method: height threshold of the first window [m]
  double max_height = 3.0;      // grid method: cap of the growing height threshold [m]
  double attach_height = 0.02;  // points higher than this (but in the ground band) next to an
                                // object join it: keeps the bottoms of stones [m]
  double attach_radius = 0.15;  // ... if within this horizontal distance of the object [m]
  double attach_distance = 0.12;  // [m] ... and within this 3-D distance of an object point
  bool attach_chain = false;    // attached points may attach further ones (default: one hop —
                                // chains run on through terrain noise under a stone's bulge)
  double fill_radius = 1.5;     // grid method: terrain under objects from a quadratic fit to the
                                // terrain cells within this radius (0: harmonic fill only) [m]
  double slope_height = 0.0;    // grid method: the ground band widens by this × the surface's
                                // slope (rise/run) — SMRF's elevation scaler (Pingel et al. 2013):
                                // a cell-sized surface cannot follow steep ground exactly [m]
  int refine_iterations = 0;    // grid method: cells whose lowest point lies in the ground band of
                                // the surface are terrain after all; refit, up to this many times

  template <class V>
  void visit(V& v) {
    v("method", method, "ground model: grid (local surface, uneven terrain) or plane (paper)");
    v("d_plane", d_plane, "plane fitting distance threshold / height above local ground [m] (Table 3)");
    v("max_tilt_deg", max_tilt_deg, "plane method: max. angle of the ground normal from +z [deg]");
    v("ransac_iterations", ransac_iterations, "plane method: RANSAC iteration cap");
    v("cell_size", cell_size, "grid method: cell edge [m]");
    v("max_window", max_window, "grid method: largest object footprint to remove [m]");
    v("slope", slope, "grid method: terrain slope tolerated by the morphological filter");
    v("initial_height", initial_height, "grid method: height threshold of the first window [m]");
    v("max_height", max_height, "grid method: cap of the height threshold [m]");
    v("attach_height", attach_height,
      "points above this height next to an object are attached to it (stone bottoms) [m]");
    v("attach_radius", attach_radius, "max. horizontal distance of attached points from the object [m]");
    v("attach_distance", attach_distance, "max. 3-D distance of an attached point from the object [m]");
    v("attach_chain", attach_chain, "attached low points may attach further ones (false: one hop from the object)");
    v("fill_radius", fill_radius, "grid method: quadratic fit radius for the ground under objects (0: harmonic only) [m]");
    v("refine_iterations", refine_iterations,
      "grid method: cells whose lowest point lies in the ground band become terrain and the surface is refit (rounds)");
    v("slope_height", slope_height,
      "grid method: the ground band is d_plane + slope_height x the surface slope (rise/run); 0: d_plane everywhere [m]");
  }
};

struct GroundResult {
  std::vector<float> height;     // per point: height above the local ground [m]
  double d_plane = 0.10;         // the ground band on flat ground [m]
  std::vector<float> widening;   // per point: the band's widening on slopes, slope_height × slope
                                 // [m]; empty when slope_height is 0
  Plane plane;                   // dominant ground plane (least squares over the ground points)
  /// Top of the ground band at point i [m].
  [[nodiscard]] double band(std::size_t i) const { return widening.empty() ? d_plane : d_plane + widening[i]; }
  /// Point i is ground: no higher above the local ground than the band there.
  [[nodiscard]] bool is_ground(std::size_t i) const { return height[i] <= band(i); }
};

/// Heights above the ground for every point. Throws ConfigError on invalid parameters and
/// InputError when no ground can be found (fewer than 3 points).
[[nodiscard]] GroundResult estimate_ground(std::span<const Vec3f> points, const GroundConfig& config,
                                           std::mt19937_64& rng);

}  // namespace cairn
