#include "cairn/core/gripper.hpp"

#include <algorithm>

namespace cairn {
namespace {
ConvexPart box_part(std::string name, const Eigen::Vector3d& center, const Eigen::Vector3d& half) {
  ConvexPart part{.name = std::move(name), .vertices = {}, .center = center, .half_extents = half};
  for (int i = 0; i < 8; ++i) {
    const Eigen::Vector3d sign((i & 1) ? 1.0 : -1.0, (i & 2) ? 1.0 : -1.0, (i & 4) ? 1.0 : -1.0);
    part.vertices.push_back(center + sign.cwiseProduct(half));
  }
  return part;
}
}  // namespace

std::vector<ConvexPart> gripper_parts(const GripperConfig& c, double opening) {
  const double w = std::clamp(opening, 0.0, c.max_opening);
  std::vector<ConvexPart> parts;
  parts.push_back(box_part("palm", {-0.5 * c.palm_depth, 0.0, 0.0},
                           {0.5 * c.palm_depth, 0.5 * c.palm_width, 0.5 * c.palm_height}));
  const Eigen::Vector3d jaw_half(0.5 * c.jaw_length, 0.5 * c.jaw_thickness, 0.5 * c.jaw_height);
  const double jaw_y = 0.5 * w + 0.5 * c.jaw_thickness;
  parts.push_back(box_part("jaw_left", {0.5 * c.jaw_length, -jaw_y, 0.0}, jaw_half));
  parts.push_back(box_part("jaw_right", {0.5 * c.jaw_length, jaw_y, 0.0}, jaw_half));
  return parts;
}

}  // namespace cairn
