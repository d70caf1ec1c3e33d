#pragma once
// When two stored objects touch and one rests on the other (objects/support.hpp).

namespace cairn {

/// When two objects touch and one rests on the other.
struct SupportConfig {
  double contact_distance = 0.08;  // [m] points of two objects this close touch (~1.5 map voxels)
  int min_contact_points = 5;      // fewer touching points: no contact (noise)
  /// B rests on A when their contact lies this far above A's centroid, seen from it (and B's
  /// centroid is the higher): two stones side by side on the ground touch near their mid height.
  double min_elevation_deg = 20.0;
  template <class V>
  void visit(V& v) {
    v("contact_distance", contact_distance, "[m] points of two objects this close touch");
    v("min_contact_points", min_contact_points, "fewer touching points than this are no contact");
    v("min_elevation_deg", min_elevation_deg,
      "[deg] B rests on A when their contact lies this far above A's centroid (seen from it)");
  }
  void validate() const;
};

}  // namespace cairn
